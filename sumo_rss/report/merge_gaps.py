"""The earliest RSS-legal merge an ego could have reached from an acceleration lane (issue 48): a lower bound on
its merge time, to tell a planner that waited for nothing from a motorway that left no gap.

From the ego's state when it entered the acceleration lane (front bumper ``s_e`` [m] along the target lane's
chain, speed ``v_e``), the ego's states at time t are those of a double integrator with acceleration in
[−brake, accel] and speed in [0, max_speed] (no jerk limit, no car ahead of it on its own lane): at each speed v
reachable by t, every front-bumper position s in [s_lo(v, t), s_hi(v, t)] (bang-bang bounds, exact). A merge can
start at t from (s, v) if, holding v for the lane change's ``change_s`` (the planner's own assumption in its RSS
barrier: the gap stays safe "this long at constant speeds"), at every recorded step of that change

- every car j of the target lane ahead has (s_j − len_j) − s_ego > d_min(v, v_j; ego as rear) + 1 mm, and every car
  behind has (s_ego − len_ego) − s_j > d_min(v_j, v; the car as rear) + 1 mm — the auditor's own
  :func:`~sumo_rss.rss.formulas.lon_safe_distance_same_dir` with each car's RSS parameters, so a car beside the
  ego is never allowed;
- the change completes with the front bumper at or before the lane's end.

For one speed each car forbids one interval of s per step of the change; s is free where the reachable interval
minus their union is not empty (exact in s). Speeds are a grid of ``speed_step``; starts and the checks within a
change are the recorded steps (0.1 s). Units: s, m, m/s, m/s².
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..planner.behavior.forward_sim import SimSettings
from ..planner.epsilon import EGO_SIM
from ..rss import formulas
from ..rss.params import PARAM_NAMES, RssParamArrays, RssParams

CHUNK = 64  # start steps per vectorised block (memory: CHUNK x speeds x cars x change steps floats)


@dataclass(frozen=True)
class EgoLimits:
    """The ego's longitudinal limits [m/s², m/s]: the EPSILON planner's (``EGO_SIM.ego_limits``) and the
    acceleration lane's speed limit."""

    accel: float
    brake: float
    max_speed: float

    @classmethod
    def planner(cls, max_speed: float, sim: SimSettings = EGO_SIM) -> EgoLimits:
        return cls(sim.ego_limits.max_accel, sim.ego_limits.hard_brake, max_speed)


@dataclass(frozen=True)
class GapSearch:
    """``change_s`` [s]: how long the gap must stay legal (default: the planner's barrier commit time, 1.0 s);
    ``speed_step`` [m/s]: the grid of the ego's speeds."""

    change_s: float = EGO_SIM.commit_time
    speed_step: float = 0.1

    def __post_init__(self) -> None:
        if not 0.0 <= self.change_s <= 20.0:
            raise ValueError(f"change time must be in [0, 20] s, is {self.change_s:g}")
        if not 0.0 < self.speed_step <= 5.0:
            raise ValueError(f"speed step must be in (0, 5] m/s, is {self.speed_step:g}")


@dataclass(frozen=True)
class TargetLane:
    """The cars of the target lane per recorded step, in N slots (a slot is not a car: step by step the slots hold
    whichever cars are there): ``times`` [T] (uniform step), ``front`` [T, N] front bumper along the lane's chain
    [m] (nan: empty slot), ``speed`` [T, N] [m/s], ``length`` [T, N] [m], ``params`` (fields [T, N]) their RSS
    parameters, ``end`` [m]: where on the chain the acceleration lane ends."""

    times: np.ndarray
    front: np.ndarray
    speed: np.ndarray
    length: np.ndarray
    params: RssParamArrays
    end: float


@dataclass(frozen=True)
class EarliestMerge:
    """The first start [s] of a legal merge (None: none before the record ends), its speed [m/s] and front bumper
    [m], and its completion = start + change time [s]."""

    start_s: float | None
    speed_ms: float | None
    front_m: float | None
    completion_s: float | None


def reachable_interval(v: np.ndarray, tau: np.ndarray, v0: float, limits: EgoLimits
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s_lo, s_hi, feasible): distances [m] the ego covers in ``tau`` [s] from ``v0`` ending at speed ``v`` [m/s]
    (arrays broadcast). s_hi: accelerate to a peak w (≤ max_speed, cruising there), then brake to v; s_lo: brake to
    a trough u (≥ 0, standing there), then accelerate to v."""
    a, b, top = limits.accel, limits.brake, limits.max_speed
    v, tau = np.asarray(v, float), np.asarray(tau, float)
    feasible = (v <= np.minimum(max(top, v0), v0 + a * tau) + 1e-9) & (v >= v0 - b * tau - 1e-9)
    w = np.minimum((tau + v0 / a + v / b) / (1.0 / a + 1.0 / b), max(top, v0))
    cruise = np.maximum(tau - (w - v0) / a - (w - v) / b, 0.0)
    s_hi = (w * w - v0 * v0) / (2.0 * a) + (w * w - v * v) / (2.0 * b) + w * cruise
    u = np.maximum((v0 / b + v / a - tau) / (1.0 / a + 1.0 / b), 0.0)
    s_lo = (v0 * v0 - u * u) / (2.0 * b) + (v * v - u * u) / (2.0 * a)
    return s_lo, s_hi, feasible


def earliest_merge(lane: TargetLane, entered_s: float, entry_front: float, entry_speed: float, ego_length: float,
                   ego_params: RssParams, limits: EgoLimits, search: GapSearch = GapSearch()) -> EarliestMerge:
    """The earliest legal merge start at or after ``entered_s`` [s] from front bumper ``entry_front`` [m] (on the
    chain) at ``entry_speed`` [m/s] (module docstring)."""
    times = np.asarray(lane.times, float)
    if times.size < 2:
        raise ValueError("the target lane's record needs at least two steps")
    dt = float(times[1] - times[0])
    k = int(round(search.change_s / dt))
    speeds = np.arange(0.0, max(limits.max_speed, entry_speed) + 1e-9, search.speed_step)
    first = int(np.searchsorted(times, entered_s - 1e-9))
    starts = np.arange(first, times.size - k)
    for block in range(0, starts.size, CHUNK):
        idx = starts[block:block + CHUNK]
        found = _first_legal(lane, idx, k, dt, speeds, entered_s, entry_front, entry_speed, ego_length, ego_params,
                             limits)
        if found is not None:
            i, v, s = found
            return EarliestMerge(float(times[i]), float(v), float(s), float(times[i] + k * dt))
    return EarliestMerge(None, None, None, None)


def _first_legal(lane: TargetLane, idx: np.ndarray, k: int, dt: float, speeds: np.ndarray, entered_s: float,
                 entry_front: float, entry_speed: float, ego_length: float, ego_params: RssParams,
                 limits: EgoLimits) -> tuple[int, float, float] | None:
    """(start step, speed, front bumper) of the first legal start among the steps ``idx``, or None."""
    tau = lane.times[idx] - entered_s  # [B]
    s_lo, s_hi, feasible = reachable_interval(speeds[None, :], tau[:, None], entry_speed, limits)  # [B, V]
    lo = entry_front + s_lo
    hi = np.minimum(entry_front + s_hi, lane.end - speeds[None, :] * k * dt)
    steps = idx[:, None] + np.arange(k + 1)[None, :]  # [B, K]
    front, speed = lane.front[steps], lane.speed[steps]  # [B, K, N]
    present = np.isfinite(front)
    p_car = RssParamArrays(*(getattr(lane.params, name)[steps][:, None] for name in PARAM_NAMES))  # [B, 1, K, N]
    v_car = np.where(present, speed, 0.0)[:, None]  # [B, 1, K, N]
    v_ego = speeds[None, :, None, None]  # [1, V, 1, 1]
    behind_car = formulas.lon_safe_distance_same_dir(v_ego, v_car, ego_params, p_car)  # ego behind car j
    ahead_car = formulas.lon_safe_distance_same_dir(v_car, v_ego, p_car, ego_params)  # car j behind ego
    shift = v_ego * (np.arange(k + 1) * dt)[None, None, :, None]  # the ego's advance during the change
    eps = formulas.SAFE_DISTANCE_PRECISION
    f = np.where(present, front, np.inf)[:, None]
    # [B, V, K, N]: each car forbids the ego's front bumpers [start, stop] at each step of the change
    start = f - lane.length[steps][:, None] - behind_car - shift - eps
    stop = f + ego_length + ahead_car - shift + eps
    shape = start.shape[:2] + (-1,)
    free, where = _free_point(start.reshape(shape), stop.reshape(shape), lo, hi)
    ok = free & feasible
    rows = np.flatnonzero(ok.any(axis=1))
    if not rows.size:
        return None
    r = int(rows[0])
    c = int(np.flatnonzero(ok[r])[0])
    return int(idx[r]), float(speeds[c]), float(where[r, c])


def _free_point(start: np.ndarray, stop: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether [lo, hi] (shape S) holds a point outside every interval [start, stop] (shape S + (M,)), and the
    lowest such point (nan where none). Intervals with start = inf are absent."""
    order = np.argsort(start, axis=-1)
    a = np.take_along_axis(start, order, axis=-1)
    e = np.maximum.accumulate(np.take_along_axis(stop, order, axis=-1), axis=-1)
    # Free segments: (-inf, a_0), (e_m, a_{m+1}), (e_last, inf); a point of [lo, hi] in one of them is free.
    seg_lo = np.concatenate([np.full(a.shape[:-1] + (1,), -np.inf), e], axis=-1)
    seg_hi = np.concatenate([a, np.full(a.shape[:-1] + (1,), np.inf)], axis=-1)
    low = np.maximum(seg_lo, lo[..., None])
    fits = (low <= np.minimum(seg_hi, hi[..., None])) & (seg_lo < seg_hi)
    point = np.where(fits, low, np.inf).min(axis=-1)
    free = np.isfinite(point)
    return free, np.where(free, point, np.nan)
