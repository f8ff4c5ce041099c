"""Whether both cars of every open episode comply at a step with the proper response they owe (rss.md §5): the
longitudinal bounds (a_acc during ρ, −b_min or −b_corr after it until stopped, −b_max for the front car) and the
lateral speed envelope, with the violation intervals they start, extend and end (:func:`judge_step`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..road_users import PERSON_CLASS
from .open_episodes import N_CONSTRAINTS, OpenEpisodes
from .situations import PairSituations
from .sorted_keys import find_sorted
from .step_input import EPS_ACCEL, StepInput

STOPPED_SPEED = 0.05  # [m/s] below this a car counts as stopped
TIME_EPS = 1e-9  # [s]


@dataclass(frozen=True, eq=False)
class JudgedStep:
    """The owed responses' bounds of one step, per open episode (by ``serial``) and car (column 0: a, 1: b); NaN
    where a bound does not apply (not owed, the step at t_b, a car stopped after ρ, the pair not evaluated)."""

    serial: np.ndarray  # int64, one per open episode
    accel: np.ndarray  # [m/s²] the car's acceleration
    accel_max: np.ndarray  # [m/s²] a ≤ this: a_acc during ρ, −b_min (−b_corr) after it
    accel_min: np.ndarray  # [m/s²] a ≥ this: −b_max (the front car)
    lat_speed: np.ndarray  # [m/s] the car's lateral speed towards the other
    lat_speed_max: np.ndarray  # [m/s] the lateral response's envelope


def in_line(lat_offset: Any, mu_a: Any, mu_b: Any) -> np.ndarray:
    """Whether two cars whose centres are ``lat_offset`` [m] apart across the road are in line: within μ/2 (the
    larger μ [m] of the two), where neither side is towards the other and the lateral response is not judged
    (rss.md, "The lateral duty keeps away from the side the other car is on now"). NaN: False."""
    return np.asarray(lat_offset) <= 0.5 * np.maximum(mu_a, mu_b)


def lateral_speed_bound(u0: Any, tau: Any, rho: Any, a_lat: Any, b_lat: Any) -> np.ndarray:
    """The lateral response's bound on a car's speed towards the other [m/s], ``tau`` s after the trigger at
    which it was ``u0`` (rss.md §5): it may grow at a_lat during ρ, must then fall at b_lat to ≤ 0 and stay there
    (never asked below 0)."""
    return np.maximum(u0 + a_lat * np.minimum(tau, rho) - b_lat * np.maximum(tau - rho, 0.0), 0.0)


def judge_step(e: OpenEpisodes, step: StepInput, rows: np.ndarray, candidate: np.ndarray, in_danger: np.ndarray,
               dt: float, join: bool) -> tuple[JudgedStep, np.ndarray]:
    """Evaluate every owed constraint for both cars of each open episode ``e`` at ``step.time`` (both cars are in
    the snapshot; ``dt`` [s] since the step before, 0 at the first): with the pair's situation where it is a
    ``candidate`` now (situation ``rows``; elsewhere ``rows`` is ignored); elsewhere (far apart now, e.g. one has
    left the junction) only the longitudinal constraints, on the cars' own accelerations and speeds: the pair's
    lateral speeds are not known there. ``in_danger``: the pair is still dangerous (its margins count). Updates
    ``e`` in place; returns the step's bounds and the violation intervals [episode, car, constraint] that ended
    (their rows are still to be written). ``join``: a violation that resumes within the car's ρ continues its
    interval (one row, not one per step where a coarsely measured acceleration dips back within its bound)."""
    sit, t = step.situations, step.time
    if len(sit):
        e.min_lon_margin = np.where(in_danger, np.minimum(e.min_lon_margin,
                                                          sit.lon_gap[rows] - sit.lon_d_min[rows]), e.min_lon_margin)
        e.min_lat_margin = np.where(in_danger, np.minimum(e.min_lat_margin,
                                                          sit.lat_gap[rows] - sit.lat_d_min[rows]), e.min_lat_margin)
    e.t_last = np.where(candidate, t, e.t_last)
    start = e.t_b  # the response starts when the cars can see each other (rule 4)
    if step.seen_from is not None and len(step.seen_from[0]):
        seen, at = find_sorted(step.seen_from[0], e.keys)
        start = np.where(seen, np.maximum(e.t_b, step.seen_from[1][at]), e.t_b)
    judged = t > start + TIME_EPS
    by_uid = np.argsort(step.uids)
    own = by_uid[np.searchsorted(step.uids[by_uid], e.uids)]  # [n, 2] snapshot rows of the cars
    pair = candidate[:, None]
    if len(sit):
        cars = np.where(pair, np.column_stack([sit.a[rows], sit.b[rows]]), own)  # [n, 2] snapshot rows
        v_lon = np.where(pair, np.column_stack([sit.v_lon_a[rows], sit.v_lon_b[rows]]), step.speed[own])
        v_lat = np.where(pair, np.column_stack([sit.v_lat_a[rows], sit.v_lat_b[rows]]), 0.0)
    else:
        cars, v_lon, v_lat = own, step.speed[own], np.zeros(own.shape)
    p = step.params
    accel = step.accel[cars]
    if len(sit):
        progress = area_progress(sit, rows, v_lon, accel, instant_brake(step, cars))
        e.entered |= pair & progress["entered"]
        e.stood_short |= pair & progress["stood_short"]
        e.stopping = np.where(pair, progress["stopping"], e.stopping)
    rho = p.response_time[cars]
    tau = (t - np.minimum(start, t))[:, None]  # 0 while hidden (nothing is judged then)
    rho_lon = np.where(e.moved_off, 0.0, rho)  # no response time to its own moving off (moving_off.py)
    in_response = tau <= rho_lon + TIME_EPS
    # The step that ends ρ inside it (ρ not a multiple of the step): its mean acceleration may be a_acc for
    # the part before t_b + ρ and must be −b after it, so its bound is the time-weighted mix of the two.
    before = np.clip((rho_lon - (tau - dt)) / dt, 0.0, 1.0) if dt > 0.0 else np.zeros_like(rho)
    braker = e.must_brake
    front = e.front_limited
    brake_needed = np.where(e.brake_correct, p.lon_brake_min_correct[cars], p.lon_brake_min[cars])
    moving = v_lon >= STOPPED_SPEED

    actual = np.zeros(cars.shape + (N_CONSTRAINTS,))
    bound = np.zeros_like(actual)
    sign = np.array([1.0, 1.0, -1.0, 1.0])  # +1: actual ≤ bound; −1: actual ≥ bound
    applies = np.zeros(actual.shape, dtype=bool)
    applies[..., 0] = braker & in_response
    actual[..., 0], bound[..., 0] = accel, p.lon_accel_max[cars]
    applies[..., 1] = braker & ~in_response & moving
    actual[..., 1], bound[..., 1] = accel, before * p.lon_accel_max[cars] - (1.0 - before) * brake_needed
    applies[..., 2] = front
    actual[..., 2], bound[..., 2] = accel, -p.lon_brake_max[cars]
    _update_lateral_order(e, sit, rows, candidate, p.lat_fluctuation_margin[cars])
    left = np.column_stack([e.a_left, ~e.a_left])
    u = np.where(left, -v_lat, v_lat)
    beside = pair & ~e.in_line[:, None]
    applies[..., 3] = e.owed_lat[:, None] & beside
    actual[..., 3] = u
    # Once a car's speed towards the other is ≤ 0 from ρ on, it must stay there.
    bound[..., 3] = np.where(e.lat_settled, 0.0,
                             lateral_speed_bound(e.u0, tau, rho, p.lat_accel_max[cars], p.lat_brake_min[cars]))
    e.lat_settled = e.lat_settled | (judged[:, None] & beside & (tau >= rho - TIME_EPS) & (u <= 0.0))
    tolerance = np.full(actual.shape, step.accel_tolerance)
    # The velocity envelope's tolerance: the acceleration tolerance integrated while the envelope changes,
    # up to when it reaches 0; from then on "stay ≤ 0" does not loosen with time.
    settles = rho + np.maximum(e.u0 + p.lat_accel_max[cars] * rho, 0.0) / p.lat_brake_min[cars]
    tolerance[..., 3] = EPS_ACCEL * np.minimum(tau, settles)
    excess = sign * (actual - bound)
    violating = applies & judged[:, None, None] & (excess > tolerance)
    ended = _roll_violations(e, violating, actual, bound, excess, t, rho if join else np.zeros_like(rho))
    shown = np.where(applies & judged[:, None, None], bound, np.nan)
    return JudgedStep(e.serial, accel, np.fmin(shown[..., 0], shown[..., 1]), shown[..., 2],
                      np.where(pair, u, np.nan), shown[..., 3]), ended


def _update_lateral_order(e: OpenEpisodes, sit: PairSituations, rows: np.ndarray, candidate: np.ndarray,
                          mu: np.ndarray) -> None:
    """Which car is left of the other, as they are now (the side a lateral response keeps away from), and
    whether they are in line: centres within μ/2 across the road (the larger μ [m] of the two, ``mu`` [n, 2]),
    where neither side is towards the other (a car that cut in and now drives straight ahead in the other's
    lane). Kept from the last step seen where the pair is no road situation now."""
    if not len(sit) or sit.lat_offset is None:
        return
    offset = np.where(candidate, sit.lat_offset[rows], np.nan)
    lined_up = in_line(offset, mu[:, 0], mu[:, 1])  # NaN (junctions, not a candidate): False
    seen = candidate & np.isfinite(offset)
    e.in_line = np.where(seen, lined_up, e.in_line)
    e.a_left = np.where(seen & ~lined_up, sit.a_is_left[rows], e.a_left)


def _roll_violations(e: OpenEpisodes, violating: np.ndarray, actual: np.ndarray, bound: np.ndarray,
                     excess: np.ndarray, t: float, grace: np.ndarray) -> np.ndarray:
    """Start, extend and end the violation intervals [episode, car, constraint]; an interval ends once ``grace``
    [s] per car has passed since its last violating step. Returns the ended ones (still holding their values)."""
    starting = violating & ~e.active
    e.v_start = np.where(starting, t, e.v_start)
    worse = violating & (excess > e.v_excess)
    e.v_worst = np.where(worse, actual, e.v_worst)
    e.v_bound = np.where(worse, bound, e.v_bound)
    e.v_excess = np.where(worse, excess, e.v_excess)
    e.v_last = np.where(violating, t, e.v_last)
    ended = e.active & ~violating & (t - e.v_last > grace[..., None] + TIME_EPS)
    e.active = violating | (e.active & ~ended)
    e.responsible |= np.any(violating, axis=2)
    return ended


def instant_brake(step: StepInput, cars: np.ndarray) -> np.ndarray:
    """[m/s²] b_max of the persons among the road users ``cars`` (rows of ``step``), NaN for vehicles."""
    return np.where(step.vclass[cars] == PERSON_CLASS, step.params.lon_brake_max[cars], np.nan)


def area_progress(sit: PairSituations, rows: np.ndarray, speed: np.ndarray, accel: np.ndarray,
                  instant_brake: np.ndarray) -> dict[str, np.ndarray]:
    """[n, 2] per car of the crossing situations ``rows`` (``speed`` [m/s] and ``accel`` [m/s²] per car): its front
    bumper is in the conflict area or past its start ('entered'), it stands short of it ('stood_short'), it is
    short of it and stands or brakes hard enough to stop before it ('stopping'); all False on roads. A person
    (``instant_brake``: its b_max [m/s²], NaN for a vehicle) is also 'stopping' while braking at b_max would stop
    it before the area: SUMO's persons have no deceleration, they stop within a step where they are to wait."""
    if sit.enter_a is None:
        none = np.zeros((len(rows), 2), dtype=bool)
        return {"entered": none, "stood_short": none, "stopping": none}
    enter = np.column_stack([sit.enter_a[rows], sit.enter_b[rows]])  # NaN on roads: every comparison False
    short = enter > 0.0
    standing = short & (speed < STOPPED_SPEED)
    can_stop = speed * speed < 2.0 * instant_brake * enter  # NaN (a vehicle): False
    return {"entered": enter < 0.0, "stood_short": standing,
            "stopping": standing | (short & (((accel < 0.0) & (speed * speed < -2.0 * accel * enter)) | can_stop))}
