"""The planner's lane-change navigation on the shipped nets: when the route (or a lane's end) makes a change
mandatory and to which side, and which changes an owed lateral response rules out."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.dcp_tree import Action, Lat, Lon, valid_policies
from sumo_rss.planner.behavior.forward_sim import SimResult, Vehicles
from sumo_rss.planner.behavior.manager import LaneChangeContext
from sumo_rss.planner.epsilon import EpsilonPlanner
from sumo_rss.planner.lanes import CURRENT, LEFT, RIGHT, lane_chains
from sumo_rss.planner.navigation import SEEK_SLOWER, change_held, change_stuck, held_sides, mandatory_change, \
    seek_speed
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.owed_responses import OwedResponses


@pytest.fixture(scope="module")
def exit_net() -> RoadNetwork:
    return RoadNetwork.from_file(NETWORKS / "highway_exit" / "highway_exit.net.xml")


def _frame(net: RoadNetwork, lane: str, route: list[str]) -> RoadFrame:
    return RoadFrame.build(lane_chains(net, int(net.lane_indices([lane])[0]), net.edge_indices(route)))


def test_an_exit_three_lanes_away_is_due_three_reaches_before_the_lane_leaves_the_route(exit_net):
    """From ex_in_2 the lane leaves the route 1330.34 m from its start (test_planner_lanes); 3 changes at 25 m/s are
    due within 3·max(200 m, 10 s·25 m/s) = 750 m of that: not at 550 m along the lane (780 m left), at 600 m."""
    net = exit_net
    frame = _frame(net, "ex_in_2", ["ex_in", "ex_decel", "ex_ramp"])
    assert mandatory_change(frame, 550.0, 25.0) is None
    assert mandatory_change(frame, 600.0, 25.0) is Lat.RIGHT
    # At 33 m/s each change needs 330 m: due 990 m before the end, at 400 m along the lane (930 m left).
    assert mandatory_change(frame, 300.0, 33.0) is None and mandatory_change(frame, 400.0, 33.0) is Lat.RIGHT


def test_a_change_that_can_only_be_made_on_the_next_edge_is_not_due_yet(exit_net):
    """On ex_in_0 the last change is into the deceleration lane, which starts on ex_decel: on ex_in there is no
    lane to the right, and a left change would be wrong; on ex_decel_1 it is due (226 m before its end)."""
    net = exit_net
    assert mandatory_change(_frame(net, "ex_in_0", ["ex_in", "ex_decel", "ex_ramp"]), 1200.0, 25.0) is None
    assert mandatory_change(_frame(net, "ex_decel_1", ["ex_decel", "ex_ramp"]), 20.0, 25.0) is Lat.RIGHT
    # Staying on the motorway, the same lane needs no change.
    assert mandatory_change(_frame(net, "ex_decel_1", ["ex_decel", "ex_main"]), 200.0, 25.0) is None


def test_the_acceleration_lane_end_makes_the_change_to_the_motorway_due():
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    frame = _frame(net, "mw_merge_0", ["mw_merge", "mw_out"])
    assert mandatory_change(frame, 60.0, 20.0) is None  # 210 m before the end (270.31 m), more than 200 m
    assert mandatory_change(frame, 80.0, 20.0) is Lat.LEFT


def _owed(lateral: list[bool], left: list[bool]) -> OwedResponses:
    n = len(lateral)
    no = np.zeros(n, dtype=bool)
    return OwedResponses(t_b=np.zeros(n), must_brake=no, brake_correct=no, front_limited=no,
                         owed_lat=np.array(lateral), other_is_left=np.array(left), u0=np.zeros(n),
                         other_id=np.array([f"c{i}" for i in range(n)]), same_direction=~no, lat_settled=no)


def test_a_lateral_response_owed_rules_out_starting_a_change_towards_that_side(highway):
    net, _ = highway
    planner = EpsilonPlanner(net, ParamResolver())
    assert held_sides(None) == frozenset() and held_sides(_owed([False], [True])) == frozenset()
    held = held_sides(_owed([True, False, True], [True, False, True]))
    assert held == frozenset({Lat.LEFT})
    lane = int(net.lane_indices(["hw0_1"])[0])
    frame = _frame(net, "hw0_1", ["hw0", "hw1", "hw2"])
    free = planner._policies(40.0, frame, lane)
    kept = planner._policies(40.0, frame, lane, held)
    assert len(free) == 27 and len(kept) == 15  # 3 x (1 keep + 4 right changes): no left change starts
    assert not [p for p in kept if Lat.LEFT in p.lats] and [p for p in kept if Lat.RIGHT in p.lats]


def _rollouts_moving(moves: list[float]) -> SimResult:
    """Simulation results of len(moves) rollouts whose ego ends ``moves`` [m] left of where it starts (3 samples)."""
    r = len(moves)
    d = np.zeros((r, 3, 2))
    d[:, -1, 0] = moves
    zero, t = np.zeros((r, 3, 2)), np.array([0.0, 2.5, 5.0])
    ego = np.zeros((r, 3))
    return SimResult(t, np.array([2]), zero, d, zero, zero, ego, ego, np.ones(r, bool), ego, ego, ego,
                     np.ones((r, 3), bool), np.zeros(r, int), np.zeros((r, 3, 2), int))


def test_a_due_discretionary_change_that_no_rollout_gets_going_is_called_off():
    """The context's changes all held by the virtual barrier (the ego moves < 0.5 m towards the left lane within
    the horizon): call it off; one rollout that gets 0.6 m across keeps it. A mandatory change keeps waiting, and a
    change already under way (the ego 0.5 m off its lane's centre) goes on."""
    policies = valid_policies(Action(Lon.MAINTAIN, Lat.LEFT, 1.0))
    policy_of = np.arange(len(policies))
    due = LaneChangeContext(Lat.LEFT, 30.0, 32.0, frozenset({1}))
    held = _rollouts_moving([0.1] * len(policies))
    assert change_stuck(due, 33.0, policies, policy_of, held, 0.0)
    assert not change_stuck(due, 31.0, policies, policy_of, held, 0.0)  # before its operation time
    assert not change_stuck(due, 33.0, policies, policy_of, held, 0.5)
    assert not change_stuck(replace(due, mandatory=True), 33.0, policies, policy_of, held, 0.0)
    going = [0.6 if p.lateral is Lat.LEFT else 0.1 for p in policies]
    assert not change_stuck(due, 33.0, policies, policy_of, _rollouts_moving(going), 0.0)


def test_a_held_mandatory_change_is_held_and_a_change_under_way_is_not():
    """change_held is the test a mandatory change seeks its gap by: every rollout of its direction < 0.5 m across."""
    policies = valid_policies(Action(Lon.MAINTAIN, Lat.KEEP, 1.0))
    policy_of = np.arange(len(policies))
    right = [-0.1 if p.lateral is Lat.RIGHT else 0.0 for p in policies]
    assert change_held(Lat.RIGHT, policies, policy_of, _rollouts_moving(right), 0.0)
    going = [-0.6 if p.lateral is Lat.RIGHT else 0.0 for p in policies]
    assert not change_held(Lat.RIGHT, policies, policy_of, _rollouts_moving(going), 0.0)
    assert not change_held(Lat.RIGHT, policies, policy_of, _rollouts_moving(right), -0.4)  # under way
    # 0.6 m to the left is no progress to the right.
    left = [0.6 if p.lateral is Lat.LEFT else 0.0 for p in policies]
    assert change_held(Lat.RIGHT, policies, policy_of, _rollouts_moving(left), 0.0)


def _around(s, speed, chain) -> Vehicles:
    n = len(s)
    return Vehicles(np.array(s, float), np.zeros(n), np.zeros(n), np.array(speed, float), np.zeros(n), np.zeros(n),
                    np.full(n, 4.5), np.full(n, 1.8), np.array(chain))


def test_a_mandatory_change_seeks_its_gap_slower_than_the_nearest_cars_of_the_target_lane():
    """The ego at 30 m/s at s = 500; right lane: a 31 m/s car 35 m behind (nearest behind), a 24 m/s car 80 m
    behind (not the nearest), a 29 m/s car 60 m ahead; a 20 m/s car ahead in the ego's own lane and a 10 m/s car in
    the left lane do not count: SEEK_SLOWER below min(31, 29) = 29 m/s."""
    cars = _around([500.0, 465.0, 420.0, 560.0, 530.0, 510.0], [30.0, 31.0, 24.0, 29.0, 20.0, 10.0],
                   [CURRENT, RIGHT, RIGHT, RIGHT, CURRENT, LEFT])
    assert seek_speed(cars, Lat.RIGHT) == pytest.approx(29.0 - SEEK_SLOWER)
    assert seek_speed(cars, Lat.LEFT) == pytest.approx(10.0 - SEEK_SLOWER)
    alone = _around([500.0, 530.0], [30.0, 20.0], [CURRENT, CURRENT])
    assert seek_speed(alone, Lat.RIGHT) == np.inf  # nobody in the target lane: nothing to seek
    crawling = _around([500.0, 480.0], [10.0, 2.0], [CURRENT, RIGHT])
    assert seek_speed(crawling, Lat.RIGHT) == 0.0
