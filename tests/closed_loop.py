"""Helpers of the closed-loop tests (test_planner_closed_loop.py, test_planner_acceptance.py): batches of a shipped
scenario with a chosen ego controller on real libsumo, and the safety checks every run of a planner must pass."""
from __future__ import annotations

import csv
import json
import os
from dataclasses import replace
from pathlib import Path

import pytest

from conftest import SCENARIOS
from sumo_rss.batch.executors import LocalExecutor
from sumo_rss.batch.orchestrator import run_batch
from sumo_rss.batch.runner import run_directory
from sumo_rss.batch.spec import Task, variant_name
from sumo_rss.road.network import RoadNetwork
from sumo_rss.scenario import load_scenario

ACCEPTANCE_SEEDS = range(20)
ACCELERATION_LANE = "mw_merge_0"
acceptance = pytest.mark.skipif(os.environ.get("SUMO_RSS_ACCEPTANCE") != "1",
                                reason="20-seed acceptance runs: set SUMO_RSS_ACCEPTANCE=1 (make acceptance)")


def batch(name: str, out: Path, seeds: range, *, controller: str = "epsilon", duration: float | None = None,
          fcd: bool = False, **planner) -> list[tuple[Task, Path]]:
    """``scenarios/<name>.toml`` for ``seeds`` with the ego driven by ``controller`` (``planner``: [ego.planner]
    settings), ``duration`` simulated s each (None: the scenario's own), on 2 processes; (task, run folder) each."""
    base = load_scenario(SCENARIOS / f"{name}.toml")
    variant = variant_name({"controller": controller, **planner})
    tasks = []
    for seed in seeds:
        spec = base.with_overrides(seed=seed, duration_s=duration, controller=controller)
        spec = replace(spec, ego=replace(spec.ego, planner=replace(spec.ego.planner, **planner)),
                       outputs=replace(spec.outputs, fcd=fcd or spec.outputs.fcd))
        tasks.append(Task(spec, variant))
    rows = run_batch(tasks, out, LocalExecutor(workers=2), progress=False)
    assert rows.status.tolist() == ["ok"] * len(tasks), rows.error.tolist()
    return [(t, run_directory(out, t)) for t in tasks]


def trace(folder: Path) -> list[dict]:
    with (folder / "ego_trace.csv").open() as fh:
        return list(csv.DictReader(fh))


def assert_safe(runs: list[tuple[Task, Path]], *, never_responsible: bool = True) -> list[dict]:
    """No collision involving the ego and (by default) never responsible; a planner ego was planned for every step
    from its first on the road to the end of the run or to its arrival. The runs' summaries."""
    summaries = []
    for task, folder in runs:
        summary = json.loads((folder / "summary.json").read_text())
        ego = summary["ego_id"]
        assert not [c for c in summary["collision_events"] if ego in (c["collider"], c["victim"])], task.run_id
        if never_responsible:
            assert summary["ego_responsible_episodes"] == 0, task.run_id
        if summary["ego_controller"] in ("epsilon", "mpdm"):
            rows = trace(folder)
            arrived = float(rows[-1]["time_s"]) + task.spec.step_s < summary["sim_time_s"] - 1e-6
            assert summary["planner"]["cycles"] == len(rows) - (0 if arrived else 1), task.run_id
        summaries.append(summary)
    return summaries


def assert_on_acceleration_lane_not_past_its_end(runs: list[tuple[Task, Path]]) -> None:
    """merge_onramp: the ego drove onto the acceleration lane and its front bumper never passed the lane's end."""
    net = RoadNetwork.from_file(load_scenario(SCENARIOS / "merge_onramp.toml").net_file)
    lane_end = float(net.lane_length[net.lane_indices([ACCELERATION_LANE])[0]])
    for task, folder in runs:
        positions = [float(r["lane_pos_m"]) for r in trace(folder) if r["lane_id"] == ACCELERATION_LANE]
        assert positions, task.run_id
        assert max(positions) <= lane_end, task.run_id
