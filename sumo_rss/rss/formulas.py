"""RSS safe distances and safe speeds, vectorised (rss.md §2; Shalev-Shwartz et al., arXiv 1708.06374 v6).

Every function broadcasts over numpy arrays: speeds, gaps and the fields of the parameter objects may be
scalars or arrays of one shape. A parameter object is anything with the attributes of
:class:`~sumo_rss.rss.params.RssParams` — one ``RssParams`` for scalars or an
:class:`~sumo_rss.rss.params.RssParamArrays` with one row per pair.

The same functions are compiled into the planner's forward-simulation kernel (one source of the formulas for the
auditor and the planner): each is :func:`~sumo_rss.jit.jitable`, its body written so that numpy runs it over arrays
and numba over scalars (``select`` for ``np.where``, ``as_float`` for ``np.asarray(x, dtype=float)``), with a
parameter object there a named tuple of floats (:data:`~sumo_rss.jit.RssRow`).

Units: speeds m/s, distances m, accelerations m/s² (brakes as positive magnitudes), times s.
Conventions match ad_rss, so results compare number for number.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..jit import as_float, jitable, select

SAFE_DISTANCE_PRECISION = 1e-3  # [m] a distance is safe iff it exceeds d_min by more than this (ad_rss)


# ---------------------------------------------------------------------------------------------------------
# Kinematic helpers
# ---------------------------------------------------------------------------------------------------------
@jitable
def speed_after_response(v: Any, accel: Any, response_time: Any, speed_cap: Any) -> np.ndarray:
    """Speed after accelerating at ``accel`` for ``response_time``, capped at ``speed_cap``.

    v_ρ = min(max(v_cap, v), v + a·ρ): a car already above the cap keeps its speed.
    """
    v = as_float(v)
    return np.minimum(np.maximum(speed_cap, v), v + accel * response_time)


@jitable
def distance_during_response(v: Any, accel: Any, response_time: Any, speed_cap: Any) -> np.ndarray:
    """Distance covered while accelerating at ``accel`` up to the capped speed v_ρ, then cruising, for ρ.

    With t₁ = (v_ρ − v)/a the time to reach v_ρ: v·t₁ + a·t₁²/2 + v_ρ·(ρ − t₁) = v_ρ·ρ − (v_ρ − v)²/(2a)
    (0 extra when a = 0, where v_ρ = v).
    """
    v = as_float(v)
    v_rho = speed_after_response(v, accel, response_time, speed_cap)
    return _distance_during_response(v, v_rho, accel, response_time)


@jitable
def _distance_during_response(v: np.ndarray, v_rho: np.ndarray, accel: Any, response_time: Any) -> np.ndarray:
    dv = v_rho - v
    return v_rho * response_time - dv * dv / (2.0 * np.maximum(accel, _TINY_ACCEL))


_TINY_ACCEL = 1e-300  # [m/s²] guards a = 0, where v_ρ − v = 0 exactly


@jitable
def stopping_distance(v: Any, brake: Any) -> np.ndarray:
    """Distance to stop from speed ``v`` braking at ``brake`` (> 0): v² / (2·b)."""
    v = as_float(v)
    return v * v / (2.0 * brake)


@jitable
def worst_case_stopping_distance(v: Any, accel: Any, response_time: Any, speed_cap: Any, brake: Any) -> np.ndarray:
    """Distance a car covers if it accelerates at ``accel`` during ρ (capped), then brakes at ``brake``.

    D(v) = dist_ρ(v) + v_ρ² / (2·b).
    """
    v = as_float(v)
    v_rho = speed_after_response(v, accel, response_time, speed_cap)
    return _distance_during_response(v, v_rho, accel, response_time) + v_rho * v_rho / (2.0 * brake)


@jitable
def lon_reach(v: Any, p: Any, brake: Any) -> np.ndarray:
    """Worst-case distance of a car with parameters ``p`` at speed ``v`` [m/s] that brakes at ``brake`` after
    accelerating during ρ: D = dist_ρ(v) + v_ρ²/(2·brake) [m]."""
    return worst_case_stopping_distance(v, p.lon_accel_max, p.response_time, p.max_speed_on_accel, brake)


@jitable(quiet=True)
def time_to_cover(v: Any, distance: Any, response_time: Any, accel_response: Any, accel_after: Any,
                  speed_cap: Any) -> np.ndarray:
    """Time [s] to cover ``distance`` [m] from speed ``v`` [m/s]: ``accel_response`` during ρ (speed floored at
    0, capped at max(v_cap, v) when accelerating), then ``accel_after`` (< 0: braking). inf if the car stops
    first; 0 for distance <= 0. Accelerations are signed [m/s²]."""
    v, d, rho, a1, a2 = as_float(v), as_float(distance), response_time, accel_response, accel_after
    # Phase 1 (ρ). Accelerating: up to the cap at t_c, then cruising. Braking: possibly to a standstill.
    top = select(a1 > 0, np.minimum(np.maximum(speed_cap, v), v + a1 * rho), v)
    t_c = select(a1 > 0, (top - v) / select(a1 > 0, a1, 1.0), 0.0)
    d_c = v * t_c + 0.5 * a1 * t_c * t_c
    stop_1 = select(a1 < 0, v / select(a1 < 0, -a1, 1.0), np.inf)
    braking_stops = stop_1 < rho
    v_rho = select(a1 > 0, top, select(braking_stops, 0.0, v + np.minimum(a1, 0.0) * rho))
    d_rho = select(a1 > 0, d_c + top * (rho - t_c),
                   select(braking_stops, v * v / (2.0 * select(a1 < 0, -a1, 1.0)),
                          v * rho + 0.5 * np.minimum(a1, 0.0) * rho * rho))
    # Time within phase 1.
    t_acc = select(d <= d_c, select(np.abs(a1) > 0, (-v + np.sqrt(v * v + 2.0 * a1 * d)) / a1, d / v),
                   t_c + (d - d_c) / top)
    t_brake1 = (v - np.sqrt(np.maximum(v * v + 2.0 * a1 * d, 0.0))) / select(a1 < 0, -a1, 1.0)
    t_first = select(a1 > 0, t_acc, select(a1 < 0, t_brake1, d / v))
    # Phase 2: braking at accel_after from v_rho.
    rest = d - d_rho
    disc = v_rho * v_rho + 2.0 * a2 * rest
    t_second = rho + (v_rho - np.sqrt(np.maximum(disc, 0.0))) / select(a2 < 0, -a2, 1.0)
    reachable_2 = (v_rho > 0) & (disc >= 0) & (a2 < 0)
    t = select(d <= d_rho, t_first, select(reachable_2, t_second, np.inf))
    return select(d <= 0.0, 0.0, select(np.isfinite(t) & (t >= 0), t, np.inf))


# The safe distances combine per-car terms; the auditor computes those terms once per vehicle and combines them
# per pair with the same functions, so both paths give bit-identical numbers.
@jitable
def combine_same_dir(rear_reach: Any, front_stop: Any, rear_min_gap: Any) -> np.ndarray:
    """d_min = max(0, D_rear − S_front) + λ_rear [m]."""
    return np.maximum(as_float(rear_reach) - front_stop, 0.0) + rear_min_gap


@jitable
def combine_opposite(reach_correct: Any, reach_other: Any, gap_correct: Any, gap_other: Any) -> np.ndarray:
    """d_min = D_correct + D_other + max(λ_correct, λ_other) [m]."""
    return as_float(reach_correct) + reach_other + np.maximum(gap_correct, gap_other)


@jitable
def combine_lateral(reach_left: Any, reach_right: Any, margin_left: Any, margin_right: Any) -> np.ndarray:
    """d_min = max(0, D_L + D_R + (μ_L + μ_R)/2) [m]."""
    return np.maximum(as_float(reach_left) + reach_right + 0.5 * (as_float(margin_left) + margin_right), 0.0)


# ---------------------------------------------------------------------------------------------------------
# Safe distances
# ---------------------------------------------------------------------------------------------------------
@jitable
def lon_safe_distance_same_dir(v_rear: Any, v_front: Any, p_rear: Any, p_front: Any) -> np.ndarray:
    """Safe longitudinal distance, same direction (paper Def. 1).

    Worst case: the rear car accelerates at a_acc for ρ (up to v_cap), then brakes only at b_min; the front car
    brakes at b_max at once.

        rear ──▶ v_rear          front ──▶ v_front
        [====]······ d ······[====]

    d_min = max(0, D_rear − v_front²/(2·b_max,front)) + λ_rear, D_rear = dist_ρ(v_rear) + v_ρ²/(2·b_min,rear).
    Speeds ≥ 0 [m/s]; result [m], bumper to bumper.
    """
    return combine_same_dir(lon_reach(v_rear, p_rear, p_rear.lon_brake_min),
                            stopping_distance(v_front, p_front.lon_brake_max), p_rear.min_lon_gap)


@jitable
def lon_safe_distance_opposite(v_correct: Any, v_other: Any, p_correct: Any, p_other: Any,
                               both_correct: bool | np.ndarray = False) -> np.ndarray:
    """Safe longitudinal distance, opposite directions (paper Def. 2).

    Worst case: both cars accelerate towards each other for ρ, then the car in its correct lane brakes at b_corr
    and the other at b_min (both at b_corr when ``both_correct``).

        correct ──▶ v_correct        v_other ◀── other
        [====]··········· d ···········[====]

    d_min = [dist_ρ(v_c) + v_ρ,c²/(2·b_corr,c)] + [dist_ρ(v_o) + v_ρ,o²/(2·b,o)] + max(λ_c, λ_o).
    Speeds are magnitudes towards each other, ≥ 0 [m/s]; result [m].
    """
    other_brake = select(both_correct, p_other.lon_brake_min_correct, p_other.lon_brake_min)
    return combine_opposite(lon_reach(v_correct, p_correct, p_correct.lon_brake_min_correct),
                            lon_reach(v_other, p_other, other_brake), p_correct.min_lon_gap, p_other.min_lon_gap)


@jitable
def lat_safe_distance(v_left: Any, v_right: Any, p_left: Any, p_right: Any) -> np.ndarray:
    """Safe lateral distance (paper Def. 4, signs as in ad_rss).

    ``v_left``, ``v_right``: each car's own lateral speed, + = to the left [m/s]. Worst case: both cars
    accelerate laterally towards each other at a_lat for ρ, then brake laterally at b_lat until their lateral
    speed towards the other is 0 (no braking term for a car still moving away after ρ).

        left car   [====]  ↓ u_L = −v_left
                      d
        right car  [====]  ↑ u_R = +v_right

    For each car, with u its speed towards the other: u_ρ = u + a_lat·ρ,
    D = (u + u_ρ)/2·ρ + max(u_ρ, 0)²/(2·b_lat);  d_min = max(0, D_L + D_R + (μ_L + μ_R)/2)  [m].
    """
    return combine_lateral(lateral_reach(-as_float(v_left), p_left), lateral_reach(v_right, p_right),
                           p_left.lat_fluctuation_margin, p_right.lat_fluctuation_margin)


@jitable
def lateral_reach(u: Any, p: Any) -> np.ndarray:
    """Lateral distance one car covers towards the other in the worst case (its share of Def. 4) [m].

    ``u``: lateral speed towards the other car [m/s]. u_ρ = u + a_lat·ρ;
    reach = (u + u_ρ)/2·ρ + max(u_ρ, 0)²/(2·b_lat) (no braking term when still moving away after ρ).
    """
    u = as_float(u)
    u_rho = u + p.lat_accel_max * p.response_time
    return (u + u_rho) / 2.0 * p.response_time + np.maximum(u_rho, 0.0) ** 2 / (2.0 * p.lat_brake_min)


@jitable
def is_safe_distance(distance: Any, d_min: Any) -> np.ndarray:
    """``distance`` [m] is safe iff it exceeds ``d_min`` [m] by more than 1 mm (ad_rss's precision)."""
    return as_float(distance) > as_float(d_min) + SAFE_DISTANCE_PRECISION


# ---------------------------------------------------------------------------------------------------------
# Safe speed interval (EPSILON's use)
# ---------------------------------------------------------------------------------------------------------
@jitable
def max_safe_speed_behind(gap: Any, v_front: Any, p_self: Any, p_front: Any) -> np.ndarray:
    """Largest own speed [m/s] that keeps ``gap`` [m] to a front car at ``v_front`` safe (same direction).

    Solves D_self(v) = gap − λ_self + v_front²/(2·b_max,front) for v, where D is continuous and increasing in
    v with three regimes: v + a·ρ ≤ v_cap (uncapped), v < v_cap < v + a·ρ (reaches the cap), v ≥ v_cap
    (no acceleration). Returns −inf where even v = 0 is unsafe.
    """
    a, rho, cap, b = p_self.lon_accel_max, p_self.response_time, p_self.max_speed_on_accel, p_self.lon_brake_min
    budget = as_float(gap) - p_self.min_lon_gap + stopping_distance(v_front, p_front.lon_brake_max)
    # Regime 1: with w = v + a·ρ, D = w²/(2b) + w·ρ − a·ρ²/2  →  w = −b·ρ + sqrt(b²ρ² + b(aρ² + 2C)).
    w = -b * rho + np.sqrt(np.maximum(b * b * rho * rho + b * (a * rho * rho + 2.0 * budget), 0.0))
    v1 = w - a * rho
    # Regime 2: D = v_cap·ρ + v_cap²/(2b) − (v_cap − v)²/(2a)  →  v = v_cap − sqrt(2a(v_cap·ρ + v_cap²/(2b) − C)).
    a_pos = select(as_float(a) > 0.0, a, 1.0)
    v2 = cap - np.sqrt(np.maximum(2.0 * a_pos * (cap * rho + cap * cap / (2.0 * b) - budget), 0.0))
    # Regime 3: D = v·ρ + v²/(2b)  →  v = −b·ρ + sqrt(b²ρ² + 2bC).
    v3 = -b * rho + np.sqrt(np.maximum(b * b * rho * rho + 2.0 * b * budget, 0.0))
    v = select(v1 + a * rho <= cap, v1, select(v3 >= cap, v3, v2))
    # d_min = max(0, D − F) + λ: the gap must also cover λ on its own.
    unsafe_at_standstill = (worst_case_stopping_distance(0.0, a, rho, cap, b) > budget) | \
        (as_float(gap) < p_self.min_lon_gap)
    return select(unsafe_at_standstill, -np.inf, np.maximum(v, 0.0))


@jitable
def min_safe_speed_ahead(gap: Any, v_rear: Any, p_self: Any, p_rear: Any) -> np.ndarray:
    """Smallest own speed [m/s] that keeps ``gap`` [m] to a rear car at ``v_rear`` safe (same direction).

    Solves D_rear(v_rear) − v²/(2·b_max,self) + λ_rear ≤ gap:  v = sqrt(max(0, 2·b_max·(D_rear + λ_rear − gap))).
    Returns +inf where no speed is safe: d_min = max(0, ·) + λ_rear, so a gap below λ_rear is never enough.
    """
    return min_safe_speed_ahead_of_reach(gap, lon_reach(v_rear, p_rear, p_rear.lon_brake_min), p_rear.min_lon_gap,
                                         p_self.lon_brake_max)


@jitable
def min_safe_speed_ahead_of_reach(gap: Any, rear_reach: Any, rear_min_gap: Any, brake_max: Any) -> np.ndarray:
    """:func:`min_safe_speed_ahead` from the rear car's reach D_rear [m] (:func:`lon_reach` at b_min), its λ [m]
    and the own b_max [m/s²]."""
    gap = as_float(gap)
    need = as_float(rear_reach) + rear_min_gap - gap
    return select(gap < rear_min_gap, np.inf, np.sqrt(np.maximum(2.0 * brake_max * need, 0.0)))


@jitable
def safe_speed_interval_same_dir(gap_front: Any, v_front: Any, p_front: Any, gap_rear: Any, v_rear: Any,
                                 p_rear: Any, p_self: Any) -> tuple[np.ndarray, np.ndarray]:
    """[v_low, v_high] [m/s] of own speeds safe to both the front and the rear car.

    Pass ``gap_front = inf`` (or ``gap_rear = inf``) where there is no such car. The interval is empty where
    v_low > v_high.
    """
    v_high = select(np.isinf(gap_front), np.inf, max_safe_speed_behind(
        select(np.isinf(gap_front), 0.0, gap_front), v_front, p_self, p_front))
    v_low = select(np.isinf(gap_rear), 0.0, min_safe_speed_ahead(
        select(np.isinf(gap_rear), 0.0, gap_rear), v_rear, p_self, p_rear))
    return v_low, v_high
