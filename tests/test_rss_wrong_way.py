"""A car overtaking through the oncoming lane of a two-way road: SUMO reports it on the opposite edge's lane, heading
against it. The auditor frames it on its own edge, in the wrong lane (rss.md §2: the car in its correct lane brakes
at b_corr, the other at b_min), so it is in an opposite-direction situation with the oncoming car and in a
same-direction one with the car it overtakes. It used to be taken as a car of the oncoming lane: a head-on
collision it caused was a same-direction episode in which the oncoming car, as the rear car, was blamed."""
from __future__ import annotations

import subprocess
import xml.etree.ElementTree as ET

import libsumo
import pytest

from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info
from sumo_rss.rss.formulas import lon_reach
from sumo_rss.sumo_home import sumo_tool

ROAD_NODES = '<nodes><node id="A" x="0" y="0" type="priority"/><node id="C" x="1500" y="0" type="priority"/></nodes>'
ROAD_EDGES = ('<edges><edge id="AC" from="A" to="C" numLanes="1" speed="25"/>'
              '<edge id="CA" from="C" to="A" numLanes="1" speed="25"/></edges>')
ROUTES = ('<routes><vType id="car" length="5" width="1.8" accel="2.6" decel="4.5" sigma="0"/>'
          '<route id="east" edges="AC"/><route id="west" edges="CA"/></routes>')


@pytest.fixture(scope="module")
def head_on(tmp_path_factory):
    """slow (8 m/s) and fast (15 m/s) drive east, onc (20 m/s) west on a two-way road with one lane each way; at
    2 s fast changes into the oncoming lane and stays there; nobody brakes (SUMO: a frontal collision at 10.5 s).
    Returns (network, route file, FCD, FCD without speedLat, collision file)."""
    folder = tmp_path_factory.mktemp("wrong_way")
    (folder / "road.nod.xml").write_text(ROAD_NODES)
    (folder / "road.edg.xml").write_text(ROAD_EDGES)
    net = folder / "road.net.xml"
    subprocess.run([str(sumo_tool("netconvert")), "-n", str(folder / "road.nod.xml"), "-e", str(folder / "road.edg.xml"),
                    "--opposites.guess", "-o", str(net)], check=True, capture_output=True)
    routes, fcd, collisions = folder / "road.rou.xml", folder / "fcd.xml", folder / "collisions.xml"
    routes.write_text(ROUTES)
    libsumo.start(["sumo", "-n", str(net), "-r", str(routes), "--step-length", "0.1", "--lanechange.duration", "3",
                   "--collision.action", "warn", "--collision-output", str(collisions), "--fcd-output", str(fcd),
                   "--fcd-output.attributes", "x,y,angle,speed,pos,lane,posLat,speedLat,acceleration,type",
                   "--no-step-log", "true", "--no-warnings", "true"])
    try:
        for vid, route, pos, speed in (("slow", "east", 300, 8), ("fast", "east", 270, 15),
                                       ("onc", "west", 880, 20)):
            libsumo.vehicle.add(vid, route, typeID="car", departPos=str(pos), departSpeed=str(speed))
            libsumo.vehicle.setSpeedMode(vid, 0)
            libsumo.vehicle.setLaneChangeMode(vid, 0)
            libsumo.vehicle.setSpeed(vid, speed)
        while libsumo.simulation.getTime() < 12.0:
            if abs(libsumo.simulation.getTime() - 2.0) < 1e-6:
                libsumo.vehicle.changeLane("fast", 1, 20.0)  # lane 1: the oncoming lane
            libsumo.simulationStep()
    finally:
        libsumo.close()
    tree = ET.parse(fcd)
    for vehicle in tree.getroot().iter("vehicle"):
        del vehicle.attrib["speedLat"]
    tree.write(folder / "no_speed_lat.xml")
    return RoadNetwork.from_file(net), routes, fcd, folder / "no_speed_lat.xml", collisions


@pytest.mark.parametrize("lateral_speed", ["speedLat", "derived"])
def test_a_head_on_collision_of_an_overtaking_car_is_an_opposite_direction_episode(head_on, lateral_speed):
    network, routes, fcd, no_speed_lat, collisions = head_on
    result = audit_fcd(fcd if lateral_speed == "speedLat" else no_speed_lat, network, ParamResolver(),
                       vehicles=read_vehicle_info(routes, network.path), collisions=collisions)
    assert result.collisions[["collider", "victim", "sumo_type"]].values.tolist() == [["fast", "onc", "frontal"]]
    episode = result.episodes.set_index("episode_key").loc["fast|onc|1"]
    assert (episode.situation, episode.trigger, episode.owed_a, episode.owed_b) == \
        ("opposite-direction", "lon", "lon:brake-min", "lon:brake-correct")
    # Neither brakes, as both owed: both responsible, and the collision is both cars' (it was the oncoming car's).
    assert (episode.responsible, episode.ended_by) == ("both", "collision")
    assert result.collisions.blamed.tolist() == ["fast;onc"]
    # t_b: the gap falls below d_min = [fast at b_min] + [onc in its correct lane at b_corr] (ad_rss preset), the
    # same-direction distance of onc 'behind' fast (76.7 m) no longer counts.
    p = ParamResolver().get("background", "car")
    d_min = float(lon_reach(15.0, p, p.lon_brake_min) + lon_reach(20.0, p, p.lon_brake_min_correct))
    assert d_min == pytest.approx(173.32, abs=0.01)
    gap_at = _bumper_gap(fcd, "fast", "onc")
    assert gap_at[round(episode.t_b_s - 0.1, 1)] >= d_min > gap_at[round(episode.t_b_s, 1)]
    # fast and the car it overtakes: one direction, a lane apart once fast is out (no episode after its change).
    assert result.episodes[result.episodes.vehicle_b == "slow"].t_b_s.max() < 2.0


def _bumper_gap(fcd, a: str, b: str) -> dict[float, float]:
    """[m] by time, the gap between the front bumpers of ``a`` (driving east) and ``b`` (driving west, ahead of
    it) on the east-west road: the FCD's x is the front bumper's."""
    gaps = {}
    for step in ET.parse(fcd).getroot().iter("timestep"):
        x = {v.get("id"): float(v.get("x")) for v in step.iter("vehicle")}
        if a in x and b in x:
            gaps[round(float(step.get("time")), 1)] = x[b] - x[a]
    return gaps
