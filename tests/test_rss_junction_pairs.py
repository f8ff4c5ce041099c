"""Pairs the auditor must keep watching at junctions of a real net, and the 'in front' rule where two paths cross.

tests/data/drt_fragment.net.xml (eclipse-sumo's DRT net, OSM): 143308542#7 is a 0.2 m edge (3 lanes) between two
junctions, its lane 1 turning right (:1560224076_2_0) or going straight on, lane 2 straight on only; at the signal
cluster_1560224191_... the left turn from 71028777#2 (link 2, permissive 'g') crosses the oncoming straight link 9
from -71028774#0 ('G'), their conflict area 0.2-15.2 m along the turn and 13.8-28.4 m along the straight path.
"""
from __future__ import annotations

import libsumo
import numpy as np
import pytest

from lane_snapshots import road_situations
from sumo_runs import CAR, DATA, hold_speed, run_sumo
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.intersection import PRIORITY_B, intersection_safety
from sumo_rss.rss.params import preset_params

NET = DATA / "drt_fragment.net.xml"
SIGNAL = "cluster_1560224191_1560224195_2697454310_443598395"
AREA = f"{SIGNAL}:2x9"


def test_a_car_turning_off_over_a_sub_metre_edge_stays_paired_with_the_car_behind_it():
    """F has turned right from lane 1 of the 0.2 m edge, its front 2 m into the junction's lane, its rear still across
    the edge; R follows in lane 2 (straight on), its front 3.4 m behind F's rear, 3 m/s against F's 2 m/s, F still
    drifting left towards R's lane at 1 m/s (SUMO's lane change, 3 s). Verdict: a same-direction pair 3.4 m apart
    (d_min 9.78 m), laterally unsafe: dangerous. It was no pair at all once F was on the junction's lane (R's lane
    does not lead there), and in Bologna the two collided one second later with no episode."""
    net = RoadNetwork.from_file(NET)
    six = float(net.lane_length[net.lane_indices(["143308542#6_2"])[0]])
    first_junction = float(net.lane_length[net.lane_indices([":945141561_0_1"])[0]])
    rear_pos = six - (2.5 + 3.4 - 0.2 - first_junction)  # 3.4 m behind F's rear, along the lanes
    cars = [("F", ":1560224076_2_0", 2.0, 2.0, ("143308542#7", "142575691#0")),
            ("R", "143308542#6_2", rear_pos, 3.0, ("143308542#6", "143308542#7", "143308542#8"))]
    pairs = road_situations(net, cars, {"F": (0.0, 1.0)})
    assert len(pairs) == 1 and pairs.kind[0] == 0 and not pairs.a_is_rear[0]
    assert pairs.lon_gap[0] == pytest.approx(3.4, abs=0.1) and pairs.lon_d_min[0] == pytest.approx(9.78, abs=0.01)
    assert pairs.lat_gap[0] < pairs.lat_d_min[0] and pairs.dangerous[0]
    assert len(road_situations(net, [cars[0], (*cars[1][:4], ("143308542#6", "143308542#7", "143308542#8"))],
                               {"F": (0.0, 1.0)})) == 1
    clear = road_situations(net, [("F", ":1560224076_2_0", 5.0, 2.0, cars[0][4]), cars[1]])
    assert len(clear) == 0  # once F's rear has left the edge, R (going straight on) follows it no more


def test_the_left_turn_area_is_a_crossing_and_a_car_standing_in_it_is_no_leader_of_the_oncoming_car():
    """The turning car L stands 7.4 m into the area; the oncoming car O, at 8 m/s, is 12.5 m into its own part of
    the area (ahead of L on ad_rss's virtual line: −12.5 + 4.5 < −7.4). Read as O leading L away from the area, the
    pair was safe ('in front', L standing needs 3.28 m); but O drives towards L, and the area is theirs: L, inside it,
    cannot stop before it, neither can O, and L never leaves it: dangerous. ad_rss's reading stays the default of
    the formula (its parity cases), the audit passes the area's kind."""
    net = RoadNetwork.from_file(NET)
    junctions = JunctionModel.from_file(NET, net)
    area = next(c for c in junctions.conflicts if c.id == AREA)
    assert area.kind == "crossing" and junctions.area_crossing[junctions.conflicts.index(area)]
    p = preset_params("ad_rss", "background")
    args = (0.0, -7.4, 15.2 - 7.4 + 4.5, 4.5, p, 8.0, -12.5, 28.4 - 13.8 - 12.5 + 4.5, 4.5, p, PRIORITY_B)
    virtual = intersection_safety(*args)
    assert virtual.b_in_front[()] and virtual.in_front[()] and virtual.safe[()]
    crossing = intersection_safety(*args, crossing=True)
    assert not crossing.in_front[()] and not crossing.safe[()]


@pytest.fixture(scope="module")
def blocked_turn(tmp_path_factory):
    """L turns left at 4 m/s and stops in the junction, its body across the oncoming lane; O comes straight on at
    8 m/s, green, and does not brake (SUMO: O collides with L at 11.5 s)."""
    folder = tmp_path_factory.mktemp("left_turn")
    speeds = {"L": 4.0, "O": 8.0}

    def control(time: float) -> None:
        if time < 1e-6:
            libsumo.trafficlight.setRedYellowGreenState(SIGNAL, "gGggrrrrgGggrrrrrGrG")
        ids = libsumo.vehicle.getIDList()
        if "L" in ids and libsumo.vehicle.getLaneID("L").endswith("_17_0") and libsumo.vehicle.getLanePosition("L") >= 2:
            speeds["L"] = max(0.0, speeds["L"] - 0.4)
        for vid, speed in speeds.items():
            if vid in ids:
                hold_speed(vid, speed)

    routes = CAR + '<route id="rl" edges="71028777#2 142575693#3"/><route id="ro" edges="-71028774#0 -71028777#2"/>' \
        '<vehicle id="L" type="car" route="rl" depart="0" departLane="1" departPos="80" departSpeed="4"/>' \
        '<vehicle id="O" type="car" route="ro" depart="2" departLane="0" departPos="20" departSpeed="8"/>'
    return run_sumo(NET, folder, routes, 14.0, lambda: None, control)


def test_the_oncoming_car_that_drives_into_the_standing_turner_is_responsible(blocked_turn):
    """Verdict: L stands in the area ahead of O (it got there first: 'in front'); O must brake and does not: O is
    responsible for the collision, which closes the pair's episode."""
    result = blocked_turn.audit()
    assert len(result.collisions) == 1
    collision = result.collisions.iloc[0]
    assert collision.blamed == "O" and collision.episode_key == "L|O|x1"
    episode = result.episodes.set_index("episode_key").loc["L|O|x1"]
    assert episode.conflict_area == AREA and episode.trigger == "in-front" and episode.owed_b == "int:brake-min"
    assert episode.t_b_s < collision.time_s - 3.0 and np.isclose(episode.t_end_s, collision.time_s)
