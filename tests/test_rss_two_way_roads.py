"""Two-way roads on real geometry: oncoming cars are framed by the road's own lanes (the other car's Frenet
coordinates, the reversed path length and the measured distance between the lanes), and two reversed edges between
the same nodes are one road only if they run side by side.

tests/data/bs3d_kink.net.xml: Braunschweig's 22959383 / -22959383 (eclipse-sumo's bs3d net, OSM), a two-way road
at 80 km/h, one 3.2 m lane each way, with a 31° kink 20 m from its northern end.
tests/data/block: two one-way streets round a block between the same junctions, 22 m apart (as Bologna's 57[1] /
58[0]), with two-way roads at either end.
"""
from __future__ import annotations

import libsumo
import numpy as np
import pytest

from lane_snapshots import WIDTH, road_situations
from sumo_runs import CAR, DATA, build_net, hold_speed, run_sumo
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, ParamResolver
from sumo_rss.rss.fcd import FcdReader, read_vehicle_info

KINK = DATA / "bs3d_kink.net.xml"
OPPOSITE = 1  # situation code


def test_an_oncoming_car_passing_the_kink_keeps_its_own_lateral_speed_and_the_pair_is_safe():
    """a drives north at 15 m/s 120 m along -22959383; b drives south at 15 m/s, swept 0.1 m at a time through the
    kink, both along their lanes (no lateral speed in SUMO). Verdict: two cars passing each other in their own lanes
    are safe at every position (lateral gap ≥ 0.82 m: b's body, a chord across the kink, cuts its corner towards a;
    the lateral d_min of two cars without lateral speed is 0.35 m). Projected onto a's lane, b took the kink's 31°
    as its direction there: 7.8 m/s sideways, a lateral gap of −0.42 m (overlap) and 8 dangerous positions."""
    net = RoadNetwork.from_file(KINK)
    sweep = [road_situations(net, [("a", "-22959383_0", 120.0, 15.0), ("b", "22959383_0", float(pos), 15.0)])
             for pos in np.arange(5.0, 60.0, 0.1)]
    pairs = [p for p in sweep if len(p)]
    assert len(pairs) == len(sweep) and all(p.kind[0] == OPPOSITE for p in pairs)
    assert max(abs(p.v_lat_a[0]) + abs(p.v_lat_b[0]) for p in pairs) == 0.0
    lateral = np.array([p.lat_gap[0] for p in pairs])
    assert lateral.min() > 0.8 and lateral.max() == pytest.approx(3.2 - WIDTH, abs=1e-3)
    assert not any(p.dangerous[0] for p in pairs)


def test_the_lanes_of_the_kinked_road_map_onto_each_other_by_the_reversed_path_length():
    """Each direction's lane starts where the other ends and runs 3.2 m to its left, along the whole road."""
    net = RoadNetwork.from_file(KINK)
    north, south = net.lane_indices(["-22959383_0", "22959383_0"])
    roads = net.two_way
    assert net.edge_opposite[net.lane_edge[north]] == net.lane_edge[south]
    for lane, other in ((north, south), (south, north)):
        assert roads.offset[lane, 0] == pytest.approx(3.2, abs=0.01)
        assert roads.start[lane, 0] == pytest.approx(net.lane_length[lane], abs=1.5)
        assert roads.end[lane, 0] == pytest.approx(0.0, abs=1.5)


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    folder = tmp_path_factory.mktemp("block")
    net = build_net(DATA / "block", folder / "block.net.xml")

    def setup():  # east drives W-E along the straight street while west comes back E-W round the block
        for vid, route, pos in (("east", "e", "60"), ("west", "w", "100")):
            libsumo.vehicle.add(vid, route, typeID="car", departPos=pos, departSpeed="13")
            hold_speed(vid, 13.0)

    routes = CAR + '<route id="e" edges="AW WE EB"/><route id="w" edges="BE EW WA"/>'
    return run_sumo(net, folder, routes, 25.0, setup)


def test_two_one_way_streets_round_a_block_are_no_two_way_road(block):
    """WE and EW join the same two junctions in opposite directions but run 22 m apart: no two-way road, and two
    cars on them are never an opposite-direction pair (they were, framed on each other's lanes). The approach roads
    at either end are two-way roads, 3.2 m between their lanes' centres."""
    net = RoadNetwork.from_file(block.net)
    we, ew, aw, wa = net.edge_indices(["WE", "EW", "AW", "WA"])
    assert net.edge_opposite[we] == -1 and net.edge_opposite[ew] == -1
    assert net.edge_opposite[aw] == wa and net.edge_opposite[wa] == aw
    vehicles = read_vehicle_info(block.routes, block.net)
    auditor = Auditor(net, ParamResolver())
    on_the_block = 0
    for snapshot in FcdReader(block.fcd, net, vehicles):
        pairs = auditor.observe(snapshot)
        edges = set(snapshot.edge_id.tolist())
        on_the_block += int(edges == {"WE", "EW"})
        assert not (pairs.kind == OPPOSITE).any() or edges != {"WE", "EW"}, snapshot.time
    assert on_the_block >= 50  # 5 s with one car on each street, driving towards each other
    assert block.audit().episodes.empty
