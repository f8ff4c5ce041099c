"""Distances along the edge and lane graphs within a horizon: hand-worked on the highway, and on a city network
equal to an all-pairs Dijkstra (scipy) wherever the target starts within the horizon beyond the source's end;
the road model holds nothing that grows with the square of the network."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from conftest import NETWORKS
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.link_pairs import LinkPairs
from sumo_rss.road.network import RoadNetwork
from sumo_rss.road.reach import HORIZON_STEP_M, GraphReach
from sumo_rss.sumo_home import sumo_home

CITY = sumo_home() / "tools" / "game" / "DRT" / "osm.net.xml"  # 8,109 edges, 11,087 lanes


@pytest.fixture(scope="module")
def city() -> RoadNetwork:
    return RoadNetwork.from_file(CITY)


def test_highway_distances_run_from_edge_start_to_edge_start():
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    hw = net.edge_indices(["hw0", "hw1", "hw2"])
    internal = [int(net.edge_successors[e][0]) for e in hw[:2]]  # the junction edge after hw0 and after hw1
    assert all(net.edge_internal[internal])
    net.require_reach(5.0)  # reaches the edges that start within 5 m beyond the source's end: the junction edges
    assert net.edge_reach.horizon == HORIZON_STEP_M  # grown a quarter beyond, to a multiple of 50 m
    length = net.edge_length
    found = net.edge_distances(np.array([hw[0], hw[0], hw[0], hw[1], hw[2]]),
                               np.array([hw[0], internal[0], hw[1], hw[0], hw[0]]))
    assert found.tolist() == [0.0, length[hw[0]], length[hw[0]] + length[internal[0]], np.inf, np.inf]
    assert np.isinf(net.edge_distances(hw[:1], hw[2:]))[0]  # hw2 starts ~1 km beyond the end of hw0
    net.require_reach(3000.0)
    assert net.edge_distances(hw[:1], hw[2:])[0] == \
        length[hw[0]] + length[internal[0]] + length[hw[1]] + length[internal[1]]
    # Lanes: hw0_0 (899.87 m), its junction lane (0.3 m), hw1_0 (874.61 m), the next junction lane, hw2_0; hw0_1 leads
    # on to hw2_1, never to hw2_0, without changing lanes.
    lanes = net.lane_indices(np.array(["hw0_0", "hw0_1", "hw2_0"]))
    assert net.lane_distances(lanes[:2], lanes[[2, 2]]).tolist() == [899.87 + 0.3 + 874.61 + 0.3, np.inf]
    assert net.lane_ids[net.downstream_lanes(int(lanes[0]))].tolist() == [":h1_0_0", ":h2_0_0", "hw0_0", "hw1_0",
                                                                          "hw2_0"]


@pytest.mark.parametrize("horizon, share", [(0.0, 0.001), (120.0, 0.05), (700.0, 0.8)])
def test_city_distances_are_those_of_an_all_pairs_search_within_the_horizon(city, horizon, share):
    net = city
    n = len(net.edge_ids)
    rows = np.repeat(np.arange(n), [len(s) for s in net.edge_successors])
    cols = np.concatenate([np.asarray(s, dtype=int) for s in net.edge_successors])
    graph = csr_matrix((net.edge_length[rows], (rows, cols)), shape=(n, n))
    sources = np.random.default_rng(5).choice(n, 60, replace=False)
    exact = dijkstra(graph, indices=sources)  # [60, n]
    reach = GraphReach(net.edge_successors, net.edge_length)
    reach.require(horizon)
    found = reach.between(np.repeat(sources, n), np.tile(np.arange(n), len(sources))).reshape(len(sources), n)
    within = exact <= net.edge_length[sources][:, None] + horizon
    assert np.array_equal(np.isfinite(found), within)
    assert np.allclose(found[within], exact[within], rtol=1e-12, atol=0.0)
    assert 0 < within.sum() < share * within.size  # a horizon, not the whole city
    # What a step looks up depends on its own reach, not on how far an earlier step searched.
    searched_farther = GraphReach(net.edge_successors, net.edge_length)
    searched_farther.require(1000.0)
    searched_farther.between(sources, sources)
    searched_farther.require(horizon)
    assert searched_farther.horizon > reach.horizon
    assert np.array_equal(searched_farther.between(np.repeat(sources, n), np.tile(np.arange(n), len(sources))
                                                   ).reshape(len(sources), n), found)
    assert all(np.array_equal(a, b) for s in sources[:5].tolist()
               for a, b in zip(searched_farther.row(s), reach.row(s)))


def test_the_models_hold_nothing_that_grows_with_the_square_of_the_network(city):
    edges, lanes = len(city.edge_ids), len(city.lane_ids)
    junctions = JunctionModel.from_file(CITY, city)
    links = len(junctions.links)
    arrays = [v for v in vars(city).values() if isinstance(v, np.ndarray)] + \
        [city.shapes.points, city.shapes.cumulative] + \
        [v for v in vars(junctions).values() if isinstance(v, np.ndarray)] + \
        [v.values for v in vars(junctions).values() if isinstance(v, LinkPairs)]
    assert max(a.size for a in arrays) < 0.02 * min(edges, lanes) ** 2  # the largest: the padded lane shapes
    # A dense table of link pairs would be links² entries: the junction blocks are far fewer.
    assert junctions.area_index.values.size < 0.05 * links ** 2
    assert junctions.area_index.shape == (links, links)


def _joined_offset_reference(net: RoadNetwork, lane: int, ref: int) -> float:
    """The rule of ``situations._joined_offset`` for one lane pair, stated lane by lane: of the lanes ``lane`` leads on
    to (``downstream_lanes``, in lane order) on ``ref``'s edge, the offset from ``ref`` of the first nearest."""
    best = np.nan
    for reached in net.downstream_lanes(lane).tolist():
        if net.lane_edge[reached] == net.lane_edge[ref]:
            offset = net.lane_offset[reached] - net.lane_offset[ref]
            if np.isnan(best) or abs(offset) < abs(best):
                best = offset
    return best


def test_city_joined_offsets_are_those_of_the_lane_by_lane_rule(city):
    from sumo_rss.rss.situations import _joined_offset

    net = city
    net.require_reach(120.0)
    rng = np.random.default_rng(11)
    lanes = rng.choice(len(net.lane_ids), 300)
    # The reference lanes: mostly lanes these lead on to (a lane of their edge, beside it), some anywhere.
    refs = []
    for lane in lanes.tolist():
        reached = net.downstream_lanes(lane)
        edge = net.lane_edge[int(rng.choice(reached))]
        on_edge = np.flatnonzero(net.lane_edge == edge)
        refs.append(int(rng.choice(on_edge)) if rng.random() < 0.8 else int(rng.integers(len(net.lane_ids))))
    refs = np.array(refs)
    found = _joined_offset(net, lanes, refs)
    want = np.array([_joined_offset_reference(net, a, b) for a, b in zip(lanes.tolist(), refs.tolist())])
    assert np.array_equal(found, want, equal_nan=True)
    assert 100 < np.isfinite(want).sum() < len(want)  # both answers are asked
    assert (np.abs(want[np.isfinite(want)]) > 0).any()  # and lanes beside the reference lane
