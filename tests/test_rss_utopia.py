"""The utopia lemma (paper Lemma 4): if both cars follow the proper response from a safe start, they never
collide, whatever else they do.

Simulated with the project's own formulas and exact 1-D kinematics: accelerations are piecewise constant,
steps are split at every event (profile changes, the end of the response time), and the danger threshold t_b
is found inside a step by bisection, so the response starts exactly when RSS says it must.
"""
from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from sumo_rss.rss.formulas import is_safe_distance, lon_safe_distance_same_dir
from sumo_rss.rss.params import RssParams

DT = 0.01  # [s] longest step
HORIZON = 25.0  # [s]
TOUCH = 1e-6  # [m] the worst case may end with the cars touching (gap 0 up to rounding); an overlap fails

fractions = st.floats(-1.0, 1.0)  # of the allowed range: −1 → brake at b_max, +1 → accelerate at a_acc
profile = st.lists(st.tuples(st.floats(0.2, 5.0), fractions), min_size=1, max_size=6)  # (duration [s], fraction)


def _move(v: float, a: float, h: float, cap: float = math.inf) -> tuple[float, float]:
    """(speed, distance) after ``h`` s at constant ``a`` from ``v``: stops at 0, accelerates at most to ``cap``."""
    if a > 0.0 and v >= cap:
        a = 0.0
    if a > 0.0 and v + a * h > cap:
        t1 = (cap - v) / a
        return cap, v * t1 + 0.5 * a * t1 * t1 + cap * (h - t1)
    if a < 0.0 and v + a * h < 0.0:
        return 0.0, v * v / (-2.0 * a)
    return v + a * h, v * h + 0.5 * a * h * h


def _segment(segments, t: float, p: RssParams) -> tuple[float, float]:
    """(accel, time to the next change) of a profile at time t; 0 m/s² after its end."""
    for duration, frac in segments:
        if t < duration - 1e-12:
            return frac * (p.lon_accel_max if frac > 0 else p.lon_brake_max), duration - t
        t -= duration
    return 0.0, math.inf


@settings(max_examples=150, deadline=None)
@given(v_rear=st.floats(0.0, 40.0), v_front=st.floats(0.0, 40.0), extra_gap=st.floats(0.01, 40.0),
       front_profile=profile, rear_profile=profile,
       p=st.sampled_from([RssParams(), RssParams(response_time=0.5, lon_brake_min=5.0),
                          RssParams(response_time=2.0, min_lon_gap=1.0, max_speed_on_accel=25.0)]))
def test_two_cars_following_the_proper_response_never_collide(v_rear, v_front, extra_gap, front_profile,
                                                             rear_profile, p):
    def safe(gap: float, vr: float, vf: float) -> bool:
        return bool(is_safe_distance(gap, lon_safe_distance_same_dir(vr, vf, p, p)))

    gap = float(lon_safe_distance_same_dir(v_rear, v_front, p, p)) + extra_gap
    t, t_b = 0.0, None
    while t < HORIZON:
        a_front, front_left = _segment(front_profile, t, p)  # the front car: anything in [−b_max, a_acc]
        if t_b is None:  # safe: the rear car is free too
            a_rear, rear_left = _segment(rear_profile, t, p)
            cap = math.inf
        elif t < t_b + p.response_time:  # danger, within ρ: at most a_acc up to the speed cap
            a_rear, rear_left, cap = p.lon_accel_max, t_b + p.response_time - t, p.max_speed_on_accel
        else:  # after ρ: brake at b_min (until stopped)
            a_rear, rear_left, cap = -p.lon_brake_min, math.inf, math.inf
        h = min(DT, front_left, rear_left, HORIZON - t)

        def advance(dt: float) -> tuple[float, float, float]:
            vf, df = _move(v_front, a_front, dt)
            vr, dr = _move(v_rear, a_rear, dt, cap)
            return gap + df - dr, vr, vf

        new_gap, new_vr, new_vf = advance(h)
        if t_b is None and not safe(new_gap, new_vr, new_vf):
            lo, hi = 0.0, h  # safe at t + lo, unsafe at t + hi: find the threshold
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if safe(*advance(mid)) else (lo, mid)
            h = hi
            new_gap, new_vr, new_vf = advance(h)
            t_b = t + h
        elif t_b is not None and safe(new_gap, new_vr, new_vf):
            t_b = None  # safe again: the episode is over
        gap, v_rear, v_front, t = new_gap, new_vr, new_vf, t + h
        assert gap > -TOUCH, f"collision at t = {t:.3f} s (gap {gap:.6f} m)"
