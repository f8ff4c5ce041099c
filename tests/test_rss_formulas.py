"""RSS formulas against hand-worked numbers (rss.md §2, ad_rss default parameters) and their properties."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sumo_rss.rss.formulas import (distance_during_response, is_safe_distance, lat_safe_distance,
                                   lon_safe_distance_opposite, lon_safe_distance_same_dir, max_safe_speed_behind,
                                   min_safe_speed_ahead, safe_speed_interval_same_dir, speed_after_response,
                                   worst_case_stopping_distance)
from sumo_rss.rss.params import RssParamArrays, RssParams

TOL = 1e-9  # [m] closed forms are exact up to floating point
AD_RSS = RssParams()  # ρ 1 s, a_acc 3.5, b_min 4, b_corr 3, b_max 8, a_lat 0.2, b_lat 0.8, μ 0.1 (SI)


def test_same_direction_hand_worked():
    # Rear 20 m/s: 20·1 + 3.5/2 = 21.75 m during ρ, then 23.5²/(2·4) = 69.03125 m; front 10 m/s: 10²/16 = 6.25 m.
    assert lon_safe_distance_same_dir(20.0, 10.0, AD_RSS, AD_RSS) == pytest.approx(84.53125, abs=TOL)
    # A front car that is much faster needs no gap: max(0, ·) keeps d_min at λ = 0.
    assert lon_safe_distance_same_dir(5.0, 40.0, AD_RSS, AD_RSS) == 0.0
    # λ of the rear car is added: the mobileye_human preset has λ = 1 m.
    with_gap = RssParams(min_lon_gap=1.0)
    assert lon_safe_distance_same_dir(20.0, 10.0, with_gap, AD_RSS) == pytest.approx(85.53125, abs=TOL)


def test_speed_cap_limits_the_acceleration_during_the_response_time():
    capped = RssParams(max_speed_on_accel=21.0)
    # 20 → 21 m/s in 1/3.5 s, then cruising: 20·t₁ + 1.75·t₁² + 21·(1 − t₁) with t₁ = 0.285714 s.
    t1 = 1.0 / 3.5
    expected_rho = 20.0 * t1 + 0.5 * 3.5 * t1**2 + 21.0 * (1.0 - t1)
    assert distance_during_response(20.0, 3.5, 1.0, 21.0) == pytest.approx(expected_rho, abs=TOL)
    assert lon_safe_distance_same_dir(20.0, 0.0, capped, capped) == pytest.approx(expected_rho + 21.0**2 / 8.0)
    # Already above the cap: no acceleration, the speed is kept.
    assert speed_after_response(30.0, 3.5, 1.0, 21.0) == 30.0


def test_opposite_direction_hand_worked():
    # Correct-lane car 10 m/s: 10 + 1.75 + 13.5²/(2·3) = 42.125 m; other car 15 m/s: 15 + 1.75 + 18.5²/8 = 59.53125 m.
    assert lon_safe_distance_opposite(10.0, 15.0, AD_RSS, AD_RSS) == pytest.approx(101.65625, abs=TOL)
    # Both in their correct lanes: both brake at b_corr = 3: 42.125 + 16.75 + 18.5²/6.
    both = lon_safe_distance_opposite(10.0, 15.0, AD_RSS, AD_RSS, both_correct=True)
    assert both == pytest.approx(42.125 + 16.75 + 18.5**2 / 6.0, abs=TOL)


def test_lateral_hand_worked():
    # At rest laterally: each car 0.1 m during ρ + 0.2²/1.6 = 0.025 m, plus μ = 0.1: 0.35 m.
    assert lat_safe_distance(0.0, 0.0, AD_RSS, AD_RSS) == pytest.approx(0.35, abs=TOL)
    # Left car drifting right (towards) at 0.5 m/s: u = 0.5 → 0.6 m during ρ... (0.5+0.7)/2 = 0.6, 0.7²/1.6 = 0.30625.
    assert lat_safe_distance(-0.5, 0.0, AD_RSS, AD_RSS) == pytest.approx(0.6 + 0.30625 + 0.125 + 0.1, abs=TOL)
    # Moving apart fast: negative reach, clipped at 0.
    assert lat_safe_distance(2.0, -2.0, AD_RSS, AD_RSS) == 0.0


def test_safe_comparison_uses_one_millimetre():
    assert not is_safe_distance(10.0005, 10.0)
    assert is_safe_distance(10.0011, 10.0)


@pytest.mark.parametrize("params", [AD_RSS, RssParams(max_speed_on_accel=12.0), RssParams(lon_accel_max=0.0),
                                    RssParams(response_time=0.2, min_lon_gap=1.0)])
def test_max_safe_speed_is_the_root_of_the_safe_distance(params):
    gaps = np.linspace(0.0, 300.0, 301)
    v = max_safe_speed_behind(gaps, 12.0, params, AD_RSS)
    ok = np.isfinite(v)
    # At the returned speed the gap is exactly the safe distance (the root), and a bit faster is unsafe.
    np.testing.assert_allclose(lon_safe_distance_same_dir(v[ok], 12.0, params, AD_RSS), gaps[ok], atol=1e-7)
    assert np.all(lon_safe_distance_same_dir(v[ok] + 0.01, 12.0, params, AD_RSS) > gaps[ok])
    # Where no speed is safe, even standing still violates the gap.
    assert np.all(lon_safe_distance_same_dir(0.0, 12.0, params, AD_RSS) > gaps[~ok])


def test_min_safe_speed_ahead_and_interval():
    gap = 30.0
    v = min_safe_speed_ahead(gap, 25.0, AD_RSS, AD_RSS)
    assert lon_safe_distance_same_dir(25.0, v, AD_RSS, AD_RSS) == pytest.approx(gap)
    low, high = safe_speed_interval_same_dir(np.inf, 0.0, AD_RSS, gap, 25.0, AD_RSS, AD_RSS)
    assert high == np.inf and low == pytest.approx(v)


def test_no_speed_ahead_is_safe_within_the_rear_cars_min_gap():
    # d_min = max(0, D_rear − v²/(2·b_max)) + λ_rear: however fast the front car goes, a gap below λ_rear (1 m,
    # the mobileye_human preset's) stays unsafe, so there is no smallest safe speed (+inf, an empty interval).
    rear = RssParams(min_lon_gap=1.0)
    assert min_safe_speed_ahead(0.5, 10.0, AD_RSS, rear) == np.inf
    low, high = safe_speed_interval_same_dir(np.inf, 0.0, AD_RSS, 0.5, 10.0, rear, AD_RSS)
    assert low == np.inf and high == np.inf
    # Just above λ_rear the root is finite again, and a little faster than it is safe.
    v = min_safe_speed_ahead(1.5, 10.0, AD_RSS, rear)
    assert np.isfinite(v) and lon_safe_distance_same_dir(10.0, v + 0.01, rear, AD_RSS) < 1.5


def test_arrays_of_parameters_broadcast_like_scalars():
    params = [RssParams(), RssParams(response_time=2.0), RssParams(lon_brake_max=6.0)]
    table = RssParamArrays.stack(params)
    v_rear, v_front = np.array([20.0, 25.0, 30.0]), np.array([10.0, 5.0, 0.0])
    vector = lon_safe_distance_same_dir(v_rear, v_front, table, table)
    scalar = [lon_safe_distance_same_dir(r, f, p, p) for r, f, p in zip(v_rear, v_front, params)]
    np.testing.assert_allclose(vector, scalar, rtol=0, atol=0)
    assert table.take(np.array([2, 0])).lon_brake_max.tolist() == [6.0, 8.0]


speeds = st.floats(0.0, 60.0)


@settings(max_examples=300, deadline=None)
@given(v_rear=speeds, v_front=speeds, dv=st.floats(0.01, 10.0))
def test_dmin_grows_with_rear_speed_and_shrinks_with_front_speed(v_rear, v_front, dv):
    d = lon_safe_distance_same_dir(v_rear, v_front, AD_RSS, AD_RSS)
    assert lon_safe_distance_same_dir(v_rear + dv, v_front, AD_RSS, AD_RSS) >= d
    assert lon_safe_distance_same_dir(v_rear, v_front + dv, AD_RSS, AD_RSS) <= d
    if d > 0:  # strictly, while the max(0, ·) is not active
        assert lon_safe_distance_same_dir(v_rear + dv, v_front, AD_RSS, AD_RSS) > d


@settings(max_examples=300, deadline=None)
@given(v_left=st.floats(-3.0, 3.0), v_right=st.floats(-3.0, 3.0))
def test_lateral_is_symmetric_under_mirroring(v_left, v_right):
    # Mirror the road: the right car becomes the left one and every lateral speed changes sign.
    a = lat_safe_distance(v_left, v_right, AD_RSS, AD_RSS)
    b = lat_safe_distance(-v_right, -v_left, AD_RSS, AD_RSS)
    assert a == pytest.approx(b, abs=1e-12)


def test_worst_case_stopping_distance_matches_a_slow_reference():
    # Integrate the worst case with a tiny time step (a second, independent implementation).
    def reference(v, p, brake, dt=1e-5):
        x, t = 0.0, 0.0
        while t < p.response_time - 1e-12:
            a = p.lon_accel_max if v < p.max_speed_on_accel else 0.0
            v_next = min(v + a * dt, max(v, p.max_speed_on_accel))
            x += 0.5 * (v + v_next) * dt
            v, t = v_next, t + dt
        return x + v * v / (2 * brake)

    for v in (0.0, 7.0, 19.9, 35.0):
        p = RssParams(max_speed_on_accel=20.0)
        assert worst_case_stopping_distance(v, 3.5, 1.0, 20.0, 4.0) == pytest.approx(reference(v, p, 4.0), abs=1e-3)
