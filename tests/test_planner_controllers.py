"""EUDM controllers against hand-computed values (epsilon.md §3; ego IDM s0 2 m, T 1 s, a 1, b 1.67 m/s²)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from sumo_rss.planner.behavior.controllers import (BicycleState, IdmParams, VehicleLimits, acc_acceleration,
                                                   bicycle_step, idm_speed_command, lookahead, pure_pursuit_steer)

EGO = IdmParams()
FAR = 1e4  # [m] a gap that does not matter


def test_free_road_acceleration():
    # a·(1 − (v/v0)^δ) = 1·(1 − 0.5^4) = 0.9375 at 10 of 20 m/s.
    assert acc_acceleration(10.0, 20.0, 10.0, FAR, EGO) == pytest.approx(0.9375, abs=1e-6)
    # Above the desired speed: IIDM −b·(1 − (v0/v)^(a·δ/b)) = −1.67·(1 − 0.8^(4/1.67)) = −0.691419; it is below
    # the heuristic's −b·v²/(v_l² + 2·b·s) = −1.67·625/(625 + 33400) = −0.030676, so the ACC blend applies:
    # 0.01·a_iidm + 0.99·(a_cah + b·tanh((a_iidm − a_cah)/b)) = −0.659296.
    a_iidm, a_cah = -1.67 * (1 - 0.8 ** (4 / 1.67)), -1.67 * 625 / (625 + 2 * 1.67 * FAR)
    blended = 0.01 * a_iidm + 0.99 * (a_cah + 1.67 * math.tanh((a_iidm - a_cah) / 1.67))
    assert acc_acceleration(25.0, 20.0, 25.0, FAR, EGO) == pytest.approx(blended, abs=1e-12)
    assert blended == pytest.approx(-0.659296, abs=1e-6)
    # Desired speed 0 means stop: the IIDM term is −b = −1.67, then blended with the heuristic as above.
    a_iidm, a_cah = -1.67, -1.67 * 25 / (25 + 2 * 1.67 * FAR)
    stop = 0.01 * a_iidm + 0.99 * (a_cah + 1.67 * math.tanh((a_iidm - a_cah) / 1.67))
    assert acc_acceleration(5.0, 0.0, 5.0, FAR, EGO) == pytest.approx(stop, abs=1e-12)
    assert idm_speed_command(0.0, 0.0, 0.0, FAR, EGO, 0.2) == 0.0


def test_free_road_term_with_an_approach_time_reaches_the_desired_speed_at_the_acceleration_limit():
    """min(a, (v0 − v)/τ) below v0 (a 2 m/s², τ 1 s), where IDM's a·(1 − (v/v0)^δ) fades out near v0."""
    ego = IdmParams(accel=2.0, approach_time=1.0)
    # 10 of 20 m/s: the limit, 2.0 (IDM: 1.875); 32.7 of 33 m/s: 0.3 (IDM: 2·(1 − (32.7/33)^4) = 0.0717).
    assert acc_acceleration(10.0, 20.0, 10.0, FAR, ego) == pytest.approx(2.0, abs=1e-5)
    assert acc_acceleration(32.7, 33.0, 32.7, FAR, ego) == pytest.approx(0.3, abs=1e-6)
    assert acc_acceleration(32.7, 33.0, 32.7, FAR, IdmParams(accel=2.0)) == pytest.approx(0.0717, abs=1e-4)
    # Above v0 and behind a close leader it is the IIDM as before.
    assert acc_acceleration(25.0, 20.0, 25.0, FAR, replace(ego, accel=1.0)) == \
        pytest.approx(acc_acceleration(25.0, 20.0, 25.0, FAR, EGO), abs=1e-12)
    assert acc_acceleration(20.0, 30.0, 15.0, 20.0, ego) == \
        pytest.approx(acc_acceleration(20.0, 30.0, 15.0, 20.0, IdmParams(accel=2.0)), abs=1e-12)
    # From 22 to 28 m/s in steps of 0.1 s: within 0.1 m/s of 28 after 2 s at 2 m/s² + τ·ln(2/0.1) = 5.0 s (4.9 in
    # steps; IDM: 15.4 s).
    for params, expected in ((ego, 4.9), (IdmParams(accel=2.0), 15.4)):
        v, t = 22.0, 0.0
        while v < 27.9:
            v, t = float(idm_speed_command(v, 28.0, v, FAR, params, 0.1)), t + 0.1
        assert t == pytest.approx(expected, abs=0.05)


def test_close_follower_blends_iidm_with_the_constant_acceleration_heuristic():
    # v = v_l = 20 m/s, net gap 10 m: s* = 2 + 20·1 = 22 m, z = 2.2, IIDM a·(1 − z²) = −3.84.
    # CAH with the leader braking at b: −b·v²/(v_l² + 2·b·s) = −1.67·400/(400 + 33.4) = −1.541301.
    # ACC: 0.01·(−3.84) + 0.99·(−1.541301 + 1.67·tanh((−3.84 + 1.541301)/1.67)).
    a_iidm, a_cah = -3.84, -1.67 * 400 / (400 + 2 * 1.67 * 10)
    expected = 0.01 * a_iidm + 0.99 * (a_cah + 1.67 * math.tanh((a_iidm - a_cah) / 1.67))
    assert acc_acceleration(20.0, 30.0, 20.0, 10.0, EGO) == pytest.approx(expected, abs=1e-9)
    assert expected == pytest.approx(-3.0199, abs=1e-3)


def test_braking_never_goes_below_standstill():
    v = idm_speed_command(0.3, 20.0, 0.0, 0.5, EGO, dt=0.2)
    assert v == 0.0  # hard braking would give 0.3 − 5·0.2 < 0; the floor is −min(b_hard, v/dt)


def test_follower_behind_a_stopped_car_stops_without_collision():
    v, gap, dt = 20.0, 80.0, 0.2
    for _ in range(300):
        v_next = float(idm_speed_command(v, 20.0, 0.0, gap, EGO, dt))
        gap -= 0.5 * (v + v_next) * dt
        v = v_next
        assert gap > 0.0
    assert v == 0.0 and 0.5 < gap < EGO.s0 + 1.0


def test_pure_pursuit_hand_worked():
    # Target 10 m ahead, 2 m left: α = atan2(2, 10) = 0.197396; δ = atan2(2·2.8·sin α, √104) = 0.107279.
    delta = pure_pursuit_steer(0.0, 0.0, 0.0, 10.0, 2.0, 2.8)
    assert delta == pytest.approx(math.atan2(2 * 2.8 * math.sin(math.atan2(2, 10)), math.hypot(10, 2)), abs=1e-12)
    assert delta == pytest.approx(0.107279, abs=1e-6)
    assert lookahead(np.array([0.5, 10.0, 100.0]), 2.5, 3.0, 100.0).tolist() == [3.0, 25.0, 100.0]


def _state(n=1, v=10.0):
    z = np.zeros(n)
    return BicycleState(z.copy(), z.copy(), z.copy(), np.full(n, v), z.copy(), z.copy())


def test_bicycle_keeps_a_straight_line_at_constant_speed():
    s = bicycle_step(_state(v=10.0), 10.0, 0.0, VehicleLimits(), 0.2)
    assert s.x[0] == pytest.approx(2.0) and s.y[0] == 0.0 and s.speed[0] == 10.0 and s.heading[0] == 0.0


def test_bicycle_respects_jerk_acceleration_and_steer_rate_limits():
    limits = VehicleLimits()
    s = bicycle_step(_state(v=10.0), 30.0, 0.5, limits, 0.2)
    # From a = 0, the jerk limit 3 m/s³ allows a = 0.6 m/s² after 0.2 s (below a_max = 1).
    assert s.accel[0] == pytest.approx(0.6) and s.speed[0] == pytest.approx(10.12)
    # The steer rate limit 0.39 rad/s allows 0.078 rad after 0.2 s, but the lateral jerk limit 1.8 m/s³ caps the
    # lateral acceleration at 0.36 m/s²: δ = atan(0.36·L / 10.12²), L = 2.85 m (epsilon.md's default vehicle).
    assert limits.wheelbase == 2.85
    assert math.atan(s.curvature[0] * 2.85) == pytest.approx(math.atan(0.36 * 2.85 / 10.12 ** 2), abs=1e-9)
    braking = bicycle_step(_state(v=10.0), 0.0, 0.0, limits, 0.2)
    assert braking.accel[0] == pytest.approx(-1.0)  # brake jerk 5 m/s³ · 0.2 s


def test_bicycle_turns_with_the_expected_radius():
    # Steady turn at 5 m/s, curvature 0.02 1/m (lateral acceleration 0.5 m/s²): heading change v·κ·t.
    s = _state(v=5.0)
    s = BicycleState(s.x, s.y, s.heading, s.speed, s.accel, np.full(1, 0.02))
    steer = math.atan(0.02 * VehicleLimits().wheelbase)
    for _ in range(10):
        s = bicycle_step(s, 5.0, steer, VehicleLimits(), 0.1)
    assert s.heading[0] == pytest.approx(5.0 * 0.02 * 1.0, abs=1e-9)
    assert math.hypot(s.x[0], s.y[0] - 50.0) == pytest.approx(50.0, abs=1e-6)  # on the circle of radius 50 m


def test_a_headway_distance_floor_raises_the_desired_gap():
    # v = v_l = 25 m/s, net gap 50 m. With T = 1 s: s* = 2 + 25 = 27 m < 50 m, free-road regime below v0 = 30:
    # a·(1 − (25/30)^4)·(1 − z^(2a/a_free)) with z = 0.54. A floor of 89.19 m (the ad_rss safe distance at these
    # speeds) on v·T gives s* = 91.19 m, z = 1.8238, IIDM a·(1 − z²) = −2.3263, blended with the heuristic
    # −b·v²/(v_l² + 2·b·s) = −1.67·625/(625 + 167) = −1.317866 into −2.2203 m/s².
    assert acc_acceleration(25.0, 30.0, 25.0, 50.0, EGO) > 0.0
    assert acc_acceleration(25.0, 30.0, 25.0, 50.0, EGO, min_distance=20.0) == acc_acceleration(25.0, 30.0, 25.0,
                                                                                                50.0, EGO)
    z = (2.0 + 89.19) / 50.0
    a_iidm, a_cah = 1.0 - z * z, -1.67 * 625 / (625 + 2 * 1.67 * 50)
    expected = 0.01 * a_iidm + 0.99 * (a_cah + 1.67 * math.tanh((a_iidm - a_cah) / 1.67))
    assert acc_acceleration(25.0, 30.0, 25.0, 50.0, EGO, min_distance=89.19) == pytest.approx(expected, abs=1e-12)
    assert expected == pytest.approx(-2.2203, abs=1e-3)
