"""The real-network invariants (real_network_checks.py) on a Monaco-size run: MoST's 18,732-edge net, 300 s of
random trips (500 cars, 300 pedestrians), audited from SUMO's own FCD, collision and signal-state outputs.

Runs only with SUMO_RSS_ACCEPTANCE=1 (``make acceptance``) and reads the run from ``$SUMO_RSS_REALNETS`` (default
/work/realnets: most.net.xml, most.rou.xml, most.fcd.xml, most.collisions.xml, most.tls.xml, built from a MoST
checkout by ``python bench/build_most.py MOST_CHECKOUT FOLDER``, which says how); skips, naming what is missing,
where it is not there. Nothing of it is in the repository (fetched data is never committed).
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest

import real_network_checks as checks
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info

FOLDER = Path(os.environ.get("SUMO_RSS_REALNETS", "/work/realnets"))
FILES = ("most.net.xml", "most.rou.xml", "most.fcd.xml", "most.collisions.xml", "most.tls.xml")

pytestmark = pytest.mark.skipif(os.environ.get("SUMO_RSS_ACCEPTANCE") != "1",
                                reason="Monaco-size audit (minutes): set SUMO_RSS_ACCEPTANCE=1 (make acceptance)")


@pytest.fixture(scope="module")
def most():
    missing = [name for name in FILES if not (FOLDER / name).is_file()]
    if missing:
        pytest.skip(f"{FOLDER}: no MoST run ({', '.join(missing)} missing; bench/build_most.py builds it; set "
                    "SUMO_RSS_REALNETS to its folder)")
    net_file, routes, fcd, collisions, tls = (FOLDER / name for name in FILES)
    vehicles = read_vehicle_info(routes, net_file)
    net = RoadNetwork.from_file(net_file)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        result = audit_fcd(fcd, net, ParamResolver(vtype_dynamics=vehicles.dynamics), vehicles=vehicles,
                           collisions=collisions, tls_states=tls, trace_class="background")
    return result, checks.FcdTable(fcd, vehicles), net


def test_monaco_opposite_pairs_are_one_road(most):
    result, fcd, net = most
    assert (result.episodes.situation == "opposite-direction").any()
    assert checks.opposite_pairs_beyond_a_lane(result, fcd, net) == []


def test_monaco_no_deep_lateral_overlap_apart(most):
    result, fcd, net = most
    assert checks.deep_lateral_overlaps_apart(result, fcd, net) == []


def test_monaco_collisions_have_episodes(most):
    result, fcd, _ = most
    assert checks.collisions_without_an_episode(result, fcd) == []


def test_monaco_no_blamed_car_stopped_short(most):
    result, fcd, _ = most
    assert checks.blamed_cars_that_stopped_short(result, fcd) == []
