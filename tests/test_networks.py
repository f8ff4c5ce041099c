"""The shipped networks: rebuilt by netconvert they equal the committed files, and each has the geometry and
junction logic its scenarios rely on."""
from __future__ import annotations

import math
import shutil
import subprocess
import sys

import numpy as np
import pytest
import sumolib

from conftest import NETWORKS
from sumo_rss.road.build import build_network, network_dirs, without_generator_header
from sumo_rss.road.network import RoadNetwork
from sumo_rss.sumo_home import sumo_tool

NAMES = ["highway", "highway_exit", "merge", "intersection_tls", "intersection_tls_peds", "intersection_priority",
         "intersection_occluded"]


def _net(name: str) -> sumolib.net.Net:
    return sumolib.net.readNet(str(NETWORKS / name / f"{name}.net.xml"), withInternal=True, withPrograms=True)


def test_every_network_is_shipped():
    assert [d.name for d in network_dirs(NETWORKS)] == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_rebuild_equals_committed_net(tmp_path, name):
    fresh = build_network(NETWORKS / name, tmp_path / f"{name}.net.xml").read_text(encoding="utf-8")
    committed = (NETWORKS / name / f"{name}.net.xml").read_text(encoding="utf-8")
    assert "generated on" in committed[:300]  # the header that is ignored
    assert without_generator_header(fresh) == without_generator_header(committed)


def test_highway_three_lanes_over_two_km_with_one_gentle_curve():
    net = _net("highway")
    edges = [net.getEdge(e) for e in ("hw0", "hw1", "hw2")]
    assert all(e.getLaneNumber() == 3 for e in edges)
    assert all(abs(lane.getSpeed() - 33.33) < 1e-9 for e in edges for lane in e.getLanes())
    assert sum(e.getLength() for e in edges) >= 2000.0
    # Straight, a 25° curve of radius 2000 m (873 m long), straight.
    def heading(lane_id: str) -> float:
        (ax, ay), (bx, by) = net.getLane(lane_id).getShape()  # exactly two points: straight
        return math.degrees(math.atan2(by - ay, bx - ax))

    assert heading("hw2_1") - heading("hw0_1") == pytest.approx(25.0, abs=0.01)
    assert net.getEdge("hw1").getLength() == pytest.approx(2000.0 * math.radians(25.0), rel=0.01)


def test_lanes_beside_a_dead_ends_turnaround_do_not_end(tmp_path):
    """netconvert's default turnaround at a dead end connects only the leftmost lane to the opposite edge; the
    other lanes lead nowhere there but do not end as an acceleration lane does (every pair of cars beside each other
    on them was audited as a merge). The merge's acceleration lane still ends."""
    (tmp_path / "r.nod.xml").write_text('<nodes><node id="A" x="0" y="0"/><node id="C" x="2000" y="0"/></nodes>')
    (tmp_path / "r.edg.xml").write_text('<edges><edge id="AC" from="A" to="C" numLanes="2" speed="25"/>'
                                        '<edge id="CA" from="C" to="A" numLanes="2" speed="25"/></edges>')
    subprocess.run([str(sumo_tool("netconvert")), "-n", str(tmp_path / "r.nod.xml"), "-e", str(tmp_path / "r.edg.xml"),
                    "-o", str(tmp_path / "r.net.xml")], check=True, capture_output=True)
    road = RoadNetwork.from_file(tmp_path / "r.net.xml")
    turnarounds = sumolib.net.readNet(str(tmp_path / "r.net.xml")).getLane("AC_1").getOutgoing()
    assert [c.getDirection() for c in turnarounds] == ["t"]  # the network has what this test is about
    assert not road.lane_ends.any()
    merge = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    assert merge.lane_ids[merge.lane_ends].tolist() == ["mw_merge_0"]


def test_merge_acceleration_lane_ends_and_ramp_feeds_it():
    net = _net("merge")
    merge_edge = net.getEdge("mw_merge")
    assert merge_edge.getLaneNumber() == 3 and net.getEdge("mw_in").getLaneNumber() == 2
    assert net.getEdge("mw_out").getLaneNumber() == 2 and net.getEdge("ramp").getLaneNumber() == 1
    accel_lane = net.getLane("mw_merge_0")
    assert accel_lane.getLength() >= 200.0
    assert accel_lane.getOutgoing() == []  # the acceleration lane ends
    assert [lane.getID() for lane in accel_lane.getIncoming() if not lane.getID().startswith(":")] == ["ramp_0"]
    assert {c.getToLane().getID() for c in net.getLane("mw_merge_1").getOutgoing()} == {"mw_out_0"}


def test_exit_deceleration_lane_is_reached_by_a_lane_change_and_leads_only_onto_the_ramp():
    net = _net("highway_exit")
    assert [net.getEdge(e).getLaneNumber() for e in ("ex_in", "ex_decel", "ex_main", "ex_ramp")] == [3, 4, 3, 1]
    decel = net.getLane("ex_decel_0")
    assert decel.getLength() >= 200.0 and decel.getSpeed() == pytest.approx(22.22)
    assert decel.getIncoming() == []  # entered only by a lane change from ex_decel_1
    assert {c.getToLane().getID() for c in decel.getOutgoing()} == {"ex_ramp_0"}
    for k in (1, 2, 3):  # the motorway lanes go straight on, and never onto the ramp
        assert {c.getToLane().getID() for c in net.getLane(f"ex_decel_{k}").getOutgoing()} == {f"ex_main_{k - 1}"}
    assert {c.getToLane().getID() for c in net.getLane("ex_in_0").getOutgoing()} == {"ex_decel_1"}


def test_tls_intersection_has_left_turn_lanes_and_protected_and_permissive_phases():
    net = _net("intersection_tls")
    for arm in "NESW":
        edge = net.getEdge(f"{arm}_in")
        assert edge.getLaneNumber() == 2
        left_lane = edge.getLane(1)
        assert {c.getDirection() for c in left_lane.getOutgoing()} == {"l"}
        assert {c.getDirection() for c in edge.getLane(0).getOutgoing()} == {"s", "r"}
    tls = net.getTLS("C")
    (program,) = tls.getPrograms().values()
    assert program.getType() == "static"
    states = [p.state for p in program.getPhases()]
    left_links = [c[2] for c in tls.getConnections() if c[0].getOutgoing() and c[0].getIndex() == 1]
    assert left_links and len(left_links) == 4
    assert any(any(s[i] == "G" for i in left_links) for s in states)  # protected left
    assert any(any(s[i] == "g" for i in left_links) for s in states)  # permissive left


def test_priority_intersection_minor_approaches_must_stop():
    net = _net("intersection_priority")
    node = net.getNode("J")
    assert node.getType() == "priority_stop"
    for edge_id, must_stop in (("N_in", True), ("S_in", True), ("W_in", False), ("E_in", False)):
        states = {c.getState() for c in net.getEdge(edge_id).getLane(0).getOutgoing()}
        assert (states == {"s"}) == must_stop, (edge_id, states)


def test_occluded_intersection_has_four_corner_buildings_clear_of_every_lane():
    """The minor approaches yield without stopping; the four buildings (rule 4's occluders) stand off every lane,
    internal lanes included (no lane point within 0.5 m of one), and one sits in each quadrant."""
    from sumo_rss.rss.occlusion import read_occluders

    net = _net("intersection_occluded")
    assert net.getNode("J").getType() == "priority"
    for edge_id, yields in (("N_in", True), ("S_in", True), ("W_in", False), ("E_in", False)):
        states = {c.getState() for c in net.getEdge(edge_id).getLane(0).getOutgoing()}
        assert ("M" not in states) == yields, (edge_id, states)
    buildings = read_occluders([NETWORKS / "intersection_occluded" / "intersection_occluded.poly.xml"])
    assert buildings.count == 4
    quadrants = {(np.sign(x), np.sign(y)) for x, y in zip(buildings.x0, buildings.y0)}
    assert quadrants == {(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)}
    low = np.minimum(np.abs(buildings.x0), np.abs(buildings.y0)).min()
    for edge in net.getEdges(withInternal=True):
        for lane in edge.getLanes():
            points = np.array(lane.getShape())
            inside = (np.abs(points[:, 0]) > low - 0.5 - lane.getWidth() / 2) & \
                (np.abs(points[:, 1]) > low - 0.5 - lane.getWidth() / 2)
            assert not inside.any(), lane.getID()


def test_nets_check_reports_every_network_and_netconvert_errors_in_one_line(tmp_path):
    root = tmp_path / "nets"
    shutil.copytree(NETWORKS, root)
    (root / "merge" / "merge.con.xml").unlink()  # netconvert refuses the merge
    edges = root / "highway" / "highway.edg.xml"
    edges.write_text(edges.read_text().replace('speed="33.33"', 'speed="30.00"'))  # the highway is stale
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "nets", "check", "--root", str(root)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 2
    assert proc.stdout.splitlines() == ["highway: STALE (run: sumo-rss nets build)", "highway_exit: up to date",
                                        "intersection_occluded: up to date", "intersection_priority: up to date",
                                        "intersection_tls: up to date", "intersection_tls_peds: up to date"]
    assert proc.stderr.splitlines() == [f"sumo-rss: error: netconvert failed for {root / 'merge' / 'merge.netccfg'}: "
                                        "Error: Could not open connections-file 'merge.con.xml'. Quitting (on error)."]


def test_nets_check_names_a_misspelt_source_attribute_and_a_missing_net(tmp_path):
    """The sources declare SUMO's schemas, so netconvert validates them: numLane= for numLanes= built a one-lane
    hw0 without a word (and where the typo repeated a default, 'check' said up to date). A deleted net.xml was an
    OSError that stopped the check before the other networks."""
    root = tmp_path / "nets"
    shutil.copytree(NETWORKS, root)
    edges = root / "highway" / "highway.edg.xml"
    edges.write_text(edges.read_text().replace('numLanes="3"', 'numLane="3"', 1))
    (root / "intersection_tls" / "intersection_tls.net.xml").unlink()
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "nets", "check", "--root", str(root)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 2
    assert proc.stdout.splitlines() == ["highway_exit: up to date", "intersection_occluded: up to date",
                                        "intersection_priority: up to date",
                                        "intersection_tls: MISSING intersection_tls.net.xml (run: sumo-rss nets build)",
                                        "intersection_tls_peds: up to date", "merge: up to date"]
    assert "Error: attribute 'numLane' is not declared for element 'edge' In file 'highway.edg.xml'" in proc.stderr


def test_frenet_takes_lane_ids_or_indices_and_names_unknown_lanes():
    """hw0 runs along +x with its left border at y = 0 and 3.5 m lanes: lane 1's centre is y = −5.25 m."""
    import numpy as np

    from sumo_rss.road.network import RoadNetwork, UnknownLaneError

    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    x, y = np.array([100.0, 200.0]), np.array([-5.25, -4.25])
    by_id = net.frenet(np.array(["hw0_1", "hw0_1"]), x, y)
    by_index = net.frenet(net.lane_indices(["hw0_1", "hw0_1"]), x, y)
    for a, b in zip(by_id, by_index):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(by_id[1], [0.0, 1.0], atol=1e-9)
    with pytest.raises(UnknownLaneError, match="hw9_0"):
        net.frenet(np.array(["hw9_0"]), x[:1], y[:1])

