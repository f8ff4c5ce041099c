"""Junction model of the shipped nets: links, conflict areas and right of way from SUMO's junction logic."""
from __future__ import annotations

import pytest

from conftest import NETWORKS
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork


def _model(name: str) -> tuple[RoadNetwork, JunctionModel]:
    path = NETWORKS / name / f"{name}.net.xml"
    network = RoadNetwork.from_file(path)
    return network, JunctionModel.from_file(path, network)


def _edge(network: RoadNetwork, lane: int) -> str:
    return str(network.edge_ids[network.lane_edge[lane]])


def test_signalised_crossing_links_and_signal_indices():
    network, model = _model("intersection_tls")
    assert len(model.links) == 12
    assert [link.tls_index for link in model.links] == list(range(12)) and {link.tls for link in model.links} == {"C"}
    left_turns = [link for link in model.links if link.direction == "l"]
    assert len(left_turns) == 4 and all(len(link.path) == 2 for link in left_turns)  # via the waiting position
    for link in model.links:
        for offset_lane in link.path:
            assert model.link_of_lane[offset_lane][0] == model.links.index(link)


def test_conflict_areas_lie_on_both_paths_and_follow_sumo_priority():
    network, model = _model("intersection_tls")
    assert len(model.conflicts) >= 16
    for c in model.conflicts:
        a, b = model.links[c.link_a], model.links[c.link_b]
        assert 0.0 <= c.a_start < c.a_end <= a.length + 1e-6 and 0.0 <= c.b_start < c.b_end <= b.length + 1e-6
        assert (c.kind == "merging") == (a.to_lane == b.to_lane)
    # A permissive left turn yields to the oncoming straight traffic: N straight (link 1) over S left (link 8).
    (c,) = [c for c in model.conflicts if c.id == "C:1x8"]
    assert c.kind == "crossing" and c.static_priority == "a"
    # Crossing straight movements (N straight x E straight) conflict in the middle of both paths.
    (c,) = [c for c in model.conflicts if c.id == "C:1x4"]
    a, b = model.links[c.link_a], model.links[c.link_b]
    assert 0.2 * a.length < c.a_start < c.a_end < 0.8 * a.length and 0.2 * b.length < c.b_start < c.b_end < 0.8 * b.length


def test_minor_road_yields_to_the_major_road_at_the_priority_junction():
    network, model = _model("intersection_priority")
    major = {"W_in", "E_in"}
    mixed = 0
    for c in model.conflicts:
        a, b = model.links[c.link_a], model.links[c.link_b]
        a_major, b_major = _edge(network, a.from_lane) in major, _edge(network, b.from_lane) in major
        if a_major != b_major:
            mixed += 1
            assert c.static_priority == ("a" if a_major else "b"), c.id
    assert mixed >= 12


@pytest.mark.parametrize("name", ["highway", "merge"])
def test_roads_without_foe_links_have_no_conflict_areas(name):
    _, model = _model(name)
    assert model.links and model.conflicts == ()
