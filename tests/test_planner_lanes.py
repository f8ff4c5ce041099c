"""Planning lanes and key vehicles on the shipped nets (highway lanes 3.5 m wide; hw0 straight along y = -8.75,
-5.25, -1.75 for lanes 0, 1, 2)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.key_vehicles import front_range, key_vehicles
from sumo_rss.planner.epsilon import EpsilonPlanner
from sumo_rss.planner.lanes import CURRENT, LEFT, RIGHT, lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.sim.snapshot import WorldSnapshot


def _net(name: str) -> RoadNetwork:
    return RoadNetwork.from_file(NETWORKS / name / f"{name}.net.xml")


def test_chains_follow_the_route_through_junctions():
    net = _net("highway")
    chains = lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1", "hw2"]))
    names = [[str(net.lane_ids[k]) for k in chain] for chain in chains.lanes]
    assert names[CURRENT][:3] == ["hw0_1", ":h1_0_1", "hw1_1"] and names[LEFT][0] == "hw0_2"
    s, d = chains.project(CURRENT, np.array([100.0, 100.0]), np.array([-5.25, -1.75]))
    np.testing.assert_allclose(s, [100.0, 100.0])
    np.testing.assert_allclose(d, [0.0, 3.5])
    # Limit 33.33 m/s; the 2000 m curve allows √(3·2000) = 77 m/s: the reference speed is the limit (not floored).
    assert chains.reference_speed(CURRENT, 800.0, desired=40.0) == pytest.approx(33.33)


def test_the_reference_speed_is_the_speed_from_which_the_ego_can_still_slow_down_to_what_lies_ahead():
    """epsilon.md §2.7 scans from the ego's position; here every lower speed ahead (a bend's √(3/|κ|), a lane's
    limit where it starts) is an envelope √(v² + 2·1.67 m/s²·distance), at epsilon.md §3.1's comfortable deceleration. S_in_1 (13.89 m/s, 289.6 m) leads into the
    left turn's junction lanes (9.26 m/s); the sharpest bend is κ = 0.1109 1/m at s = 299.28 (SUMO's middle three
    samples of the 90° turn in 19.3 m): 5.20 m/s there. The release took floor(min(...)) over v²/1.67 ahead, so the
    ego cruised at 13 m/s and slowed to 3 m/s from 115 m before the turn."""
    net = _net("intersection_tls")
    chains = lane_chains(net, int(net.lane_indices(["S_in_1"])[0]), net.edge_indices(["S_in", "W_out"]))
    assert chains.reference_speed(CURRENT, 50.0, desired=13.89) == 13.89
    # 20 m before the line: the turn's first bend sample (κ = 0.0818 1/m at s = 294.9: 6.06 m/s) gives
    # √(6.06² + 2·1.67·24.9) = 10.95 m/s, below its sharpest one's √(5.20² + 2·1.67·29.28) = 11.17 and the junction
    # lane's √(9.26² + 2·1.67·19.6) = 12.30.
    assert chains.reference_speed(CURRENT, 270.0, desired=13.89) == pytest.approx(10.95, abs=0.01)
    assert chains.reference_speed(CURRENT, 300.0, desired=13.89) == pytest.approx(5.20, abs=0.01)
    assert chains.reference_speed(CURRENT, 310.0, desired=13.89) == 13.89  # out of the turn, on W_out_1
    # A window's cap (the yield rule's crossing speeds): the slowest speed over it, the bend's within 20 m of 280.
    assert chains.speed_cap(CURRENT, 280.0, 20.0, 13.89) == pytest.approx(5.20, abs=0.01)
    assert chains.speed_cap(CURRENT, 250.0, 20.0, 13.89) == 13.89
    net = _net("merge")
    chains = lane_chains(net, int(net.lane_indices(["mw_merge_0"])[0]), net.edge_indices(["mw_merge", "mw_out"]))
    assert str(net.lane_ids[chains.lanes[chains.chain_of[CURRENT]][0]]) == "ramp_0"  # the ramp is in the chain
    assert chains.reference_speed(CURRENT, 100.0, desired=30.0) == 30.0
    assert chains.reference_speed(CURRENT, -100.0, desired=30.0) == 22.22  # on the ramp: its limit holds at once


def test_acceleration_lane_chain_ends_and_has_no_right_neighbour():
    net = _net("merge")
    lane = int(net.lane_indices(["mw_merge_0"])[0])
    chains = lane_chains(net, lane, net.edge_indices(["mw_merge", "mw_out"]))
    assert not chains.exists(RIGHT) and chains.exists(LEFT)
    current = [str(net.lane_ids[k]) for k in chains.lanes[chains.chain_of[CURRENT]]]
    assert current[-1] == "mw_merge_0" and current[0] == "ramp_0"  # the ramp behind, nothing after the lane end
    ramp_length = float(net.lane_length[net.lane_indices(["ramp_0"])[0]])
    assert chains.start_s[chains.chain_of[CURRENT]] > ramp_length  # s is measured from the ego's own lane


def _snapshot(xs, ys, speeds):
    n = len(xs)
    f = np.zeros(n)
    return WorldSnapshot(time=0.0, ids=np.array([f"v{i}" for i in range(n)]), x=np.asarray(xs, float),
                         y=np.asarray(ys, float), heading=f, speed=np.asarray(speeds, float), accel=f, lat_speed=f,
                         length=np.full(n, 4.5), width=np.full(n, 1.8), lane_id=np.array(["hw0_1"] * n),
                         edge_id=np.array(["hw0"] * n), lane_index=np.ones(n, int), lane_pos=np.asarray(xs, float),
                         lat_pos=f, vclass=np.array(["background"] * n), vtype=np.array(["car"] * n),
                         signals=np.zeros(n, int), route_index=np.zeros(n, int))


def test_key_vehicles_by_lane_and_range():
    net = _net("highway")
    chains = lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1", "hw2"]))
    # Ego (row 0) at x = 300 in lane 1 at 20 m/s: R_f = 20·max(5, 12.5) + 100 = 350 → clamp 170 m.
    assert front_range(20.0) == 170.0
    xs = [300, 400, 480, 290, 250, 260, 350]
    ys = [-5.25, -5.25, -5.25, -5.25, -1.75, -12.25, -8.75]
    speeds = [20, 20, 20, 10, 20, 20, 20]
    key = key_vehicles(_snapshot(xs, ys, speeds), 0, RoadFrame.build(chains))
    # 1: 100 m ahead, same lane; 2: 180 m ahead (> R_f) no; 3: the ego-lane follower 10 m behind (key in the
    # port); 4: 50 m behind in the left lane, within max(20, 5·20) = 100 m; 5: off every key lane (lane 0 is at
    # -8.75, this car 3.5 m further right); 6: 50 m ahead in the right lane.
    assert key.rows.tolist() == [1, 3, 4, 6]
    assert key.chain.tolist() == [CURRENT, CURRENT, LEFT, RIGHT]
    np.testing.assert_allclose(key.s, [100.0, -10.0, -50.0, 50.0])


def test_rear_key_range_covers_the_rss_distance_of_fast_followers():
    """A car 160 m behind a stopped ego at 30 m/s is beyond the 5·v = 150 m rear range but within its RSS distance
    under ad_rss (30·1 + 3.5·1²/2 + 33.5²/(2·4) = 172.0 m bumper gap): it is key once the reach is given."""
    net = _net("highway")
    chains = lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1", "hw2"]))
    snapshot = _snapshot([400, 240], [-5.25, -1.75], [0.0, 30.0])
    frame = RoadFrame.build(chains)
    assert key_vehicles(snapshot, 0, frame).rows.tolist() == []
    reach = EpsilonPlanner._rear_reach(snapshot, 0, ParamResolver().arrays(snapshot))
    assert reach[1] == pytest.approx(30.0 + 1.75 + 33.5 ** 2 / 8.0 + 4.5)
    assert key_vehicles(snapshot, 0, frame, reach).rows.tolist() == [1]


def _on_lane(net: RoadNetwork, lane_id: str, back_from_end: float) -> tuple[float, float, float]:
    """(x, y, heading) of the front bumper ``back_from_end`` m before the end of ``lane_id``."""
    k = int(net.lane_indices([lane_id])[0])
    pts = net.shapes.points[k, : net.shapes.count[k]]
    (x0, y0), (x1, y1) = pts[-2], pts[-1]
    heading = float(np.arctan2(y1 - y0, x1 - x0))
    return x1 - back_from_end * np.cos(heading), y1 - back_from_end * np.sin(heading), heading


@pytest.mark.parametrize("lane_id, may_change", [("ramp_0", False), ("mw_merge_0", True)])
def test_lane_changes_start_only_towards_a_neighbour_on_the_same_edge(lane_id, may_change):
    """The ramp runs beside the motorway before they join, but SUMO changes lanes only within an edge: no change
    starts on the ramp; on the acceleration lane the change to the left is planned."""
    net = _net("merge")
    x, y, heading = _on_lane(net, lane_id, 30.0)
    snap = WorldSnapshot(time=50.0, ids=np.array(["ego"]), x=np.array([x]), y=np.array([y]),
                         heading=np.array([heading]), speed=np.array([15.0]), accel=np.zeros(1),
                         lat_speed=np.zeros(1), length=np.array([4.5]), width=np.array([1.8]),
                         lane_id=np.array([lane_id]), edge_id=np.array([lane_id[:-2]]), lane_index=np.zeros(1, int),
                         lane_pos=np.array([100.0]), lat_pos=np.zeros(1), vclass=np.array(["ego"]),
                         vtype=np.array(["car"]), signals=np.zeros(1, int), route_index=np.zeros(1, int),
                         route_edges=((lane_id[:-2], "mw_merge", "mw_out") if lane_id == "ramp_0" else
                                      ("mw_merge", "mw_out"),))
    result = EpsilonPlanner(net, ParamResolver()).plan(snap, "ego")
    lateral = [name for name in result.costs if name != "backup" and set(name.split(":")[1]) != {"K"}]
    assert bool(lateral) == may_change
    # Per speed action: KKKKK, plus KLLLL ... KKKKL where the left lane may be entered (no lane on the right); + backup.
    assert len(result.costs) == (3 * 5 + 1 if may_change else 3 + 1)


def test_a_neighbour_chain_ends_where_its_lane_turns_off_the_route():
    """The ego in the left-turn lane S_in_1 (route S_in → W_out): its right neighbour S_in_0 leads only straight
    on or right, off the route. Carried on through the right turn, that chain read 37 m across the ego's frame
    at the junction (a 1.5 rad kink), and cars coming up in S_in_0 turned into the ego's way in the forward
    simulation: the ego's start across the junction was called off for a phantom collision."""
    net = _net("intersection_tls")
    chains = lane_chains(net, int(net.lane_indices(["S_in_1"])[0]), net.edge_indices(["S_in", "W_out"]))
    right = [str(net.lane_ids[k]) for k in chains.lanes[chains.chain_of[RIGHT]]]
    assert right[-1] == "S_in_0"
    frame = RoadFrame.build(chains)
    assert np.abs(np.diff(frame.centre[RIGHT])).max() < 0.2  # [m] per grid step: parallel to the ego's lane
    assert frame.end_s[RIGHT] == np.inf  # it goes on (off the route): no standing obstacle at its end


def test_the_route_says_which_lane_changes_the_ego_still_has_to_make_and_where_its_lane_leaves_the_route():
    """SUMO's "best lanes" for the planner's mandatory changes. highway_exit: ex_in (3 lanes, 1096 m) leads lane by
    lane into lanes 1-3 of ex_decel (226.34 m as built, its 8 m junction lanes between); lane 0 of ex_decel is the
    deceleration lane, the only way onto ex_ramp. From ex_in's left lane that is 3 changes, 2 of them on ex_in
    (the rest cannot be made earlier), and its lane leaves the route at the end of ex_decel_3, 1096 + 8 + 226.34 m
    on. From the acceleration lane of the merge: 1 change to the left, within its 270.31 m."""
    net = _net("highway_exit")
    route = net.edge_indices(["ex_in", "ex_decel", "ex_ramp"])
    for lane, changes, end in (("ex_in_2", (-2, 3), 1330.34), ("ex_in_0", (0, 1), 1330.34),
                               ("ex_decel_1", (-1, 1), 226.34), ("ex_decel_0", (0, 0), np.inf)):
        k = int(net.lane_indices([lane])[0])
        chains = lane_chains(net, k, route[list(route).index(net.lane_edge[k]):])
        assert chains.changes == changes, lane
        assert chains.route_end == pytest.approx(end, abs=0.01), lane
    frame = RoadFrame.build(lane_chains(net, int(net.lane_indices(["ex_in_2"])[0]), route))
    assert frame.end_s[CURRENT] == pytest.approx(1330.34, abs=0.01)  # the ego's own lane ends there for it
    net = _net("merge")
    chains = lane_chains(net, int(net.lane_indices(["mw_merge_0"])[0]), net.edge_indices(["mw_merge", "mw_out"]))
    assert chains.changes == (1, 1) and chains.route_end == pytest.approx(270.31, abs=0.01)
    highway = _net("highway")
    chains = lane_chains(highway, int(highway.lane_indices(["hw0_2"])[0]), highway.edge_indices(["hw0", "hw1", "hw2"]))
    assert chains.changes == (0, 0) and chains.route_end == np.inf
