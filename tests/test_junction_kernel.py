"""The auditor's compiled junction kernel (rss/junction_kernel.py) against the numpy formulas it compiles: on a
random junction (8 links, random conflict areas, static priorities and signal states) and random entries (cars
before, in and past the areas, speeds 0-30 m/s, the presets' and random parameter sets), every pair the kernel
evaluates is the one the numpy path gives (every two entries of two cars that share an area neither has left,
named by id order) with the same priority, kind, rules and margins, to 1e-9. Its entries (the links each car is
on or approaches, and those further along its route) against a vehicle-by-vehicle statement of the rule, on the
DRT fragment's junctions with random positions and routes."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.link_pairs import LinkBlocks, LinkPairs
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.intersection import (JUNCTIONS_AHEAD, KIND_SAME, KIND_SIGNAL, KIND_YIELD, PRIORITY_B, PRIORITY_SAME,
                                       intersection_safety, junction_entries, next_route_edge,
                                       param_table)
from sumo_rss.rss.junction_kernel import CODE_COLUMNS, FLAG_COLUMNS, FLOAT_COLUMNS, INT_COLUMNS, junction_pairs
from sumo_rss.rss.params import PRESETS, RssParamArrays, RssParams, preset_params
from sumo_rss.rss.situations import RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_NO_OVERLAP
from sumo_runs import DATA

LINKS, CARS, ENTRIES = 8, 30, 45
FRAGMENT = DATA / "drt_fragment.net.xml"  # 560 m x 610 m of the DRT city (tests/data/README.md)


def _random_params(rng: np.random.Generator, n: int) -> RssParamArrays:
    presets = [preset_params(p, role) for p in PRESETS for role in ("ego", "background")]
    rows = []
    for k in range(n):
        b_min = rng.uniform(2.0, 6.0)
        rows.append(presets[k % len(presets)] if k % 2 else RssParams(
            response_time=rng.uniform(0.2, 2.0), lon_accel_max=rng.choice([0.0, rng.uniform(0.0, 4.0)]),
            lon_brake_min=b_min, lon_brake_min_correct=b_min - 1.0, lon_brake_max=b_min + rng.uniform(0.0, 4.0),
            min_lon_gap=rng.choice([0.0, 1.0]), max_speed_on_accel=rng.uniform(5.0, 100.0)))
    return RssParamArrays.stack(rows)


def _junction(rng: np.random.Generator) -> dict:
    """A junction's conflict-pair tables (both directions of each area, as JunctionModel.conflict_pairs lists them)."""
    blocks = LinkBlocks.of(["j"] * LINKS)
    index = LinkPairs.full(blocks, -1, int)
    start, end, static = (LinkPairs.full(blocks, 0.0, float), LinkPairs.full(blocks, 0.0, float),
                          LinkPairs.full(blocks, 0, np.int8))
    area = 0
    for a in range(LINKS):
        for b in range(a + 1, LINKS):
            if rng.random() < 0.6:
                sign = int(rng.integers(-1, 2))
                for x, y, s in ((a, b, sign), (b, a, -sign)):
                    begin = rng.uniform(0.0, 15.0)
                    index.set(x, y, area)
                    start.set(x, y, begin)
                    end.set(x, y, begin + rng.uniform(1.0, 6.0))
                    static.set(x, y, s)
                area += 1
    pairs = index.pairs()
    return {"pairs": pairs, "area": index.values[pairs.flat], "start": start.values[pairs.flat],
            "end": end.values[pairs.flat], "static": static.values[pairs.flat],
            "crossing": rng.random(area) < 0.5, "tls_index": np.where(rng.random(LINKS) < 0.7, np.arange(LINKS), -1),
            "ranks": rng.integers(-1, 3, LINKS)}


def _numpy_pairs(j: dict, rows, links, pos, id_rank, length, v, p) -> tuple[np.ndarray, dict]:
    """The kernel's outputs by numpy: every two entries of two cars whose links share an area, neither past it."""
    i, k = np.triu_indices(len(rows), 1)
    pairs = j["pairs"]
    lookup = {(a, b): n for n, (a, b) in enumerate(zip(pairs.link.tolist(), pairs.other.tolist()))}
    number = np.array([lookup.get((a, b), -1) for a, b in zip(links[i].tolist(), links[k].tolist())], dtype=int)
    i, k, number = i[number >= 0], k[number >= 0], number[number >= 0]
    keep = rows[i] != rows[k]
    i, k, number = i[keep], k[keep], number[keep]
    swap = id_rank[rows[i]] > id_rank[rows[k]]
    ea, eb = np.where(swap, k, i), np.where(swap, i, k)
    ka = np.where(swap, pairs.reverse[number], number)
    kb = pairs.reverse[ka]
    ra, rb, la, lb = rows[ea], rows[eb], links[ea], links[eb]
    enter_a, exit_a = j["start"][ka] - pos[ea], j["end"][ka] - pos[ea] + length[ra]
    enter_b, exit_b = j["start"][kb] - pos[eb], j["end"][kb] - pos[eb] + length[rb]
    out = (exit_a > 0.0) & (exit_b > 0.0)
    ra, rb, la, lb, ka, enter_a, exit_a, enter_b, exit_b = (
        x[out] for x in (ra, rb, la, lb, ka, enter_a, exit_a, enter_b, exit_b))
    rank_a, rank_b = j["ranks"][la], j["ranks"][lb]
    by_signal = (rank_a >= 0) & (rank_b >= 0) & (rank_a != rank_b)
    unknown = ((j["tls_index"][la] >= 0) & (rank_a < 0)) | ((j["tls_index"][lb] >= 0) & (rank_b < 0))
    static = np.where(unknown, 0, j["static"][ka])
    priority = np.where(by_signal, np.where(rank_a > rank_b, 1, 2), np.where(static > 0, 1, np.where(static < 0, 2, 0)))
    kind = np.where(by_signal, KIND_SIGNAL, np.where(priority != PRIORITY_SAME, KIND_YIELD, KIND_SAME))
    s = intersection_safety(v[ra], enter_a, exit_a, length[ra], p.take(ra), v[rb], enter_b, exit_b, length[rb],
                            p.take(rb), priority, j["crossing"][j["area"][ka]])
    a_yields = (priority == PRIORITY_B) | ((priority == PRIORITY_SAME) & (enter_a - s.need_a <= enter_b - s.need_b))
    floats = np.array([np.where(a_yields, enter_a, enter_b), v[ra], v[rb], np.where(a_yields, s.need_a, s.need_b),
                       enter_a, enter_b]).reshape(len(FLOAT_COLUMNS), -1)
    rules = s.able_to_stop * RULE_ABLE_TO_STOP + s.in_front * RULE_IN_FRONT + s.no_time_overlap * RULE_NO_OVERLAP
    columns = {"a": ra, "b": rb, "kind": kind, "a_is_rear": ~s.a_in_front, "safe": s.safe, "rules": rules,
               "priority": priority, "in_front": np.where(s.a_in_front, 1, np.where(s.b_in_front, 2, 0)), "pair": ka}
    return floats, {name: np.asarray(x).reshape(-1) for name, x in columns.items()}


@pytest.mark.parametrize("seed", range(6))
def test_the_kernel_gives_the_numpy_formulas_pairs(seed):
    rng = np.random.default_rng(seed)
    j = _junction(rng)
    rows = np.sort(rng.integers(0, CARS, ENTRIES))  # some cars with entries on several links
    links = rng.integers(0, LINKS, ENTRIES)
    pos = rng.uniform(-40.0, 25.0, ENTRIES)
    id_rank = rng.permutation(CARS).astype(np.int64)
    length, v = rng.uniform(3.0, 12.0, CARS), np.where(rng.random(CARS) < 0.2, 0.0, rng.uniform(0.0, 30.0, CARS))
    p = _random_params(rng, CARS)
    pairs = j["pairs"]
    floats, ints, flags, codes = junction_pairs(
        rows, links, pos, id_rank, pairs.indptr, pairs.other, pairs.reverse, j["start"], j["end"], j["static"],
        j["area"], j["crossing"], j["tls_index"], j["ranks"], length, v, param_table(p))
    want_floats, want = _numpy_pairs(j, rows, links, pos, id_rank, length, v, p)
    assert (flags.dtype, codes.dtype) == (np.bool_, np.int8)  # as PairSituations holds them
    got = dict(zip(INT_COLUMNS + FLAG_COLUMNS + CODE_COLUMNS, [*ints, *flags, *codes]))
    assert ints.shape[1] > 20  # the junction gives pairs
    assert set(got) == set(want)
    assert all(np.array_equal(got[name], want[name]) for name in want)
    assert np.allclose(floats, want_floats, rtol=0.0, atol=1e-9)
    # The pairs meet every case: each combination of the three rules holding, and every kind of priority.
    assert set(got["rules"].tolist()) == set(range(8))
    assert set(got["kind"].tolist()) == {KIND_SIGNAL, KIND_YIELD, KIND_SAME}


@pytest.fixture(scope="module")
def fragment() -> tuple[RoadNetwork, JunctionModel]:
    network = RoadNetwork.from_file(FRAGMENT)
    return network, JunctionModel.from_file(FRAGMENT, network)


def _walk(rng: np.random.Generator, lane: int, junctions: JunctionModel, network: RoadNetwork, hops: int) -> list[int]:
    """A route from ``lane``'s edge through ``hops`` junctions, each link chosen at random."""
    route = [int(network.lane_edge[lane])]
    for _ in range(hops):
        links = junctions.lane_links[lane][junctions.lane_links[lane] >= 0]
        if links.size == 0:
            break
        link = int(rng.choice(links))
        route.append(int(junctions.link_to_edge[link]))
        lane = int(junctions.link_to_lane[link])
    return route


def _reference_entries(lane, lane_pos, next_edge, routes, levels, horizon, junctions, network) -> list[tuple]:
    """The entries as junction_entries documents them, vehicle by vehicle in Python."""
    found = [(i, int(junctions.lane_link[l]), junctions.lane_link_offset[l] + p)
             for i, (l, p) in enumerate(zip(lane, lane_pos)) if junctions.lane_link[l] >= 0]
    for i, (l, p) in enumerate(zip(lane, lane_pos)):
        to_end = network.lane_length[l] - p
        found += [(i, int(k), -to_end) for k in junctions.lane_links[l] if k >= 0 and to_end <= horizon and
                  (next_edge[i] < 0 or junctions.link_to_edge[k] == next_edge[i])]
    level = list(found)
    for _ in range(levels):
        further = []
        for i, k, p in level:
            onto = junctions.link_to_lane[k]
            start = (junctions.link_length[k] - p) + network.lane_length[onto]
            route = [e for e in routes[i].tolist() if e >= 0]
            edge = network.lane_edge[onto]
            after = route[route.index(edge) + 1] if edge in route[:-1] else -1
            further += [(i, int(k2), -start) for k2 in junctions.lane_links[onto] if k2 >= 0 and after >= 0 and
                        start <= horizon and junctions.link_to_edge[k2] == after]
        if not further:
            break
        found += further
        level = further
    return found


def test_entries_are_each_vehicles_links_and_those_further_along_its_route(fragment):
    network, junctions = fragment
    rng = np.random.default_rng(11)
    n = 400
    approach = np.flatnonzero((junctions.lane_links >= 0).any(axis=1))
    lane = np.where(rng.random(n) < 0.3, rng.integers(0, len(network.lane_ids), n), rng.choice(approach, n))
    lane_pos = rng.uniform(0.0, 1.0, n) * network.lane_length[lane]
    routes = np.full((n, 6), -1, dtype=np.int64)
    for i in range(n):
        if rng.random() < 0.8:  # the others: route unknown
            route = _walk(rng, int(lane[i]), junctions, network, 5)
            routes[i, :len(route)] = route
    next_edge = next_route_edge(routes, network.lane_edge[lane])
    for levels, horizon in ((0, np.inf), (0, 50.0), (JUNCTIONS_AHEAD, 120.0)):
        rows, links, pos = junction_entries(lane, lane_pos, next_edge, network, junctions, horizon, levels, routes)
        want = _reference_entries(lane, lane_pos, next_edge, routes, levels, horizon, junctions, network)
        assert list(zip(rows.tolist(), links.tolist())) == [(i, k) for i, k, _ in want]
        assert np.array_equal(pos, np.array([p for _, _, p in want]))
        # Without next_edge the kernel finds it on the routes itself (as the auditor calls it): the same entries.
        found = junction_entries(lane, lane_pos, None, network, junctions, horizon, levels, routes)
        assert all(np.array_equal(x, y) for x, y in zip(found, (rows, links, pos)))
        if levels:
            assert len(rows) > len(junction_entries(lane, lane_pos, next_edge, network, junctions, horizon)[0]) + 50


def test_next_route_edge_is_the_edge_after_the_first_occurrence_on_the_route():
    # Routes of 6 edges drawn from 8 (repeats: a route may pass an edge twice), -1 padded; the current edge on the
    # route, twice on it, last on it, not on it, and a route unknown.
    rng = np.random.default_rng(3)
    routes = rng.integers(0, 8, (200, 6))
    routes[rng.random(200) < 0.1] = -1
    routes[:, 4:][rng.random((200, 2)) < 0.3] = -1
    edge = rng.integers(0, 8, 200)
    want = []
    for route, e in zip(routes.tolist(), edge.tolist()):
        at = route[:-1].index(e) if e in route[:-1] else -1
        want.append(route[at + 1] if at >= 0 else -1)
    assert next_route_edge(routes, edge).tolist() == want
    assert {-1, 0}.issubset(set(want)) and len(set(want)) > 5
    assert next_route_edge(np.full((3, 1), 4), np.array([4, 4, 1])).tolist() == [-1, -1, -1]  # one edge: no next
