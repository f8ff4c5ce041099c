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
from sumo_rss.planner.epsilon import EGO_SIM, EpsilonPlanner, PlannerConfig
from sumo_rss.planner.gap_aim import aim_at_gap
from sumo_rss.planner.lanes import CURRENT, LEFT, RIGHT, lane_chains
from sumo_rss.planner.navigation import SEEK_SLOWER, change_held, change_stuck, held_sides, mandatory_change, \
    seek_speed
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.params import RssParamArrays, RssParams
from sumo_rss.rss.responsibility import OwedResponses
from sumo_rss.sim.snapshot import WorldSnapshot


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


def _ad_rss(n: int) -> RssParamArrays:
    return RssParamArrays.stack([RssParams()] * n)  # ad_rss: ρ 1 s, a_acc 3.5, b_min 4, b_max 8 m/s², λ 0


def test_a_mandatory_change_with_no_reachable_gap_seeks_it_slower_than_the_nearest_cars_of_the_target_lane():
    """The ego at 30 m/s at s = 500; right lane: a 31 m/s car 35 m behind (nearest behind), a 24 m/s car 80 m
    behind (not the nearest), a 29 m/s car 60 m ahead; a 20 m/s car ahead in the ego's own lane and a 10 m/s car in
    the left lane do not count. With no room to reach a gap (0 m: no gap is RSS-legal now, and at 30 m/s the ego
    cannot stop within 0 m): SEEK_SLOWER below min(31, 29) = 29 m/s."""
    cars = _around([500.0, 465.0, 420.0, 560.0, 530.0, 510.0], [30.0, 31.0, 24.0, 29.0, 20.0, 10.0],
                   [CURRENT, RIGHT, RIGHT, RIGHT, CURRENT, LEFT])
    assert seek_speed(cars, _ad_rss(6), Lat.RIGHT, 0.0, 33.0, EGO_SIM) == pytest.approx(29.0 - SEEK_SLOWER)
    assert seek_speed(cars, _ad_rss(6), Lat.LEFT, 0.0, 33.0, EGO_SIM) == pytest.approx(10.0 - SEEK_SLOWER)
    alone = _around([500.0, 530.0], [30.0, 20.0], [CURRENT, CURRENT])
    assert seek_speed(alone, _ad_rss(2), Lat.RIGHT, 0.0, 33.0, EGO_SIM) == np.inf  # nobody in the target lane
    crawling = _around([500.0, 497.0], [10.0, 2.0], [CURRENT, RIGHT])  # beside the ego: not legal now
    assert seek_speed(crawling, _ad_rss(2), Lat.RIGHT, 0.0, 33.0, EGO_SIM) == 0.0


def test_a_held_mandatory_change_aims_at_a_gap_speeding_up_ahead_of_a_car_or_slowing_down_behind_it():
    """Ego (4.7 m) at 20 m/s at s = 500, one 4.5 m car at 20 m/s in the left lane 40 m behind (bumper gap 35.4 m),
    ad_rss. Ahead of it the ego at speed u needs d_min(20, u) = D(20) − u²/16 with D(20) = 20 + 1.75 + 23.5²/8 =
    90.78 m (65.8 m at u = 20: not legal now). Speeding up at 2 m/s² the gap grows by t² while d_min falls:
    35.4 + t² ≥ 90.78 − (20 + 2t)²/16 first at t ≈ 3.3 s (v 26.7 m/s), on the 0.2 s grid 3.4 s, and still 1 s later:
    the aim is u = 27 m/s, the nearest speed whose profile gets there as soon, no car ahead of the gap. With 200 m of
    room the ego could not stop short of its end from there (79.6 m + 27²/(2·1.67) = 298 m), so it slows down (at
    AIM_BRAKE) to let the car pass and slip in behind it: u = 9 m/s at t = 10.4 s, 9.5 m behind the car (d_min(9.6,
    20) = 7.8 m; 154 m + 9²/(2·1.67) = 178 m of room). With 60 m it cannot even stop within the room (120 m at
    20 m/s): no aim."""
    cars = Vehicles(np.array([500.0, 460.0]), np.zeros(2), np.zeros(2), np.array([20.0, 20.0]), np.zeros(2),
                    np.zeros(2), np.array([4.7, 4.5]), np.full(2, 1.8), np.array([CURRENT, LEFT]))
    ahead = aim_at_gap(cars, LEFT, _ad_rss(2), 1000.0, 33.0, 1.0, 2.0, 1.67)
    assert (ahead.speed, ahead.rear, ahead.front) == (27.0, 1, 0) and ahead.time == pytest.approx(3.4)
    behind = aim_at_gap(cars, LEFT, _ad_rss(2), 200.0, 33.0, 1.0, 2.0, 1.67)
    assert (behind.speed, behind.rear, behind.front) == (9.0, 0, 1) and behind.time == pytest.approx(10.4)
    assert aim_at_gap(cars, LEFT, _ad_rss(2), 60.0, 33.0, 1.0, 2.0, 1.67) is None
    assert seek_speed(cars, _ad_rss(2), Lat.LEFT, 1000.0, 33.0, EGO_SIM) == 27.0
    far = replace(cars, s=np.array([500.0, 380.0]))  # 115.4 m ≥ 65.8 m and still 1 s later: take it now
    assert aim_at_gap(far, LEFT, _ad_rss(2), 1000.0, 33.0, 1.0, 2.0, 1.67).time == 0.0
    assert seek_speed(far, _ad_rss(2), Lat.LEFT, 1000.0, 33.0, EGO_SIM) == np.inf

def _merge_snapshot(t: float, lane_pos: list[float], speeds: list[float], lanes: list[str]) -> WorldSnapshot:
    """Cars on the merge network's straight mw_merge (the acceleration lane mw_merge_0 at y = −8.75 m, lane 1 at
    −5.25 m, from x = 675.69 m), front bumpers at ``lane_pos`` [m]; column 0 is the ego (4.7 m), the others 4.5 m."""
    n = len(lane_pos)
    zero = np.zeros(n)
    y = {"mw_merge_0": -8.75, "mw_merge_1": -5.25}
    vclass = np.array(["ego"] + ["background"] * (n - 1))
    return WorldSnapshot(time=t, ids=np.array([f"v{i}" for i in range(n)]), x=675.69 + np.array(lane_pos),
                         y=np.array([y[lane] for lane in lanes]), heading=zero.copy(), speed=np.array(speeds),
                         accel=zero.copy(), lat_speed=zero.copy(), length=np.array([4.7] + [4.5] * (n - 1)),
                         width=np.full(n, 1.8), lane_id=np.array(lanes), edge_id=np.array(["mw_merge"] * n),
                         lane_index=np.array([int(lane[-1]) for lane in lanes]), lane_pos=np.array(lane_pos),
                         lat_pos=zero.copy(), vclass=vclass, vtype=np.array(["car"] * n), signals=np.zeros(n, int),
                         route_index=np.zeros(n, int), route_edges=tuple(("mw_merge", "mw_out") for _ in range(n)))


def test_on_the_acceleration_lane_a_held_merge_slows_down_to_slip_in_behind_the_car_beside_it():
    """The real merge network and planner (ad_rss): the ego at 15 m/s 190 m before the acceleration lane's end (its
    front at 80 m of 270.31), a car at 20 m/s in lane 1 with its front 20 m behind the ego's. The change left is due
    and the barrier holds it (that car is not RSS-safe behind the ego); in the next cycle the ego aims at the gap
    behind that car: 10 m/s, legal 4.8 s on (d_min(10, 20) = max(0, 10 + 1.75 + 13.5²/8 − 20²/16) = 9.5 m behind
    it), short of the 20 m waiting margin. Its plan slows from 15 to < 11.5 m/s within the horizon (the fallback
    rule, SEEK_SLOWER below the 20 m/s car, would hold 15 m/s and let the car pass at 5 m/s)."""
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    planner = EpsilonPlanner(net, ParamResolver(), PlannerConfig(desired_speed=30.0))
    lanes = ["mw_merge_0", "mw_merge_1"]
    planner.plan(_merge_snapshot(40.0, [80.0, 60.0], [15.0, 20.0], lanes), "v0")
    assert planner._seeking is Lat.LEFT and planner.stats.gap_seek_cycles == 0  # held: seeks from the next cycle
    snapshot = _merge_snapshot(40.1, [81.5, 62.0], [15.0, 20.0], lanes)
    frame = planner.frame_for(snapshot, 0)
    vehicles, params = planner._aim_vehicles(snapshot, 0, frame, planner.params.arrays(snapshot),
                                             RssParamArrays.stack([planner.params.get("ego", "car")]))
    room = float(frame.end_s[CURRENT]) - float(vehicles.s[0]) - 2.35 - EGO_SIM.lane_end_margin
    aim = aim_at_gap(vehicles, LEFT, params, room, 30.0, 1.0, EGO_SIM.ego_limits.max_accel,
                     EGO_SIM.ego_idm.comfort_brake)
    assert (aim.speed, aim.rear, aim.front) == (10.0, 0, 1) and aim.time == pytest.approx(4.6, abs=0.21)
    result = planner.plan(snapshot, "v0")
    assert planner.stats.gap_seek_cycles == 1
    assert result.trajectory.speed[-1] < 11.5 and np.all(np.diff(result.trajectory.speed) <= 1e-9)
