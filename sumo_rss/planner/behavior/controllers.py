"""Controllers and vehicle model of EUDM's forward simulation (epsilon.md §3), vectorised over arrays.

- :func:`acc_acceleration`: Treiber-Kesting ACC (improved IDM + constant-acceleration heuristic), with the port's
  fixes: the heuristic uses the net gap, the braking floor uses the step ``dt`` (so the speed cannot go negative),
  and a desired speed of 0 means "stop"; optionally (``IdmParams.approach_time``) a free-road term that reaches the
  desired speed at the acceleration limit instead of IDM's asymptotic approach.
- :func:`pure_pursuit_steer`: steering towards a look-ahead point.
- :func:`bicycle_step`: the "ideal steer" kinematic bicycle (rear-axle reference) with acceleration/jerk,
  lateral-acceleration/jerk and steer-angle/rate limits, integrated with RK4.
Each is :func:`~sumo_rss.jit.jitable`: numpy runs it over arrays, the forward-simulation kernel compiles it for
scalars (parameter objects there are named tuples with the dataclasses' fields).
Units: m, s, m/s, m/s², rad.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ...angles import cos_sin, wrap_angle
from ...jit import as_float, jitable, select

V0_STOP = 1e-3  # [m/s] a desired speed below this means "stop"


@jitable
def clamp(x: Any, low: Any, high: Any) -> np.ndarray:
    """``np.clip`` with less call overhead (these run many times per planning cycle on small arrays)."""
    return np.minimum(np.maximum(x, low), high)


@dataclass(frozen=True)
class IdmParams:
    """Car-following parameters (epsilon.md §3.1: ego s0 2.0, T 1.0, a 1.0; agents s0 1.0, T 0.5, a 2.0)."""

    s0: float = 2.0  # [m] minimum spacing
    headway: float = 1.0  # [s] T
    accel: float = 1.0  # [m/s²] a
    comfort_brake: float = 1.67  # [m/s²] b
    hard_brake: float = 5.0  # [m/s²] acceleration floor
    exponent: float = 4.0  # δ
    coolness: float = 0.99  # c of the ACC model
    # [s] τ > 0: below the desired speed the free-road term is min(a, (v0 − v)/τ), a speed target reached at the
    # acceleration limit; 0: IDM's a·(1 − (v/v0)^δ), whose time constant near v0 is v0/(a·δ) (4.1 s at 33 m/s)
    approach_time: float = 0.0


@dataclass(frozen=True)
class VehicleLimits:
    """Limits of the bicycle model (epsilon.md §3.1, ego values as defaults)."""

    wheelbase: float = 2.85  # [m] (epsilon.md's default vehicle)
    max_accel: float = 1.0  # [m/s²]
    hard_brake: float = 5.0  # [m/s²]
    accel_jerk: float = 3.0  # [m/s³]
    brake_jerk: float = 5.0  # [m/s³]
    lat_accel: float = 1.2  # [m/s²]
    lat_jerk: float = 1.8  # [m/s³]
    max_steer: float = 0.785  # [rad]
    max_steer_rate: float = 0.39  # [rad/s]


@jitable(quiet=True)
def acc_acceleration(v: Any, v0: Any, v_lead: Any, gap: Any, p: IdmParams, min_distance: Any = 0.0) -> np.ndarray:
    """ACC acceleration [m/s²] at speed ``v`` with desired speed ``v0``, a leader at ``v_lead`` (clamped ≥ 0) and
    net bumper gap ``gap`` [m] (use a large gap and v_lead = v for a free road). Clipped to [−hard_brake, a].
    ``min_distance`` [m]: a floor on the headway distance v·T of the desired gap (the RSS safe distance)."""
    v, v0 = as_float(v), as_float(v0)
    v_lead = np.maximum(v_lead, 0.0)
    a, b, delta = p.accel, p.comfort_brake, p.exponent
    s_net = np.maximum(gap, 1e-3)
    headway = np.maximum(v * p.headway, min_distance)
    s_star = p.s0 + np.maximum(0.0, headway + v * (v - v_lead) / (2.0 * np.sqrt(a * b)))
    z = s_star / s_net
    stop = v0 < V0_STOP
    v0_safe = select(stop, 1.0, v0)
    tau = p.approach_time
    rising = select(tau > 0.0, np.minimum(a, (v0_safe - v) / np.maximum(tau, 1e-9)),
                    a * (1.0 - (v / v0_safe) ** delta))
    a_free = select(v <= v0_safe, rising,
                    -b * (1.0 - (v0_safe / np.maximum(v, 1e-9)) ** (a * delta / b)))
    a_free = select(stop, -b, a_free)
    below = select(z >= 1.0, a * (1.0 - z * z),
                   select(np.abs(a_free) > 1e-12, a_free * (1.0 - z ** (2.0 * a / a_free)), 0.0))
    above = select(z >= 1.0, a_free + a * (1.0 - z * z), a_free)
    # "Stop" (v0 = 0) is always the decelerating regime: the below-v0 formula assumes a_free > 0.
    a_iidm = clamp(select((v <= v0_safe) & ~stop, below, above), -p.hard_brake, a)
    # Constant-acceleration heuristic, leader braking at b, on the net gap.
    a_cah = -b * v * v / (v_lead * v_lead + 2.0 * b * s_net)
    blended = (1.0 - p.coolness) * a_iidm + p.coolness * (a_cah + b * np.tanh((a_iidm - a_cah) / b))
    return clamp(select(a_iidm >= a_cah, a_iidm, blended), -p.hard_brake, a)


@jitable(quiet=True)
def idm_speed_command(v: Any, v0: Any, v_lead: Any, gap: Any, p: IdmParams, dt: float,
                      min_distance: Any = 0.0) -> np.ndarray:
    """Speed command [m/s] for the end of a step of ``dt`` s; braking never goes below standstill."""
    v = as_float(v)
    accel = np.maximum(acc_acceleration(v, v0, v_lead, gap, p, min_distance), -np.minimum(p.hard_brake, v / dt))
    return np.maximum(v + accel * dt, 0.0)


@jitable
def lookahead(v: Any, gain: float, minimum: float, maximum: float) -> np.ndarray:
    """Pure-pursuit look-ahead distance ℓ = clamp(gain·v, min, max) [m]."""
    return clamp(gain * as_float(v), minimum, maximum)


@jitable
def pure_pursuit_steer(x: Any, y: Any, heading: Any, target_x: Any, target_y: Any, wheelbase: float) -> np.ndarray:
    """Steering angle [rad] towards the target point: δ = atan2(2·L·sin α, ‖target − position‖), α the bearing
    of the target relative to the heading (rear-axle reference)."""
    dx, dy = as_float(target_x) - as_float(x), as_float(target_y) - as_float(y)
    cos_h, sin_h = cos_sin(heading)
    # sin α = (dy·cos h − dx·sin h) / ‖d‖; both arguments of the arctangent scaled by ‖d‖ > 0.
    return np.arctan2(2.0 * wheelbase * (dy * cos_h - dx * sin_h), dx * dx + dy * dy)


class BicycleState(NamedTuple):
    """Rear-axle pose and motion of many vehicles (arrays of one shape, or floats in the kernel)."""

    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray  # [rad]
    speed: np.ndarray  # [m/s]
    accel: np.ndarray  # [m/s²] applied during the last step
    curvature: np.ndarray  # [1/m] tan(steer) / wheelbase


@jitable
def bicycle_step(state: BicycleState, speed_cmd: Any, steer_cmd: Any, limits: VehicleLimits, dt: float,
                 max_accel: Any = None) -> BicycleState:
    """Advance by ``dt`` s towards the commanded speed and steering, within the limits (epsilon.md §3.2);
    ``max_accel`` [m/s²] replaces ``limits.max_accel`` for this step where given."""
    L = limits.wheelbase
    v, curvature = state.speed, state.curvature
    steer = np.arctan(curvature * L)
    v_cmd = np.maximum(speed_cmd, 0.0)
    steer_cmd = clamp(steer_cmd, -limits.max_steer, limits.max_steer)
    # Longitudinal shaping: jerk, then acceleration limits.
    jerk = clamp(((v_cmd - v) / dt - state.accel) / dt, -limits.brake_jerk, limits.accel_jerk)
    accel = clamp(state.accel + jerk * dt, -limits.hard_brake, limits.max_accel if max_accel is None else max_accel)
    v_new = np.maximum(v + accel * dt, 0.0)
    # Lateral shaping: lateral jerk and acceleration limits, then the steer rate (both angles lie in ±π/2, so
    # their difference needs no wrapping).
    v_new_sq = v_new * v_new
    a_lat_des = v_new_sq * np.tan(steer_cmd) / L
    a_lat_now = v * v * curvature
    a_lat = clamp(a_lat_now + clamp(a_lat_des - a_lat_now, -limits.lat_jerk * dt, limits.lat_jerk * dt),
                  -limits.lat_accel, limits.lat_accel)
    steer_target = np.arctan(a_lat * L / np.maximum(v_new_sq, 0.01))
    steer_new = steer + clamp(steer_target - steer, -limits.max_steer_rate * dt, limits.max_steer_rate * dt)
    # Integrate ẋ = v cos θ, ẏ = v sin θ, θ̇ = v tan δ / L with v and δ linear over the step (one RK4 step).
    # The yaw rate depends on time only, so it is evaluated once per RK4 stage time (0, dt/2, dt).
    x, y, th = state.x, state.y, state.heading
    v_mid = 0.5 * (v + v_new)
    curvature_new = np.tan(steer_new) / L
    w0, w_mid, w_end = v * curvature, v_mid * np.tan(0.5 * (steer + steer_new)) / L, v_new * curvature_new
    cos0, sin0 = cos_sin(th)  # the RK4 stages' θ
    cos1, sin1 = cos_sin(th + dt / 2 * w0)
    cos2, sin2 = cos_sin(th + dt / 2 * w_mid)
    cos3, sin3 = cos_sin(th + dt * w_mid)
    x = x + dt / 6 * (v * cos0 + 2 * v_mid * (cos1 + cos2) + v_new * cos3)
    y = y + dt / 6 * (v * sin0 + 2 * v_mid * (sin1 + sin2) + v_new * sin3)
    th = th + dt / 6 * (w0 + 4 * w_mid + w_end)
    return BicycleState(x, y, wrap_angle(th), v_new, (v_new - v) / dt, curvature_new)
