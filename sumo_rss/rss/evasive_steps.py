"""Rule 5's per-step record (rss.md §8, docs/rss.md "Rule 5"): what the legality of a car's evasive manoeuvres at a
step needs, kept for the steps of a bounded look-back window so that the candidates are evaluated only for the
episodes that end in a collision, when they do (:mod:`.evasive_track`).

A step's record holds the asked episodes (one responsible car c₂ so far, on a road), the state of every vehicle, the
step's vehicle pairs and open episodes with the bounds owed in them: traffic-sized, and only for the steps of the
window. :func:`legal_at` gives, from such a record, exactly what evaluating the step as it came would have found.

Units: m, s, m/s, m/s² (brakes positive magnitudes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .evasive import OPPOSITE_CODE, Candidates, PairRows, candidates, collides, dangerous_at_end, grid
from .evasive import on_drivable_lanes, owed_to_others
from .params import RssParamArrays
from .compliance import JudgedStep
from .situations import FIRST_INTERSECTION_CODE, PairSituations, VehicleFrame
from .sorted_keys import find_sorted


@dataclass(frozen=True, eq=False)
class StepMotion:
    """Every vehicle's accelerations at a step, by uid (sorted): what a car's actual motion is matched with."""

    time: float  # [s]
    uid: np.ndarray  # sorted
    accel: np.ndarray  # [m/s²] along its lane
    lat_accel: np.ndarray  # [m/s²] across it (+ = left), from the lateral speeds of this and the step before
    tolerance: float  # [m/s²] the acceleration tolerance of the step


@dataclass(frozen=True, eq=False)
class AskedStep:
    """The asked episodes of a step and what their legality needs.

    Asked episodes: serial, c1_side (0: c₁ is car a), c₁'s uid, the pair's key and c₁'s role. Vehicles (snapshot
    rows, copied): uid, speed, lat_speed, accel, lane, d, half_lon, half_lat and the RSS parameters. The step's
    vehicle pair rows (the situations' arrays, which the auditor makes anew every step and never changes): a, b
    (vehicle rows), key, kind, a_is_rear, lon_gap, a_is_left, lat_gap, wrong_way_a, wrong_way_b (None: none); the
    gaps copied (on roads they are two rows of one block of nine, :mod:`.road_kernel`, kept whole by a view). The
    open episodes (copied): serial, uids [·, 2], a_left, owed_lat; and the responsibility tracker's bounds of the
    step, ``judged`` (:class:`~.compliance.JudgedStep`, made anew every step; None: none).
    """

    serial: np.ndarray
    c1_side: np.ndarray
    c1_uid: np.ndarray
    pair_key: np.ndarray
    role: np.ndarray
    uid: np.ndarray
    speed: np.ndarray
    lat_speed: np.ndarray
    accel: np.ndarray
    lane: np.ndarray
    d: np.ndarray
    half_lon: np.ndarray
    half_lat: np.ndarray
    params: RssParamArrays
    a: np.ndarray
    b: np.ndarray
    key: np.ndarray
    kind: np.ndarray
    a_is_rear: np.ndarray
    lon_gap: np.ndarray
    a_is_left: np.ndarray
    lat_gap: np.ndarray
    wrong_way_a: np.ndarray | None
    wrong_way_b: np.ndarray | None
    ep_serial: np.ndarray
    ep_uids: np.ndarray
    ep_a_left: np.ndarray
    ep_owed_lat: np.ndarray
    judged: JudgedStep | None


def asked_step(snapshot: WorldSnapshot, uids: np.ndarray, frame: VehicleFrame, sit: PairSituations,
               keys: np.ndarray, tracker, params: RssParamArrays, prior: tuple[np.ndarray, np.ndarray]
               ) -> AskedStep | None:
    """The record of a step (``tracker``'s open episodes after its step; ``prior``: (sorted serials, [·, 2]
    responsible in their earlier parts) of the joinable closed episodes): None when no episode is asked."""
    e = tracker.open
    if not len(e) or not len(sit):
        return None
    known, at = find_sorted(prior[0], e.serial)
    resp = e.responsible.copy()
    resp[known] |= prior[1][at[known]]
    ask = np.flatnonzero((resp.sum(axis=1) == 1) & (e.kind < FIRST_INTERSECTION_CODE))
    if not ask.size:
        return None
    c1_side = resp[ask, 0].astype(np.int8)  # c₂ is a → c₁ is b
    return AskedStep(
        serial=e.serial[ask], c1_side=c1_side, c1_uid=np.where(c1_side == 0, e.uids[ask, 0], e.uids[ask, 1]),
        pair_key=e.keys[ask], role=e.roles[ask, c1_side], uid=uids.copy(), speed=snapshot.speed.copy(),
        lat_speed=snapshot.lat_speed.copy(), accel=snapshot.accel.copy(), lane=frame.lane.copy(), d=frame.d.copy(),
        half_lon=frame.half_lon.copy(), half_lat=frame.half_lat.copy(), params=params.take(np.arange(len(uids))),
        a=sit.a, b=sit.b, key=keys, kind=sit.kind, a_is_rear=sit.a_is_rear, lon_gap=sit.lon_gap.copy(),
        a_is_left=sit.a_is_left, lat_gap=sit.lat_gap.copy(), wrong_way_a=sit.wrong_way_a, wrong_way_b=sit.wrong_way_b,
        ep_serial=e.serial.copy(), ep_uids=e.uids.copy(), ep_a_left=e.a_left.copy(), ep_owed_lat=e.owed_lat.copy(),
        judged=tracker.judged)


def legal_at(s: AskedStep, k: int, network: RoadNetwork, horizon: float, tolerance: float
             ) -> tuple[Candidates, np.ndarray, float] | None:
    """(the candidates, [1, 12] which are legal, c₁'s ρ [s]) of asked episode ``k`` of the step ``s`` (rss.md §8
    (a)-(d) with horizon ``horizon`` [s]); None when no candidate is legal (or the pair is no road row of the step).
    """
    c1 = np.flatnonzero(s.uid == s.c1_uid[k])
    mine = np.flatnonzero(((s.a == c1[0]) | (s.b == c1[0])) & (s.kind < FIRST_INTERSECTION_CODE))  # c₁'s road rows
    target = mine[s.key[mine] == s.pair_key[k]][:1]
    if not target.size:
        return None
    # The cheap tests first, each while a legal candidate is left: the pair at t₀ + T (the candidates' end states
    # only), then on the time grid the drivable band, the contact with c₂ and with the other road users around c₁,
    # and the responses c₁ owes them.
    ends = _candidates(s, network, c1, np.array([0.0, horizon]))
    rows = _rows(s, target, c1, np.zeros(1, dtype=int))
    if dangerous_at_end(ends, rows).all():
        return None
    cand = _candidates(s, network, c1, grid(horizon))
    lane = s.lane[c1]
    legal = ~dangerous_at_end(cand, rows)
    legal &= on_drivable_lanes(cand, s.d[c1], s.half_lat[c1], _room(network, lane, network.lane_left),
                               _room(network, lane, network.lane_right))
    if legal.any():
        legal &= ~collides(cand, rows)
    if not legal.any():
        return None
    # (d) every other road user around c₁ (within reach over the horizon) on its naive prediction.
    row = mine[mine != target[0]]
    if row.size:
        others = _rows(s, row, np.repeat(c1, row.size), np.zeros(row.size, dtype=int))
        others = others.take(np.flatnonzero(~others.beyond_reach(cand)))
        if len(others.q):
            legal &= ~collides(cand, others).any(axis=0)
    legal &= _owed(s, k, cand, tolerance)
    if not legal.any():
        return None
    return cand, legal, float(s.params.response_time[c1[0]])


def _candidates(s: AskedStep, network: RoadNetwork, c1: np.ndarray, times: np.ndarray) -> Candidates:
    """The candidates of the cars ``c1`` (vehicle rows) at ``times`` [s]."""
    lane = s.lane[c1]
    return candidates(s.speed[c1], s.lat_speed[c1], s.params.take(c1), network.lane_speed[lane],
                      0.5 * network.lane_width[lane], times)


def _rows(s: AskedStep, rows: np.ndarray, c1: np.ndarray, q: np.ndarray) -> PairRows:
    """The pair rows ``rows`` of ``s`` seen from car ``c1`` (vehicle rows, one per row; asked index ``q``)."""
    a, b = s.a[rows], s.b[rows]
    c1_is_a = a == c1
    other = np.where(c1_is_a, b, a)
    b_minus_a = np.where(s.a_is_rear[rows], 1.0, -1.0) * (s.lon_gap[rows] + s.half_lon[a] + s.half_lon[b])
    b_minus_a_lat = np.where(s.a_is_left[rows], -1.0, 1.0) * (s.lat_gap[rows] + s.half_lat[a] + s.half_lat[b])
    flip = np.where(c1_is_a, 1.0, -1.0)
    opposite = s.kind[rows] == OPPOSITE_CODE
    dir_a = np.where(opposite & ~s.a_is_rear[rows], -1.0, 1.0)
    dir_b = np.where(opposite, -dir_a, 1.0)
    p1, po = s.params.take(c1), s.params.take(other)
    wrong = (s.wrong_way_a[rows], s.wrong_way_b[rows]) if s.wrong_way_a is not None else \
        (np.zeros(len(rows), bool),) * 2
    w1, wo = np.where(c1_is_a, wrong[0], wrong[1]), np.where(c1_is_a, wrong[1], wrong[0])
    return PairRows(
        q=q, dx=flip * b_minus_a, dy=flip * b_minus_a_lat, dir_c1=np.where(c1_is_a, dir_a, dir_b),
        dir_o=np.where(c1_is_a, dir_b, dir_a), half_lon=s.half_lon[a] + s.half_lon[b],
        half_lat=s.half_lat[a] + s.half_lat[b], v_o=s.speed[other], a_o=s.accel[other], u_o=s.lat_speed[other],
        opposite=opposite, p_c1=p1, p_o=po, brake_c1=np.where(w1, p1.lon_brake_min, p1.lon_brake_min_correct),
        brake_o=np.where(wo, po.lon_brake_min, po.lon_brake_min_correct))


def _room(network: RoadNetwork, lane: np.ndarray, beside: np.ndarray) -> np.ndarray:
    """[m] drivable width from a lane's centre line to the far side of the lane ``beside`` it (or its own border
    where there is none)."""
    other = beside[lane]
    return 0.5 * network.lane_width[lane] + np.where(other >= 0, network.lane_width[np.maximum(other, 0)], 0.0)


def _owed(s: AskedStep, k: int, cand: Candidates, tolerance: float) -> np.ndarray:
    """[1, 12] legality (a) of asked episode ``k``'s candidates: the bounds of this step in c₁'s other open
    episodes."""
    episode, side = np.nonzero(s.ep_uids == s.c1_uid[k])
    keep = s.ep_serial[episode] != s.serial[k]
    episode, side = episode[keep], side[keep]
    accel_max, accel_min = np.full(episode.size, np.nan), np.full(episode.size, np.nan)
    judged = s.judged
    if judged is not None and len(judged.serial) and episode.size:
        by_serial = np.argsort(judged.serial)
        found, at = find_sorted(judged.serial[by_serial], s.ep_serial[episode])
        at = by_serial[at]
        accel_max = np.where(found, judged.accel_max[at, side], np.nan)
        accel_min = np.where(found, judged.accel_min[at, side], np.nan)
    other_left = np.where(side == 0, ~s.ep_a_left[episode], s.ep_a_left[episode])
    towards = np.where(s.ep_owed_lat[episode], np.where(other_left, 1.0, -1.0), 0.0)
    return owed_to_others(cand, np.zeros(1, dtype=int), np.zeros(episode.size, dtype=int), accel_max, accel_min,
                          towards, tolerance)
