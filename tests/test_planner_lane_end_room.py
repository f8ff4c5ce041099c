"""Room before the end of the ego's lane for every lane change it must still make (docs/planner.md, "Room for every
change"), on the highway_exit net: ex_decel (226.34 m) has the deceleration lane ex_decel_0, the only way onto
ex_ramp; from ex_decel_2 the ego must make 2 changes, from ex_decel_1 one."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.forward_sim import Rollouts, SimSettings, Vehicles, ego_end_room, simulate
from sumo_rss.planner.lanes import CURRENT, RIGHT, lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.params import RssParamArrays, RssParams

MARGIN = SimSettings().lane_end_margin  # [m] the waiting margin, 20 m


@pytest.fixture(scope="module")
def exit_net() -> RoadNetwork:
    return RoadNetwork.from_file(NETWORKS / "highway_exit" / "highway_exit.net.xml")


def _frame(net: RoadNetwork, lane: str) -> RoadFrame:
    k = int(net.lane_indices([lane])[0])
    route = net.edge_indices(["ex_in", "ex_decel", "ex_ramp"])
    return RoadFrame.build(lane_chains(net, k, route[list(route).index(net.lane_edge[k]):]))


@pytest.mark.parametrize("lane, room", [("ex_in_2", 2 * MARGIN), ("ex_in_0", 0.0), ("ex_decel_2", MARGIN),
                                        ("ex_decel_1", 0.0), ("ex_decel_0", 0.0)])
def test_the_room_grows_with_the_changes_after_the_next_one(exit_net, lane, room):
    assert ego_end_room(_frame(exit_net, lane), MARGIN) == pytest.approx(room)


def test_no_room_where_the_lane_does_not_end_or_needs_one_change():
    merge = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    frame = RoadFrame.build(lane_chains(merge, int(merge.lane_indices(["mw_merge_0"])[0]),
                                        merge.edge_indices(["mw_merge", "mw_out"])))
    assert ego_end_room(frame, MARGIN) == 0.0
    highway = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    frame = RoadFrame.build(lane_chains(highway, int(highway.lane_indices(["hw0_2"])[0]),
                                        highway.edge_indices(["hw0", "hw1", "hw2"])))
    assert ego_end_room(frame, MARGIN) == 0.0


def _ego_alone(frame: RoadFrame, back_from_end: float, speed: float, lat: int) -> tuple[np.ndarray, np.ndarray]:
    """The ego alone ``back_from_end`` m (front bumper) before its lane's end at ``speed`` [m/s], 12 s of one
    rollout towards ``lat``: its front bumper's distance to that end [m] and its chain, per sample."""
    end = float(frame.end_s[CURRENT])
    s = end - back_from_end - 2.25
    vehicles = Vehicles(np.array([s]), np.zeros(1), np.zeros(1), np.array([speed]), np.zeros(1), np.zeros(1),
                        np.array([4.5]), np.array([1.8]), np.array([CURRENT]))
    rollouts = Rollouts(np.full((1, 12), lat), np.full(1, 20.0), np.ones(1), np.zeros(1, dtype=bool), 4.2,
                        np.full((1, 1), CURRENT), np.zeros(1))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 12, SimSettings(), RssParams(),
                   RssParamArrays.stack([RssParams()]))
    return end - (sim.s[0, :, 0] + 2.25), sim.chain[0, :, 0]


@pytest.mark.parametrize("lane, stands", [("ex_decel_2", 2 * MARGIN), ("ex_decel_1", MARGIN)])
def test_an_ego_keeping_its_lane_waits_with_room_for_every_change_still_to_make(exit_net, lane, stands):
    to_end, _ = _ego_alone(_frame(exit_net, lane), 80.0, 8.0, CURRENT)
    assert stands - 1.0 < to_end[-1] < stands + 3.0


def test_a_change_under_way_keeps_the_room_of_the_change_after_it(exit_net):
    """Going from ex_decel_2 towards ex_decel_1 at 3 m/s, 25 m before the end: while its centre is still in
    ex_decel_2 the ego keeps the room of its last change (with all of the lane to use it went on to 16.8 m before
    its centre crossed). (The rollout does not see ex_decel_1 end: a neighbour's end is known only where it ends
    for good.)"""
    to_end, chain = _ego_alone(_frame(exit_net, "ex_decel_2"), 25.0, 3.0, RIGHT)
    in_lane = np.cumsum(chain == RIGHT) == 0  # the samples before its centre first crosses
    assert to_end[in_lane].min() > MARGIN - 0.5
