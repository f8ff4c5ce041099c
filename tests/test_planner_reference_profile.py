"""The ego's desired speed along its rollout's own path (docs/planner.md, "The desired speed along the rollout's
path"): the reference profile through the compiled kernel, on intersection_tls's left turn (S_in_1 at 13.89 m/s
into the junction lanes :C_8_0 / :C_14_0 at 9.26 m/s from s = 289.6 m) and on hw0's constant 33.33 m/s."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.forward_sim import ReferenceProfile, Rollouts, Vehicles, simulate
from sumo_rss.planner.epsilon import EGO_SIM, REFERENCE_PREVIEW, _reference_speed
from sumo_rss.planner.lanes import CURRENT, lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.params import RssParamArrays, RssParams

JUNCTION_START, JUNCTION_END, JUNCTION_LIMIT = 289.6, 308.95, 9.26  # [m], [m], [m/s] along S_in_1's chain
HORIZON = 5.0  # [s] five 1 s layers


def _frame(net_name: str, lane: str, edges: list[str]) -> RoadFrame:
    net = RoadNetwork.from_file(NETWORKS / net_name / f"{net_name}.net.xml")
    return RoadFrame.build(lane_chains(net, int(net.lane_indices([lane])[0]), net.edge_indices(edges)))


def _ego(s: float, v: float) -> Vehicles:
    one = np.ones(1)
    return Vehicles(np.array([s]), 0.0 * one, 0.0 * one, np.array([v]), 0.0 * one, 0.0 * one, 4.5 * one, 1.8 * one,
                    np.array([CURRENT]))


def _maintain(v0: float, reference: ReferenceProfile | None) -> Rollouts:
    """One lane-keeping rollout of the lone ego at desired speed ``v0`` [m/s]."""
    return Rollouts(np.full((1, 5), CURRENT), np.array([v0]), np.ones(1), np.zeros(1, dtype=bool), 4.2,
                    np.full((1, 1), CURRENT), np.zeros(1), np.inf, reference)


def _profile(frame: RoadFrame, vehicles: Vehicles, desired: float) -> ReferenceProfile:
    """The planner's profile for the lone ego (as ``EpsilonPlanner._rollouts`` builds it)."""
    reach = max(float(vehicles.speed[0]), desired) * (HORIZON + REFERENCE_PREVIEW)
    return ReferenceProfile.along(frame.chains, float(vehicles.s[0]) + 2.25, reach, desired, REFERENCE_PREVIEW)


def _run(frame: RoadFrame, vehicles: Vehicles, rollouts: Rollouts):
    return simulate(frame, vehicles, rollouts, (1.0,) * 5, EGO_SIM, RssParams(), RssParamArrays.stack([RssParams()]))


def test_the_profile_is_the_reference_speed_at_every_point():
    frame = _frame("intersection_tls", "S_in_1", ["S_in", "W_out"])
    s = np.arange(-50.0, 400.0, 0.7)
    profile = frame.chains.reference_profile(CURRENT, s, 13.89)
    assert np.array_equal(profile, [frame.chains.reference_speed(CURRENT, x, 13.89) for x in s])
    # Without the bends only the limits count: the junction lane's 9.26 m/s at the turn's apex (5.20 with them).
    limits = frame.chains.reference_profile(CURRENT, np.array([270.0, 300.0]), 13.89, bends=False)
    np.testing.assert_allclose(limits, [np.sqrt(9.26 ** 2 + 2 * 1.67 * 19.6), 9.26], atol=0.01)


def test_the_ego_keeps_a_lower_limit_ahead_where_one_desired_speed_for_the_horizon_did_not():
    """The ego's front bumper 47 m before the junction lanes at 13.89 m/s: the reference speed there is 12.8 m/s
    (the turn's first bend ahead), and a rollout that holds it for the horizon enters the 9.26 m/s lane far above
    it. Along the profile its speed is at most the limit (+ 0.05 m/s) wherever its front bumper is on the slow
    lanes."""
    frame = _frame("intersection_tls", "S_in_1", ["S_in", "W_out"])
    vehicles = _ego(240.0, 13.89)
    v_ref = _reference_speed(frame, vehicles, 13.89, 13.89)
    assert v_ref == pytest.approx(12.8, abs=0.1)
    reference = _profile(frame, vehicles, 13.89)
    for profile, limit in ((reference, JUNCTION_LIMIT + 0.05), (None, None)):
        sim = _run(frame, vehicles, _maintain(v_ref, profile))
        front = sim.s[0, :, 0] + 2.25
        on_slow = (front >= JUNCTION_START) & (front < JUNCTION_END)
        assert on_slow.sum() >= 3  # the horizon reaches the junction lanes
        fastest = float(sim.speed[0, on_slow, 0].max())
        if limit is not None:
            assert fastest <= limit
        else:
            assert fastest > JUNCTION_LIMIT + 2.0  # the single desired speed: its IDM lags the limit


def test_a_constant_limit_road_drives_as_without_the_profile():
    """On hw0 (33.33 m/s, no bend below it) the profile is the desired speed everywhere: the same rollouts."""
    frame = _frame("highway", "hw0_1", ["hw0", "hw1", "hw2"])
    vehicles = _ego(100.0, 25.0)
    reference = _profile(frame, vehicles, 30.0)
    assert np.all(reference.speed == 30.0) and np.all(reference.limit == 30.0)
    with_profile, without = (_run(frame, vehicles, _maintain(28.0, r)) for r in (reference, None))
    for name in ("s", "d", "heading", "speed", "ego_accel"):
        assert np.array_equal(getattr(with_profile, name), getattr(without, name)), name


def test_a_bad_profile_is_refused():
    with pytest.raises(ValueError, match="finite"):
        ReferenceProfile(0.0, 1.0, np.full((3, 4), np.inf), np.ones((3, 4)), 1.0)
    with pytest.raises(ValueError, match="positive step"):
        ReferenceProfile(0.0, 0.0, np.ones((3, 4)), np.ones((3, 4)), 1.0)
