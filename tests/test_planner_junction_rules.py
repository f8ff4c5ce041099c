"""Stop lines before junctions (red, yellow, yield) on the real intersection networks."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.junction_rules import NO_STOP, STOP_MARGIN, Crossing, stop_line
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.road.routes import RouteTable
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.params import RssParamArrays
from sumo_rss.sim.snapshot import WorldSnapshot

def _model(name: str) -> tuple[RoadNetwork, JunctionModel]:
    net = RoadNetwork.from_file(NETWORKS / name / f"{name}.net.xml")
    return net, JunctionModel.from_file(net.path, net)


def _snapshot(net: RoadNetwork, cars: list[tuple[str, str, float, float, tuple[str, str]]],
              tls_states: dict[str, str] | None = None) -> WorldSnapshot:
    """``cars``: (id, lane id, metres before the lane's end, speed, route) on straight approach lanes."""
    n = len(cars)
    xs, ys, hs, pos = [], [], [], []
    for _, lane_id, before, _, _ in cars:
        k = int(net.lane_indices([lane_id])[0])
        end, prev = net.shapes.points[k, net.shapes.count[k] - 1], net.shapes.points[k, net.shapes.count[k] - 2]
        u = (end - prev) / np.linalg.norm(end - prev)
        p = end - before * u
        xs.append(p[0])
        ys.append(p[1])
        hs.append(np.arctan2(u[1], u[0]))
        pos.append(net.lane_length[k] - before)
    z = np.zeros(n)
    return WorldSnapshot(time=10.0, ids=np.array([c[0] for c in cars]), x=np.array(xs), y=np.array(ys),
                         heading=np.array(hs), speed=np.array([c[3] for c in cars], float), accel=z, lat_speed=z,
                         length=np.full(n, 4.5), width=np.full(n, 1.8), lane_id=np.array([c[1] for c in cars]),
                         edge_id=np.array([c[1].rsplit("_", 1)[0] for c in cars]), lane_index=np.zeros(n, int),
                         lane_pos=np.array(pos), lat_pos=z, vclass=np.array(["ego"] + ["background"] * (n - 1)),
                         vtype=np.full(n, "car"), signals=np.zeros(n, int), route_index=np.zeros(n, int),
                         route_edges=tuple(c[4] for c in cars), tls_states=tls_states)


def _stop(snapshot: WorldSnapshot, net: RoadNetwork, junctions: JunctionModel):
    """The stop line of the ego (row 0) under ad_rss (b_min 4, b_max 8 m/s², ρ 1 s, a_acc 3.5 m/s²)."""
    return stop_line(snapshot, 0, net, junctions, RouteTable(net), ParamResolver("ad_rss").arrays(snapshot))


def _signal(net: RoadNetwork, junctions: JunctionModel, lane_id: str, to_edge: str, state: str) -> dict[str, str]:
    """Every signal green ('G') except the link from ``lane_id`` to ``to_edge``, which shows ``state``."""
    lane = int(net.lane_indices([lane_id])[0])
    link = next(k for k in junctions.lane_links[lane] if k >= 0 and
                junctions.link_to_edge[k] == net.edge_indices([to_edge])[0])
    tls, index = str(junctions.link_tls[link]), int(junctions.link_tls_index[link])
    size = 1 + max(int(i) for i, t in zip(junctions.link_tls_index, junctions.link_tls) if t == tls)
    return {tls: "".join(state if i == index else "G" for i in range(size))}


def test_red_stops_the_ego_at_the_line_and_green_does_not():
    net, junctions = _model("intersection_tls")
    ego = ("ego", "S_in_0", 50.0, 10.0, ("S_in", "N_out"))
    red = _stop(_snapshot(net, [ego], _signal(net, junctions, "S_in_0", "N_out", "r")), net, junctions)
    assert red.reason == "red" and red.distance == pytest.approx(50.0 - STOP_MARGIN, abs=1e-6)
    assert _stop(_snapshot(net, [ego], _signal(net, junctions, "S_in_0", "N_out", "G")), net, junctions) == NO_STOP
    # The first conflict area of the ego's way (straight on from S_in_0) begins this far past where it stops.
    own = next(k for k in junctions.lane_links[int(net.lane_indices(["S_in_0"])[0])]
               if k >= 0 and junctions.link_to_edge[k] == net.edge_indices(["N_out"])[0])
    first_area = junctions.area_start[own, junctions.area_index[own] >= 0].min()
    assert red.area_beyond == pytest.approx(STOP_MARGIN + first_area) and 0.0 <= first_area < 15.0


def test_yellow_stops_the_ego_only_where_it_can_stop_at_b_min_and_red_only_where_it_can_at_b_max():
    net, junctions = _model("intersection_tls")
    yellow = _signal(net, junctions, "S_in_0", "N_out", "y")
    red = _signal(net, junctions, "S_in_0", "N_out", "r")
    # 14 m/s: stopping takes 24.5 m at b_min and 12.25 m at b_max (+ the 1 m margin before the line).

    def at(before: float, signal: dict[str, str]):
        return _stop(_snapshot(net, [("ego", "S_in_0", before, 14.0, ("S_in", "N_out"))], signal), net, junctions)

    assert at(40.0, yellow).reason == "yellow"
    assert at(20.0, yellow) == NO_STOP
    assert at(20.0, red).reason == "red"
    assert at(10.0, red) == NO_STOP  # too late to stop: it drives on


def test_the_minor_road_yields_to_a_major_road_car_that_arrives_in_time():
    net, junctions = _model("intersection_priority")
    ego = ("ego", "S_in_0", 30.0, 8.0, ("S_in", "J_N"))  # minor road, straight across
    near = ("major", "E_in_0", 60.0, 14.0, ("E_in", "J_W"))  # major road, straight: ~4 s from the crossing
    far = ("major", "E_in_0", 280.0, 14.0, ("E_in", "J_W"))  # ~20 s away: the ego crosses first
    assert _stop(_snapshot(net, [ego, near]), net, junctions).reason == "yield"
    assert _stop(_snapshot(net, [ego, far]), net, junctions) == NO_STOP
    assert _stop(_snapshot(net, [ego]), net, junctions) == NO_STOP
    # The major road does not yield to the minor one.
    major_ego = ("ego", "E_in_0", 60.0, 14.0, ("E_in", "J_W"))
    minor = ("minor", "S_in_0", 30.0, 8.0, ("S_in", "J_N"))
    assert _stop(_snapshot(net, [major_ego, minor]), net, junctions) == NO_STOP


def test_the_ego_waits_at_the_line_while_a_car_waits_at_red_next_to_its_turn():
    """intersection_tls, NS permissive phase: the ego turns left from S_in_1 (its light 'g'); a car waits at red on
    W_in_1 to turn left too. Their turns share an area that starts 0.2 m past W's stop line, so a car standing
    1 m before that line can not stop before it under ad_rss's worst case (1.75 m during ρ + 1.53 m braking),
    and it is nearer to the area than the ego: the ego, closing in behind it on the virtual line, would owe
    braking inside the junction (it stopped there and stayed 50 s, SUMO's crossing traffic waiting for it).
    Waiting 20 m back it could stop; the ego goes."""
    net, junctions = _model("intersection_tls")
    phase = {"C": "GGgrrrGGgrrr"}
    ego = ("ego", "S_in_1", 2.0, 0.0, ("S_in", "W_out"))
    stop = _stop(_snapshot(net, [ego, ("w", "W_in_1", 1.0, 0.0, ("W_in", "N_out"))], phase), net, junctions)
    assert stop.reason == "rss" and stop.distance == pytest.approx(2.0 - STOP_MARGIN, abs=1e-6)
    assert _stop(_snapshot(net, [ego, ("w", "W_in_1", 20.0, 0.0, ("W_in", "N_out"))], phase), net, junctions) == NO_STOP
    assert _stop(_snapshot(net, [ego], phase), net, junctions) == NO_STOP
    # Creeping up to its line at 1 m/s it can stop even less (5.3 m), and is in front of the ego: the same.
    creeping = ("w", "W_in_1", 1.0, 1.0, ("W_in", "N_out"))
    assert _stop(_snapshot(net, [ego, creeping], phase), net, junctions).reason == "rss"
    # Still 60 m out at 10 m/s it can stop before the area: if it comes too close later, stopping is its duty.
    coming = ("w", "W_in_1", 60.0, 10.0, ("W_in", "N_out"))
    assert _stop(_snapshot(net, [ego, coming], phase), net, junctions) == NO_STOP


def test_with_hold_standing_a_car_standing_at_red_does_not_hold_the_ego_but_a_creeping_one_does():
    """``[rss] hold_standing`` (CARLA's convention): the car standing at red 1 m before its line is not assumed to
    accelerate within ρ, so it can stop before the area (it stands) and the ego turns; one creeping at 1 m/s is
    moving, keeps a_acc and still holds the ego at its line (as in the test above)."""
    net, junctions = _model("intersection_tls")
    phase = {"C": "GGgrrrGGgrrr"}
    ego = ("ego", "S_in_1", 2.0, 0.0, ("S_in", "W_out"))
    resolver = ParamResolver("ad_rss", hold_standing=True)
    moving = RssParamArrays.stack([resolver.get("ego", "car")])

    def stop(snapshot):
        return stop_line(snapshot, 0, net, junctions, RouteTable(net), resolver.arrays(snapshot), moving)

    standing = _snapshot(net, [ego, ("w", "W_in_1", 1.0, 0.0, ("W_in", "N_out"))], phase)
    assert list(resolver.arrays(standing).lon_accel_max) == [0.0, 0.0]
    assert stop(standing) == NO_STOP
    assert stop(_snapshot(net, [ego, ("w", "W_in_1", 1.0, 1.0, ("W_in", "N_out"))], phase)).reason == "rss"


def test_the_yield_timing_assumes_the_ego_crossing_as_it_drives():
    """The ego standing 2 m before its line turns left across the oncoming straight lane (permissive left). It
    accelerates at 1.0 m/s² and turns at 3 m/s (its reference speed there): from rest, 2 m to the line take 2 s
    (reaching 2 m/s), and 25 m beyond it take 1 s to reach 3 m/s (2.5 m) and 22.5 / 3 = 7.5 s more, 10.5 s in
    all; the former assumption (1.5 m/s², no cap) gave √(2·1.5·27) / 1.5 = 6 s. An oncoming car 90-130 m out at
    13 m/s arrives in between: the ego started, found it would not clear in time after all, and stopped again."""
    assert Crossing(1.0, lambda start, length: 13.0 if start == 0.0 else 3.0).time_to_cover(0.0, 2.0, 27.0) == \
        pytest.approx(10.5)
    assert Crossing().time_to_cover(0.0, 2.0, 27.0) == pytest.approx(6.0)
    net, junctions = _model("intersection_tls")
    phase = {"C": "GGgrrrGGgrrr"}
    ego = ("ego", "S_in_1", 2.0, 0.0, ("S_in", "W_out"))
    as_driven = Crossing(1.0, lambda start, length: 13.0 if start == 0.0 else 3.0)

    def stop(oncoming_m: float, crossing: Crossing) -> str:
        snap = _snapshot(net, [ego, ("n", "N_in_0", oncoming_m, 13.0, ("N_in", "S_out"))], phase)
        return stop_line(snap, 0, net, junctions, RouteTable(net), ParamResolver("ad_rss").arrays(snap), None,
                         crossing).reason

    assert stop(110.0, Crossing()) == "" and stop(110.0, as_driven) == "yield"
    assert stop(150.0, Crossing()) == stop(150.0, as_driven) == ""
    assert stop(60.0, Crossing()) == stop(60.0, as_driven) == "yield"


def test_the_yield_timing_counts_each_cars_own_conflict_area():
    """docs/planner.md: the ego yields unless the car with priority reaches the conflict area at least 2 s after
    the ego would have cleared *it*. The oncoming straight car's area ends 15.4 m along the ego's left turn; a car
    waiting at red far back on W_in_1 (no priority) has an area ending later along the turn. It used to set the
    clearing time for every car: the ego yielded to an oncoming car 135-145 m out that arrives after it has
    cleared that car's own area. (140 m is now held by the RSS check along the crossing instead: the oncoming car
    would come within its RSS distance behind the ego on their virtual line before the ego has left their area; it
    goes from 150 m.)"""
    net, junctions = _model("intersection_tls")
    phase = {"C": "GGgrrrGGgrrr"}
    ego = ("ego", "S_in_1", 2.0, 0.0, ("S_in", "W_out"))
    waiting = ("w", "W_in_1", 100.0, 0.0, ("W_in", "N_out"))
    as_driven = Crossing(1.0, lambda start, length: 13.0 if start == 0.0 else 3.0)

    def stop(cars) -> str:
        snap = _snapshot(net, cars, phase)
        return stop_line(snap, 0, net, junctions, RouteTable(net), ParamResolver("ad_rss").arrays(snap), None,
                         as_driven).reason

    for oncoming_m, reason in ((130.0, "yield"), (140.0, "yield"), (150.0, "")):
        oncoming = ("n", "N_in_0", oncoming_m, 13.0, ("N_in", "S_out"))
        assert stop([ego, oncoming]) == stop([ego, oncoming, waiting]) == reason


def test_the_planners_stopping_distance_ramps_the_braking_at_its_jerk():
    """From 4.1 m/s accelerating at 2.6 m/s², braking at the ego's 5 m/s³ up to 5 m/s² takes 1.52 s to reach full
    braking (6.30 m covered, 2.27 m/s left) and 0.52 m more: 6.83 m, against 1.05 m at b_max 8 m/s² at once."""
    crossing = Crossing()
    assert crossing.stopping_distance(4.1, 2.6) == pytest.approx(6.827, abs=1e-3)
    assert crossing.stopping_distance(10.0, -5.0) == pytest.approx(10.0)  # already braking fully: v²/(2·5)
    assert crossing.stopping_distance(0.0, 0.0) == 0.0
    assert crossing.stopping_distance(0.5, 1.0) < 0.5  # it stands before the braking is full


def test_a_start_under_way_goes_on_where_stopping_would_stand_it_inside_the_junction():
    """intersection_priority: the ego crosses from the minor road and a major-road car (14 m/s) is 35-60 m from the
    crossing: it arrives after the ego would have cleared their area, but within the 2 s margin. Standing 3 m
    back, or still 30 m out at 8 m/s, the ego yields at its line. Moving off at 4 m/s 2 m before the line it cannot
    stop before the line as the planner brakes (3.4 m), yet could at b_max (1.0 m): it used to be told to stop,
    and stood in the junction (seed 17 with a = 2.6 m/s²); now it goes on. It still stops for a car that would
    reach the area before it has cleared it (30 m out)."""
    net, junctions = _model("intersection_priority")

    def reason(ego_before: float, v: float, major_m: float, accel: float = 0.0) -> str:
        snap = _snapshot(net, [("ego", "S_in_0", ego_before, v, ("S_in", "J_N")),
                               ("major", "E_in_0", major_m, 14.0, ("E_in", "J_W"))])
        return _stop(replace(snap, accel=np.array([accel, 0.0])), net, junctions).reason

    for major_m in (35.0, 45.0, 60.0):
        assert reason(3.0, 0.0, major_m) == reason(30.0, 8.0, major_m) == "yield"
        assert reason(2.0, 4.0, major_m) == "committed"
    assert reason(2.0, 3.0, 60.0, 2.0) == "committed"  # moving off slower but accelerating: 4.0 m to stop
    assert reason(2.0, 4.0, 30.0) == "yield"  # it would be in the area with the car: stopping is the lesser harm
    assert reason(2.0, 4.0, 100.0) == ""  # late enough even with the margin
    # Slow enough, or braking already, to stop before the line: it yields as before.
    assert reason(2.0, 1.5, 45.0) == reason(2.0, 4.0, 45.0, -5.0) == "yield"


def test_the_ego_does_not_start_a_crossing_that_would_turn_rss_unsafe_on_its_way():
    """intersection_priority, ``hold_standing`` (the scenario's): the ego standing 2 m before its line, a major-road
    car at 14 m/s. 90 m out (6.4 s) it would arrive over 2 s after the ego has cleared their area, but before that,
    once the ego can no longer stop before the area (RSS's worst case), the car comes within its RSS distance
    behind the ego on their virtual line: the ego would owe braking inside the junction (seed 17 with a = 2.6 m/s²
    stood there to the end of the run). It waits; 100 m out the crossing stays safe and it goes."""
    net, junctions = _model("intersection_priority")
    resolver = ParamResolver("ad_rss", hold_standing=True)
    moving = RssParamArrays.stack([resolver.get("ego", "car")])

    def reason(major_m: float) -> str:
        snap = _snapshot(net, [("ego", "S_in_0", 2.0, 0.0, ("S_in", "J_N")),
                               ("major", "E_in_0", major_m, 14.0, ("E_in", "J_W"))])
        return stop_line(snap, 0, net, junctions, RouteTable(net), resolver.arrays(snap), moving, Crossing(2.0)).reason

    assert reason(80.0) == reason(90.0) == "yield"
    assert reason(100.0) == ""
