"""The per-network tables the junction situations gather from each step, on eclipse-sumo's DRT city (3,703
junction links, 5,459 conflict areas, 21 signals): the list of conflicting link pairs against the conflict areas,
the entry pairs found through it against every pair of entries, and the signal ranks against each link's own
state."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.road.junctions import SIGNAL_RANK, JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.junction_kernel import conflicting_entries
from sumo_rss.sumo_home import sumo_home

CITY = sumo_home() / "tools" / "game" / "DRT" / "osm.net.xml"


@pytest.fixture(scope="module")
def junctions() -> JunctionModel:
    return JunctionModel.from_file(CITY, RoadNetwork.from_file(CITY))


def test_the_conflicting_pairs_are_both_directions_of_every_conflict_area(junctions):
    table = junctions.conflict_pairs
    pairs, n = table.pairs, len(junctions.links)
    sign = {"a": 1, "b": -1, "same": 0}
    expected = sorted([(c.link_a, c.link_b, m, c.a_start, c.a_end, sign[c.static_priority], c.id)
                       for m, c in enumerate(junctions.conflicts)] +
                      [(c.link_b, c.link_a, m, c.b_start, c.b_end, -sign[c.static_priority], c.id)
                       for m, c in enumerate(junctions.conflicts)])
    assert len(pairs) == len(expected) == 2 * len(junctions.conflicts) > 1000
    got = list(zip(pairs.link.tolist(), pairs.other.tolist(), table.area.tolist(), table.start.tolist(),
                   table.end.tolist(), table.static_priority.tolist(), table.area_id.tolist()))
    assert got == expected  # in (a, b) order
    assert np.array_equal(pairs.indptr, np.searchsorted(pairs.link, np.arange(n + 1)))
    assert np.array_equal(junctions.area_index[pairs.link, pairs.other], table.area)
    assert np.array_equal(pairs.link[pairs.reverse], pairs.other) and np.array_equal(pairs.other[pairs.reverse],
                                                                                       pairs.link)


def test_entry_pairs_are_those_of_every_pair_of_entries_in_the_same_order(junctions):
    rng = np.random.default_rng(3)
    # The links of the three junctions with the most conflicts (several entries on some links), and links of any
    # junction.
    junction = junctions.area_index.blocks.junction
    busiest = np.argsort(np.bincount(junction[junctions.conflict_pairs.pairs.link]))[-3:]
    crowded = np.flatnonzero(np.isin(junction, busiest))
    for size in (0, 1, 5, 40, 300):
        links = np.concatenate([rng.choice(crowded, size), rng.integers(0, len(junctions.links), size // 3)])
        pairs = junctions.conflict_pairs.pairs
        i, j, k = conflicting_entries(links, pairs.indptr, pairs.other)
        ti, tj = np.triu_indices(len(links), 1)
        share = junctions.area_index[links[ti], links[tj]] >= 0
        assert i.tolist() == ti[share].tolist() and j.tolist() == tj[share].tolist()
        assert np.array_equal(junctions.conflict_pairs.area[k], junctions.area_index[links[i], links[j]])
        if size >= 40:
            assert len(i) > size  # the test sees pairs


def test_signal_ranks_read_each_links_state_character(junctions):
    signals = sorted({link.tls for link in junctions.links if link.tls})
    assert len(signals) >= 5
    rng = np.random.default_rng(5)
    size = {s: 1 + max(link.tls_index for link in junctions.links if link.tls == s) for s in signals}
    states = {s: "".join(rng.choice(list("GgyrusoO"), size[s])) for s in signals}
    states[signals[0]] = states[signals[0]][:-2]  # too short: its last links' states are unknown
    del states[signals[1]]  # not reported: unknown
    states["not-a-signal"] = "GGG"
    ranks = junctions.signal_ranks(states)
    for k, link in enumerate(junctions.links):
        state = states.get(link.tls) if link.tls else None
        known = state is not None and 0 <= link.tls_index < len(state)  # SUMO gives some signalised links -1
        assert ranks[k] == (SIGNAL_RANK.get(state[link.tls_index], 0) if known else -1), (k, link.tls)
    assert {-1, 0, 1, 2} <= set(ranks.tolist())
    assert (junctions.signal_ranks(None) == -1).all() and (junctions.signal_ranks({}) == -1).all()
