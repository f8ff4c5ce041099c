"""The road model cache: a second load of a network (its models and topology index) comes from its entry and equals
a fresh build; a changed network, a damaged entry and an entry of other code are rebuilt, never used; the cache can
be moved or turned off."""
from __future__ import annotations

import dataclasses
import os
import shutil

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.road import model_cache, topology
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.road.topology import read_topology
from sumo_rss.rss import signals
from sumo_rss.rss.signals import SignalStates

TLS = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(model_cache.CACHE_ENV, str(folder))
    # The models this process keeps (an earlier test on this worker may have read the same net's signals).
    monkeypatch.setattr(model_cache, "_kept", {})
    return folder


@pytest.fixture
def net_copy(tmp_path):
    path = tmp_path / "net" / "tls.net.xml"
    path.parent.mkdir()
    shutil.copy(TLS, path)
    return path


def _same_network(a: RoadNetwork, b: RoadNetwork) -> bool:
    for f in dataclasses.fields(RoadNetwork):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) and not (np.array_equal(x, y) and x.dtype == y.dtype):
            return False
    return a.lane_successors == b.lane_successors and np.array_equal(a.shapes.points, b.shapes.points) and \
        np.array_equal(a.shapes.cumulative, b.shapes.cumulative)


def _no_build(*_args):
    raise AssertionError("built although cached")


def test_a_second_load_comes_from_the_cache_and_equals_a_fresh_build(cache, net_copy, monkeypatch):
    fresh, fresh_states = RoadNetwork.build(TLS), SignalStates(TLS).states(12.0)
    first = RoadNetwork.from_file(net_copy)
    junctions = JunctionModel.from_file(net_copy, first)
    SignalStates(net_copy)
    index = read_topology(net_copy)
    assert sorted(p.name.split("-")[0] for p in cache.iterdir()) == ["junctions", "network", "signals", "topology"]
    monkeypatch.setattr(RoadNetwork, "build", classmethod(_no_build))
    monkeypatch.setattr(JunctionModel, "build", classmethod(_no_build))
    monkeypatch.setattr(signals, "signal_programs", _no_build)
    monkeypatch.setattr(topology, "_parse_topology", _no_build)
    topology._read_topology.cache_clear()  # as in a new process
    assert read_topology(net_copy) == index and index.signals and index.lane_links
    again = RoadNetwork.from_file(net_copy)
    assert again.path == net_copy and _same_network(again, fresh)
    assert JunctionModel.from_file(net_copy, again).conflicts == junctions.conflicts
    assert SignalStates(net_copy).states(12.0) == fresh_states
    # What distances were searched is not kept: a cached model starts with none.
    first.require_reach(500.0)
    assert RoadNetwork.from_file(net_copy).edge_reach.horizon == 0.0


def test_a_changed_network_is_built_again(cache, net_copy):
    before = RoadNetwork.from_file(net_copy)
    text = net_copy.read_text()
    net_copy.write_text(text.replace('speed="13.89"', 'speed="8.33"'))
    after = RoadNetwork.from_file(net_copy)
    lane = int(before.lane_indices(["N_in_0"])[0])
    assert (before.lane_speed[lane], after.lane_speed[lane]) == (13.89, 8.33)
    assert len(list(cache.glob("network-*"))) == 2  # one entry per content


@pytest.mark.parametrize("damage", ["truncate", "flip", "header", "other code"])
def test_a_damaged_or_foreign_entry_is_rebuilt_never_used(cache, net_copy, damage):
    RoadNetwork.from_file(net_copy)
    (entry,) = cache.glob("network-*")
    data = entry.read_bytes()
    head_end = data.index(b"\n", len(model_cache.MAGIC))
    if damage == "truncate":
        entry.write_bytes(data[: len(data) // 2])
    elif damage == "flip":  # one byte of the payload: its hash no longer matches
        entry.write_bytes(data[:-10] + bytes([data[-10] ^ 0xFF]) + data[-9:])
    elif damage == "header":
        entry.write_bytes(b"garbage" + data)
    else:  # an entry written by other code (or an older format): same payload, another fingerprint
        entry.write_bytes(data[:head_end].replace(model_cache.code_fingerprint().encode(), b"0" * 64) +
                          data[head_end:])
    rebuilt = RoadNetwork.from_file(net_copy)
    assert _same_network(rebuilt, RoadNetwork.build(TLS))
    assert entry.read_bytes() == data  # and the entry is whole again


def test_the_cache_can_be_turned_off_or_be_unwritable(tmp_path, net_copy, monkeypatch):
    monkeypatch.setenv(model_cache.CACHE_ENV, "off")
    assert model_cache.cache_dir() is None
    RoadNetwork.from_file(net_copy)
    monkeypatch.delenv(model_cache.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert model_cache.cache_dir() == tmp_path / "xdg" / "sumo_rss"
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the folder should be")
    monkeypatch.setenv(model_cache.CACHE_ENV, str(blocked / "cache"))
    monkeypatch.setattr(model_cache, "_warned_unwritable", False)
    with pytest.warns(UserWarning, match="cannot write the road model cache"):
        network = RoadNetwork.from_file(net_copy)
    assert _same_network(network, RoadNetwork.build(TLS))
    assert os.listdir(tmp_path / "net") == ["tls.net.xml"]  # nothing written beside the network instead
