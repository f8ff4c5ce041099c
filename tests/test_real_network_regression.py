"""A real city network run with SUMO and audited: invariants that hold on any network (issue 46).

tests/data/drt_fragment.net.xml (a 560 m x 610 m cut of eclipse-sumo's DRT net, OSM: 161 edges, 6 actuated signals,
two-way streets, a divided road, curves; tests/data/README.md), random trips for 90 s (seed 7, one every 0.7 s), SUMO
as docs/rss.md says (--lanechange.duration 3 --collision.check-junctions, signal states saved), written with
--precision 6 and 2. The checks are in real_network_checks.py (also run on Monaco by test_real_networks_acceptance).
"""
from __future__ import annotations

import subprocess
import sys
import warnings

import pytest

import real_network_checks as checks
from sumo_runs import DATA
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info
from sumo_rss.sumo_home import sumo_home, sumo_tool

NET = DATA / "drt_fragment.net.xml"
SECONDS, SEED = 90, 7


@pytest.fixture(scope="module")
def city(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("city")
    routes = folder / "trips.rou.xml"
    subprocess.run([sys.executable, str(sumo_home() / "tools" / "randomTrips.py"), "-n", str(NET), "-o",
                    str(folder / "trips.xml"), "-r", str(routes), "--seed", str(SEED), "-b", "0", "-e", str(SECONDS),
                    "-p", "0.7", "--validate", "--fringe-factor", "5"], check=True, capture_output=True,
                   env={"SUMO_HOME": str(sumo_home()), "PATH": str(sumo_tool("sumo").parent)})
    vehicles = read_vehicle_info(routes, NET)
    runs = {}
    for precision in (6, 2):
        out = folder / f"p{precision}"
        out.mkdir()
        (out / "tls.add.xml").write_text(f'<additional><timedEvent type="SaveTLSStates" dest="{out / "tls.xml"}"/>'
                                         '</additional>')
        subprocess.run([str(sumo_tool("sumo")), "-n", str(NET), "-r", str(routes), "-a", str(out / "tls.add.xml"),
                        "--step-length", "0.1", "--lanechange.duration", "3", "--precision", str(precision),
                        "--collision.action", "warn", "--collision.check-junctions", "--collision-output",
                        str(out / "collisions.xml"), "--fcd-output", str(out / "fcd.xml"), "--end", str(SECONDS),
                        "--seed", str(SEED), "--no-step-log", "--no-warnings"], check=True, capture_output=True)
        with warnings.catch_warnings():  # at 2 decimals: the audit says how it reads rounded positions
            warnings.simplefilter("ignore", UserWarning)
            result = audit_fcd(out / "fcd.xml", RoadNetwork.from_file(NET), ParamResolver(vtype_dynamics=vehicles.dynamics),
                               vehicles=vehicles, collisions=out / "collisions.xml", tls_states=out / "tls.xml",
                               trace_class="background")
        runs[precision] = (result, checks.FcdTable(out / "fcd.xml", vehicles) if precision == 6 else None)
    return runs


@pytest.fixture(scope="module")
def net() -> RoadNetwork:
    return RoadNetwork.from_file(NET)


def test_the_run_has_what_the_invariants_are_about(city):
    result, fcd = city[6]
    situations = set(result.episodes.situation)
    assert {"same-direction", "opposite-direction", "intersection-yield", "intersection-priority"} <= situations
    assert len(result.collisions) >= 1 and len(fcd.ids) > 100
    assert (result.episodes.situation == "opposite-direction").sum() >= 1
    assert (result.episodes.situation.str.startswith("intersection") & (result.episodes.responsible != "none")).any()


def test_no_opposite_direction_pair_between_edges_more_than_a_lane_apart(city, net):
    result, fcd = city[6]
    assert checks.opposite_pairs_beyond_a_lane(result, fcd, net) == []


def test_no_lateral_overlap_deeper_than_the_bodies_without_an_overlap_in_the_fcd(city, net):
    """(A car SUMO turns 30° against its lane while it changes lanes at walking pace takes 2.7 m of the lane's width,
    not 1.8 m: the half widths are the bodies' across their lanes at SUMO's angles.)"""
    result, fcd = city[6]
    deep = result.pair_states[result.pair_states.lat_gap_m < -2.8]
    assert len(deep) < 0.05 * len(result.pair_states)
    assert checks.deep_lateral_overlaps_apart(result, fcd, net) == []


def test_every_collision_between_audited_cars_is_in_an_episode_open_within_the_second_before_it(city):
    result, fcd = city[6]
    assert checks.collisions_without_an_episode(result, fcd) == []


def test_no_blamed_car_stopped_before_its_conflict_area(city):
    result, fcd = city[6]
    assert checks.blamed_cars_that_stopped_short(result, fcd) == []


def test_episode_and_violation_counts_are_stable_across_the_fcd_precision(city):
    """The same run written with 6 and with 2 decimals (positions to the cm, speeds to the cm/s): episodes, violations
    and blamed episodes agree within 3 % (at 2 decimals accelerations worked out from speeds are off by 0.1 m/s²)."""
    fine, coarse = checks.counts(city[6][0]), checks.counts(city[2][0])
    for a, b in zip(fine, coarse):
        assert abs(a - b) <= 0.03 * a + 2, (fine, coarse)
