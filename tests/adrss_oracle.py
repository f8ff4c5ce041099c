"""Intel's ad_rss (PyPI ``ad-rss`` 5.0.0) as a test oracle for the safe distances of rss.md §2.

Test-only helper: ``from adrss_oracle import same_direction, opposite_direction, lateral``.
Inputs are in OUR conventions (rss.md §1): SI units, braking values as positive magnitudes, and any
object with the attributes of :class:`sumo_rss.rss.params.RssParams` (a ``SimpleNamespace`` will do).
Each function returns the ad_rss safe distance in metres and raises ``RuntimeError`` when ad_rss
reports failure (e.g. a speed outside [0, 100] m/s, ρ outside (0, 10] s or μ > 1 m); ad_rss then
also logs ``[error] withinValidInputRange...`` lines to stdout. Nothing is printed on success.

What ad_rss 5.0.0 does with these calls (checked by hand-worked numbers; all agree with rss.md §2):

- Same direction: the rear car's ρ, a_acc, b_min, ``max_speed_on_acceleration`` (v_cap) and λ
  (``min_longitudinal_safety_distance``) and the front car's b_max are used; λ is added *outside*
  the clamp: d = max(0, D_r − v_f²/(2·b_max,f)) + λ_r.  The front car's λ is ignored.
- Opposite direction: the correct-lane car brakes with b_corr, the other with b_min; each car's own
  v_cap applies; d = D_c + D_o + max(λ_c, λ_o).
- v_cap: v_ρ = min(max(v_cap, v), v + a_acc·ρ) with the exact accelerate-then-cruise distance; a car
  already faster than v_cap keeps its speed during ρ (it does not slow down to v_cap).
- Lateral: λ is not used; μ is ½(μ_L + μ_R) and lies *inside* the clamp: d = max(0, D_L + D_R + ½(μ_L+μ_R)).

ad_physics compares with a tolerance (1e-3 in Distance/Speed, 1e-4 in Acceleration), so compare with ~1e-3 m
tolerance and keep inputs away from these edges, where ad_rss deviates from the exact formula:
|v − v_cap| < 1e-3 m/s (treated as v = v_cap; up to (ρ + v/b)·1e-3 m off), 0 < |λ_c − λ_o| < 1e-3 m (it
may take λ_c instead of the max), a_acc < 1e-4 m/s² (~½·a·ρ² off), and a clamped result may come back as a
tiny negative number in (−1e-3, 0) instead of 0.
"""
from __future__ import annotations

import warnings
from typing import Protocol

with warnings.catch_warnings():
    # Importing the boost.python bindings warns (on stderr) about a converter registered twice.
    warnings.simplefilter("ignore", RuntimeWarning)
    import ad_rss  # note: this appends site-packages/ad_rss to sys.path (ad_rss's own __init__)

__all__ = ["same_direction", "opposite_direction", "lateral"]

_P = ad_rss.physics
_WORLD = ad_rss.rss.world
_CORE = ad_rss.rss.core
_STRUCTURED = ad_rss.rss.structured


class Params(Protocol):
    """Our per-vehicle RSS parameters (positive magnitudes, SI)."""

    response_time: float  # ρ [s]
    lon_accel_max: float  # a_acc [m/s²]
    lon_brake_min: float  # b_min [m/s²]
    lon_brake_min_correct: float  # b_corr [m/s²]
    lon_brake_max: float  # b_max [m/s²]
    lat_accel_max: float  # a_lat [m/s²]
    lat_brake_min: float  # b_lat [m/s²]
    lat_fluctuation_margin: float  # μ [m]
    min_lon_gap: float  # λ [m]
    max_speed_on_accel: float  # v_cap [m/s]


def _dynamics(p: Params) -> object:
    """ad_rss ``RssDynamics`` with every field set (a default-constructed one holds NaNs)."""
    d = _WORLD.RssDynamics()
    d.response_time = _P.Duration(float(p.response_time))
    d.alpha_lon.accel_max = _P.Acceleration(float(p.lon_accel_max))
    # ad_rss decelerations are negative: brake_max <= brake_min <= brake_min_correct < 0.
    d.alpha_lon.brake_min = _P.Acceleration(-float(p.lon_brake_min))
    d.alpha_lon.brake_min_correct = _P.Acceleration(-float(p.lon_brake_min_correct))
    d.alpha_lon.brake_max = _P.Acceleration(-float(p.lon_brake_max))
    d.alpha_lat.accel_max = _P.Acceleration(float(p.lat_accel_max))
    d.alpha_lat.brake_min = _P.Acceleration(-float(p.lat_brake_min))
    d.lateral_fluctuation_margin = _P.Distance(float(p.lat_fluctuation_margin))
    d.min_longitudinal_safety_distance = _P.Distance(float(p.min_lon_gap))
    d.max_speed_on_acceleration = _P.Speed(float(p.max_speed_on_accel))
    # Unused by the structured formulas, but validated: ad_rss / CARLA defaults.
    u = d.unstructured_settings
    u.pedestrian_turning_radius = _P.Distance(2.0)
    u.drive_away_max_angle = _P.Angle(2.4)
    u.vehicle_yaw_rate_change = _P.AngularAcceleration(0.3)
    u.vehicle_min_radius = _P.Distance(3.5)
    u.vehicle_trajectory_calculation_step = _P.Duration(0.2)
    return d


def fill_unstructured(un: object, speed_min: float, speed_max: float) -> None:
    """Fill an ad_rss unstructured object state with finite placeholder values and the given speed range [m/s]
    (ad_rss validates it even in structured situations; its defaults are NaN)."""
    un.yaw = _P.Angle(0.0)
    un.yaw_rate = _P.AngularVelocity(0.0)
    un.steering_angle = _P.Angle(0.0)
    un.dimension.length = _P.Distance(4.5)
    un.dimension.width = _P.Distance(1.8)
    un.center_point.x = _P.Distance(0.0)
    un.center_point.y = _P.Distance(0.0)
    un.speed_range.minimum = _P.Speed(speed_min)
    un.speed_range.maximum = _P.Speed(speed_max)


def _state(p: Params, speed_lon: float, speed_lat: float) -> object:
    """ad_rss ``RelativeObjectState`` of a vehicle with an exact (min = max) speed in ad_rss's frame.

    ``speed_lon`` [m/s] along the road (>= 0); ``speed_lat`` [m/s] in ad_rss's convention (+ = right).
    """
    s = _CORE.RelativeObjectState()
    s.object_type = _WORLD.ObjectType.OtherVehicle
    s.dynamics = _dynamics(p)
    # The unstructured part is validated too (defaults are NaN): any finite values do.
    fill_unstructured(s.unstructured_object_state, float(speed_lon), float(speed_lon))
    st = s.structured_object_state
    # The default 1e9 m fails ad_rss's own input-range check; not used by these formulas.
    st.distance_to_enter_intersection = _P.Distance(0.0)
    st.distance_to_leave_intersection = _P.Distance(0.0)
    v = st.velocity
    v.speed_lon_min = _P.Speed(float(speed_lon))
    v.speed_lon_max = _P.Speed(float(speed_lon))
    v.speed_lat_min = _P.Speed(float(speed_lat))
    v.speed_lat_max = _P.Speed(float(speed_lat))
    return s


def _call(name: str, first: object, second: object, args: tuple[float, ...]) -> float:
    out = _P.Distance(0.0)
    if not getattr(_STRUCTURED, name)(first, second, out):
        raise RuntimeError(f"ad_rss {name} failed for speeds {args} (see ad_rss's log on stdout)")
    return float(out.mDistance)


def same_direction(v_rear: float, v_front: float, p_rear: Params, p_front: Params) -> float:
    """Safe longitudinal distance [m] of a rear car behind a front car driving the same way.

    ``v_rear``, ``v_front``: longitudinal speeds [m/s], >= 0. Includes the rear car's λ.
    """
    return _call("calculateSafeLongitudinalDistanceSameDirection",
                 _state(p_front, v_front, 0.0), _state(p_rear, v_rear, 0.0), (v_rear, v_front))


def opposite_direction(v_correct: float, v_other: float, p_correct: Params, p_other: Params) -> float:
    """Safe longitudinal distance [m] of two cars approaching each other.

    ``v_correct``: speed [m/s] of the car in its correct lane (brakes with b_corr); ``v_other``: speed of
    the other car (brakes with b_min). Both are magnitudes towards each other, >= 0. Includes max(λ_c, λ_o).
    """
    return _call("calculateSafeLongitudinalDistanceOppositeDirection",
                 _state(p_correct, v_correct, 0.0), _state(p_other, v_other, 0.0), (v_correct, v_other))


def lateral(v_left: float, v_right: float, p_left: Params, p_right: Params) -> float:
    """Safe lateral distance [m] between a car on the left and a car on the right.

    ``v_left``, ``v_right``: each car's OWN lateral speed [m/s] in our convention (+ = to the left).

    ad_rss wants each car's own lateral velocity in its frame (+ = to the right), not the speed towards
    the other car: it reads the left car's ``speed_lat_max`` and the right car's ``speed_lat_min`` and
    flips the right car's accelerations itself. So both speeds are simply negated here. In rss.md §2's
    terms the speeds towards the other car are u_L = −v_left and u_R = +v_right.
    Example (ad_rss defaults, μ = 0): v_left = −1 (left car moving right, towards the other) gives
    2.125 m; v_left = +1 (moving away) gives 0. Includes ½(μ_L + μ_R); λ is not used.
    """
    return _call("calculateSafeLateralDistance",
                 _state(p_left, 0.0, -v_left), _state(p_right, 0.0, -v_right), (v_left, v_right))
