"""Offline audits: SUMO FCD files → WorldSnapshot stream (:mod:`.fcd_reader`) → the same auditor as online.

Collisions come from SUMO's collision-output file (:mod:`.fcd_inputs`) or from overlapping bounding boxes; signal
states from SUMO's signal-state file or the network's programs.
"""
from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..boxes import boxes_overlap
from ..errors import listed
from ..road.network import RoadNetwork
from ..sim.collisions import CollisionEvent, ContactTracker
from ..sim.snapshot import WorldSnapshot
from .auditor import AuditResult, Auditor, ParamResolver
from .fcd_inputs import STEP_TIME_TOLERANCE, CollisionReports, FcdError, VehicleInfo, read_collisions, read_vehicle_info
from .fcd_reader import FcdReader
from .occlusion import OccluderEdges, OcclusionParams
from .params import EvasiveParams
from .record_checks import check_collisions_in_fcd, warn_late_signal_states, warn_without_signal_states
from .signals import SignalStates
from .situations import FIRST_INTERSECTION_CODE, SAME_DIRECTION_CODES, PairSituations, body_poses

__all__ = ["AuditProgress", "FcdError", "FcdReader", "VehicleInfo", "audit_fcd", "overlap_contacts",
           "read_collisions", "read_vehicle_info"]


@dataclass(frozen=True)
class AuditProgress:
    """How far an offline audit has got, after a time step."""

    bytes_read: int  # of the FCD file, on disk (of its size: a gzipped file's compressed bytes)
    time: float  # [s] of the step
    steps: int  # audited so far
    pair_steps: int  # pairs evaluated so far (road and junction situations, each step)


def audit_fcd(fcd: Path, network: RoadNetwork, params: ParamResolver, *, vehicles: VehicleInfo | None = None,
              collisions: Path | None = None, tls_states: Path | None = None, ego_ids: tuple[str, ...] = (),
              run_id: str = "", signal_rule: bool = True, raw_episodes: bool = False, junction_brake_min: bool = False,
              trace_class: str | None = None, on_progress: Callable[[AuditProgress], None] | None = None,
              stop: Callable[[], bool] | None = None, record_states: bool = False, spool: Path | None = None,
              on_snapshot: Callable[[WorldSnapshot], None] | None = None,
              evasive: EvasiveParams | None = None, occlusion: OcclusionParams | None = None,
              occluders: OccluderEdges | None = None) -> AuditResult:
    """Audit a whole FCD file. Collisions come from SUMO's collision-output file when given, else from
    overlapping bounding boxes of the evaluated pairs (:func:`_in_contact`). Signal states come from SUMO's
    signal-state file (``SaveTLSStates``) when given, else from the network's fixed-time programs. ``vehicles``
    defaults to SUMO's built-in vTypes (:func:`read_vehicle_info`). ``on_progress(AuditProgress)`` is called after
    every time step. ``stop()`` is asked after every time step: True ends the audit there, as if the file ended
    there (with a warning that names the step). ``signal_rule``, ``raw_episodes``, ``junction_brake_min``,
    ``trace_class``, ``record_states``, ``spool``, ``evasive``, ``occlusion``, ``occluders``: as for :class:`Auditor`
    (the vTypes' heights from ``vehicles``). ``on_snapshot(snapshot)``:
    after every audited time step (e.g. a viewer's recorder)."""
    reports = CollisionReports(read_collisions(collisions)) if collisions is not None else None
    if vehicles is None:
        vehicles = read_vehicle_info(None, network.path)
    if tls_states is None:
        warn_without_signal_states(network.path)
    try:
        signals = SignalStates(network.path, tls_states)
    except ValueError as exc:
        raise FcdError(str(exc)) from exc
    contacts = ContactTracker()
    auditor = Auditor(network, params, run_id, trace_class=trace_class, signal_rule=signal_rule,
                      raw_episodes=raw_episodes, junction_brake_min=junction_brake_min, record_states=record_states,
                      spool=spool, evasive=evasive, occlusion=occlusion, heights=vehicles.heights,
                      occluders=occluders)
    absent = set(ego_ids)  # ego ids not seen in the file yet
    reader = FcdReader(fcd, network, vehicles, ego_ids)
    steps = 0
    # Not in the FCD's steps so far (looked up among the reader's vehicles, not in every step's ids).
    unseen = set(reports.parties().tolist()) if reports is not None else set()
    for steps, snapshot in enumerate(reader, start=1):
        if steps == 1:
            warn_late_signal_states(signals, fcd, snapshot.time)
        snapshot = replace(snapshot, tls_states=signals.states(snapshot.time))
        if absent or unseen:
            absent.difference_update([v for v in absent if v in reader.vehicles_seen])
            unseen.difference_update([v for v in unseen if v in reader.vehicles_seen])
        if reports is not None:
            auditor.observe(snapshot, contacts.step(reports.take_until(snapshot.time)))
        else:
            found = overlap_contacts(snapshot, auditor.observe(snapshot), network)
            auditor.record_collisions(contacts.step(found))
        if on_progress is not None:
            on_progress(AuditProgress(reader.bytes_read, snapshot.time, steps, auditor.pair_steps))
        if on_snapshot is not None:
            on_snapshot(snapshot)
        if stop is not None and stop():
            warnings.warn(f"{fcd}: stopped after time step {snapshot.time:g} s: audited up to there", stacklevel=2)
            return auditor.finish()
    if not steps:
        warnings.warn(f"{fcd}: no <timestep> in the file: nothing to audit", stacklevel=2)
    elif signals.known_until is not None and snapshot.time > signals.known_until + STEP_TIME_TOLERANCE:
        warnings.warn(f"{signals.saved_states}: the signal states break off at {signals.known_until:g} s; the time "
                      f"steps of {fcd} after it (to {snapshot.time:g} s) were audited with the states at "
                      f"{signals.known_until:g} s", stacklevel=2)
    if reports is not None:
        check_collisions_in_fcd(collisions, fcd, reports.audited(), unseen - reader.people)
        reports.warn_unused(collisions, fcd)
    if absent:
        warnings.warn(f"{fcd}: no vehicle {listed(sorted(absent))} (given as the ego): audited without it",
                      stacklevel=2)
    return auditor.finish()


def overlap_contacts(snapshot: WorldSnapshot, pairs: PairSituations, network: RoadNetwork) -> list[CollisionEvent]:
    """The evaluated ``pairs`` whose bounding boxes overlap (:func:`_in_contact`), as collision events of type
    'overlap'. The rear car of a pair going the same way (also a merge) is named the collider (SUMO's convention),
    else car a."""
    overlap = _in_contact(snapshot, pairs, network)
    a_named = pairs.a_is_rear | ~np.isin(pairs.kind, SAME_DIRECTION_CODES)
    collider = np.where(a_named, pairs.a, pairs.b)[overlap]
    victim = np.where(a_named, pairs.b, pairs.a)[overlap]
    return [CollisionEvent(snapshot.time, str(snapshot.ids[c]), str(snapshot.ids[v]), "", "", 0.0, 0.0, "overlap",
                           "", 0.0) for c, v in zip(collider, victim)]


def _in_contact(snapshot: WorldSnapshot, pairs: PairSituations, network: RoadNetwork) -> np.ndarray:
    """Per evaluated pair, whether the two bounding boxes overlap: both gaps negative for a road pair (lane frame);
    the footprints themselves (:func:`body_poses`) for a pair crossing in a junction (its gaps are distances to the
    conflict area)."""
    overlap = (pairs.lon_gap < 0.0) & (pairs.lat_gap < 0.0)
    crossing = np.flatnonzero(pairs.kind >= FIRST_INTERSECTION_CODE)
    if crossing.size:
        x, y, heading = body_poses(snapshot, network, network.lane_indices(snapshot.lane_id))
        a, b = pairs.a[crossing], pairs.b[crossing]
        overlap[crossing] = boxes_overlap(x[a], y[a], heading[a], snapshot.length[a], snapshot.width[a],
                                          x[b], y[b], heading[b], snapshot.length[b], snapshot.width[b])
    return overlap
