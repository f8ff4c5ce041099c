"""The motion layer's choices on the highway net's straight hw0 (d = 0: the middle lane's centre): SSC when the
corridor exists, the low-speed primitive at walking pace, the previous trajectory for a short while when the
corridor fails, then the behaviour layer's emergency backup; and the executed heading of a plan that creeps
sideways."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.controllers import VehicleLimits
from sumo_rss.planner.lanes import lane_chains
from sumo_rss.planner.motion.frenet_plan import MAX_CURVATURE, FrenetPlan, from_samples
from sumo_rss.planner.motion.ssc import MotionInput, MotionLayer, MotionSettings
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork

TIMES = np.round(np.arange(26) * 0.2, 10)  # [s]
LENGTH, WIDTH = 4.5, 1.8  # [m]


@pytest.fixture(scope="module")
def frame():
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    return RoadFrame.build(lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1"])))


def _input(frame, now, s0, v, parked_at=None):
    """The ego at s0 keeping its lane at v; one agent, parked at ``parked_at`` (else far behind)."""
    s = s0 + v * TIMES
    zeros = np.zeros(TIMES.size)
    ego = (s, zeros, zeros, np.full(TIMES.size, v), zeros)
    at = -1e3 if parked_at is None else parked_at
    agents = (np.full((TIMES.size, 1), at), np.zeros((TIMES.size, 1)), np.zeros((TIMES.size, 1)),
              np.array([LENGTH]), np.array([WIDTH]))
    return MotionInput(frame, now, TIMES, ego, LENGTH, WIDTH, agents, np.inf)


def _backup(frame, inp):
    t = np.round(np.arange(0.0, 5.0 + 1e-9, 0.1), 10)
    s = np.interp(t, TIMES, inp.ego[0])
    plan = from_samples(frame, inp.now + t, s, np.zeros(t.size), np.zeros(t.size), np.full(t.size, inp.ego[3][0]))
    return plan, plan.to_world(0.5 * LENGTH, 0.0)


def test_ssc_then_previous_then_backup(frame):
    layer = MotionLayer(MotionSettings(), 0.1)
    first = _input(frame, 10.0, 100.0, 15.0)
    plan, trajectory = layer.plan(first, lambda: _backup(frame, first))
    assert layer.stats.outcomes["ssc"] == 1
    # It starts where the ego is (front bumper 2.25 m ahead of its centre) at its speed.
    x, y, _ = frame.bumper_at(100.0, 0.0, 0.0, 0.5 * LENGTH)
    state = trajectory.state_at(10.0)
    assert (state.x, state.y, state.speed) == pytest.approx((float(x), float(y), 15.0), abs=1e-6)
    assert np.allclose(plan.s_dot, 15.0, atol=1e-3) and np.allclose(plan.d, 0.0, atol=1e-6)

    blocked = _input(frame, 10.1, 101.5, 15.0, parked_at=120.0)  # its seeds run through a parked car
    _, kept = layer.plan(blocked, lambda: _backup(frame, blocked))
    assert kept is trajectory and layer.stats.outcomes["previous"] == 1
    assert layer.stats.failures == {"corridor_blocked": 1}

    late = _input(frame, 11.5, 122.5, 15.0, parked_at=140.0)  # still failing 1.5 s after the last plan
    backup = _backup(frame, late)
    _, executed = layer.plan(late, lambda: backup)
    assert executed is backup[1] and layer.stats.outcomes["backup"] == 1


def test_walking_pace_uses_the_primitive(frame):
    layer = MotionLayer(MotionSettings(), 0.1)
    slow = _input(frame, 0.0, 100.0, 1.0)
    plan, _ = layer.plan(slow, lambda: _backup(frame, slow))
    assert layer.stats.outcomes["primitive"] == 1
    assert plan.s[-1] == pytest.approx(105.0) and np.all(np.diff(plan.s) >= 0.0)


@pytest.mark.parametrize("accel, starts_at, clipped", [(1.5, 1.5, 0), (-6.5, -5.0, 1)])
def test_the_plan_starts_at_the_measured_acceleration_within_the_dynamic_bounds(frame, accel, starts_at, clipped):
    """The QP's start acceleration is the ego's (s̈ bounds [−5, 3] m/s²); beyond them it starts at the bound,
    and the cycle is counted in ``start_clipped``."""
    layer = MotionLayer(MotionSettings(), 0.1)
    inp = _input(frame, 10.0, 100.0, 15.0)
    measured = np.zeros(TIMES.size)
    measured[0] = accel
    inp = replace(inp, ego=(*inp.ego[:4], measured))
    plan, _ = layer.plan(inp, lambda: _backup(frame, inp))
    assert layer.stats.outcomes["ssc"] == 1
    assert plan.s_ddot[0] == pytest.approx(starts_at, abs=1e-6)
    assert layer.stats.start_clipped == clipped


def test_creeping_sideways_does_not_turn_the_ego_on_the_spot(frame):
    """A plan that moves the ego 0.6 m across at walking pace while it gains 0.1 m along the lane: its velocity
    points 80° off the lane, but a car cannot turn on the spot; the heading turns by at most MAX_CURVATURE per metre
    of path (highway_exit seed 8 stood turned by 1.1 rad across a lane's edge). At speed the heading is the
    velocity's direction, as before."""
    t = 10.0 + np.round(np.arange(21) * 0.1, 10)
    u = t - t[0]
    s, d = 100.0 + 0.05 * u, -0.3 * u  # [m] 0.05 m/s along, 0.3 m/s to the right
    creep = FrenetPlan(frame, t, s, d, np.full(t.size, 0.05), np.full(t.size, -0.3), np.zeros(t.size),
                       np.zeros(t.size))
    heading = creep.to_world(0.5 * LENGTH, 0.0).heading - frame.to_world(s, d, np.zeros(t.size))[2]
    path = np.hypot(0.05, 0.3) * u
    tightest = np.tan(VehicleLimits().max_steer) / VehicleLimits().wheelbase  # [1/m] the bicycle model's
    assert MAX_CURVATURE == pytest.approx(tightest) and 0.3 < tightest < 0.4
    assert np.all(np.abs(heading) <= tightest * path + 1e-9)
    assert heading[-1] == pytest.approx(-tightest * path[-1])  # turning as fast as it may, towards its way
    change = FrenetPlan(frame, t, 100.0 + 20.0 * u, -0.5 * u, np.full(t.size, 20.0), np.full(t.size, -0.5),
                        np.zeros(t.size), np.zeros(t.size))
    heading = change.to_world(0.5 * LENGTH, np.arctan2(-0.5, 20.0)).heading - \
        frame.to_world(change.s, change.d, np.zeros(t.size))[2]
    assert np.allclose(heading, np.arctan2(-0.5, 20.0), atol=1e-9)
