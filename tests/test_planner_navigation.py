"""The planner's lane-change navigation on the shipped nets: when the route (or a lane's end) makes a change
mandatory and to which side, and which changes an owed lateral response rules out."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.dcp_tree import Lat
from sumo_rss.planner.epsilon import EpsilonPlanner, _held_sides
from sumo_rss.planner.lanes import lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.responsibility import OwedResponses


@pytest.fixture(scope="module")
def exit_net() -> tuple[RoadNetwork, EpsilonPlanner]:
    net = RoadNetwork.from_file(NETWORKS / "highway_exit" / "highway_exit.net.xml")
    return net, EpsilonPlanner(net, ParamResolver())


def _frame(net: RoadNetwork, lane: str, route: list[str]) -> RoadFrame:
    return RoadFrame.build(lane_chains(net, int(net.lane_indices([lane])[0]), net.edge_indices(route)))


def test_an_exit_three_lanes_away_is_due_three_reaches_before_the_lane_leaves_the_route(exit_net):
    """From ex_in_2 the lane leaves the route 1330.34 m from its start (test_planner_lanes); 3 changes at 25 m/s are
    due within 3·max(200 m, 10 s·25 m/s) = 750 m of that: not at 550 m along the lane (780 m left), at 600 m."""
    net, planner = exit_net
    frame = _frame(net, "ex_in_2", ["ex_in", "ex_decel", "ex_ramp"])
    assert planner._mandatory(frame, 550.0, 25.0) is None
    assert planner._mandatory(frame, 600.0, 25.0) is Lat.RIGHT
    # At 33 m/s each change needs 330 m: due 990 m before the end, at 400 m along the lane (930 m left).
    assert planner._mandatory(frame, 300.0, 33.0) is None and planner._mandatory(frame, 400.0, 33.0) is Lat.RIGHT


def test_a_change_that_can_only_be_made_on_the_next_edge_is_not_due_yet(exit_net):
    """On ex_in_0 the last change is into the deceleration lane, which starts on ex_decel: on ex_in there is no
    lane to the right, and a left change would be wrong; on ex_decel_1 it is due (226 m before its end)."""
    net, planner = exit_net
    assert planner._mandatory(_frame(net, "ex_in_0", ["ex_in", "ex_decel", "ex_ramp"]), 1200.0, 25.0) is None
    assert planner._mandatory(_frame(net, "ex_decel_1", ["ex_decel", "ex_ramp"]), 20.0, 25.0) is Lat.RIGHT
    # Staying on the motorway, the same lane needs no change.
    assert planner._mandatory(_frame(net, "ex_decel_1", ["ex_decel", "ex_main"]), 200.0, 25.0) is None


def test_the_acceleration_lane_end_makes_the_change_to_the_motorway_due():
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    planner = EpsilonPlanner(net, ParamResolver())
    frame = _frame(net, "mw_merge_0", ["mw_merge", "mw_out"])
    assert planner._mandatory(frame, 60.0, 20.0) is None  # 210 m before the end (270.31 m), more than 200 m
    assert planner._mandatory(frame, 80.0, 20.0) is Lat.LEFT


def _owed(lateral: list[bool], left: list[bool]) -> OwedResponses:
    n = len(lateral)
    no = np.zeros(n, dtype=bool)
    return OwedResponses(t_b=np.zeros(n), must_brake=no, brake_correct=no, front_limited=no,
                         owed_lat=np.array(lateral), other_is_left=np.array(left), u0=np.zeros(n),
                         other_id=np.array([f"c{i}" for i in range(n)]), same_direction=~no, lat_settled=no)


def test_a_lateral_response_owed_rules_out_starting_a_change_towards_that_side(highway):
    net, _ = highway
    planner = EpsilonPlanner(net, ParamResolver())
    assert _held_sides(None) == frozenset() and _held_sides(_owed([False], [True])) == frozenset()
    held = _held_sides(_owed([True, False, True], [True, False, True]))
    assert held == frozenset({Lat.LEFT})
    lane = int(net.lane_indices(["hw0_1"])[0])
    frame = _frame(net, "hw0_1", ["hw0", "hw1", "hw2"])
    free = planner._policies(40.0, frame, lane)
    kept = planner._policies(40.0, frame, lane, held)
    assert len(free) == 27 and len(kept) == 15  # 3 x (1 keep + 4 right changes): no left change starts
    assert not [p for p in kept if Lat.LEFT in p.lats] and [p for p in kept if Lat.RIGHT in p.lats]
