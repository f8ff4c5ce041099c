"""What the responsibility tracker is given at each step (:class:`StepInput`): the step's pair situations and the
per-vehicle values of its snapshot, and at junctions the rules of every conflict area of every crossing pair
(:class:`AreaRules`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import RssParamArrays
from .situations import PairSituations

EPS_ACCEL = 0.05  # [m/s²] tolerance on every acceleration bound

AREA_KEY = np.dtype([("pair", np.int64), ("area", np.int64)])


@dataclass(frozen=True, eq=False)
class AreaRules:
    """The RULE_* bits and priority of one step in every conflict area of every crossing pair, sorted by ``keys``
    (AREA_KEY: pair key, area number). A pair is kept as one situation, in its most critical area; when it
    becomes dangerous in an area, what held in that area at the step before t_b decides who owes what (rss.md
    §5), not what held in the area that was most critical then."""

    keys: np.ndarray
    rules: np.ndarray  # int8
    priority: np.ndarray  # int8
    by_signal: np.ndarray  # bool: the signals decided the priority


@dataclass
class StepInput:
    """What one step of the tracker needs, per pair (rows of the snapshot in ``a``/``b``)."""

    time: float  # [s]
    keys: np.ndarray  # int64 pair keys, unique
    situations: PairSituations
    ids: np.ndarray  # vehicle ids of the snapshot
    uids: np.ndarray  # int64 per snapshot row: a number for each vehicle id, the same at every step
    vclass: np.ndarray
    accel: np.ndarray  # [m/s²] per snapshot row
    speed: np.ndarray  # [m/s] per snapshot row
    params: RssParamArrays  # per snapshot row
    new_vehicle: np.ndarray  # bool per snapshot row: not seen at the previous step
    # Intersections: every conflict area's rules of every crossing pair (not only the row kept per pair), and the
    # number of the area of each row of ``situations`` (-1: a road situation).
    areas: AreaRules | None = None
    area_number: np.ndarray | None = None
    accel_tolerance: float = EPS_ACCEL  # [m/s²] on the acceleration bounds (wider for accelerations measured coarsely)
    # Rule 4 (:mod:`.occlusion_track`): sorted pair keys and the start [s] of their cars' current run of seeing each
    # other (+inf while hidden); a response is owed from max(t_b, that start) + ρ. None: every car sees every car.
    seen_from: tuple[np.ndarray, np.ndarray] | None = None
