"""The egos side by side (issue 48, decision 3): epsilon, sumo, sumo_restricted (SUMO held to RSS by the ego's
guard) and mpdm on the same scenarios and seeds in one batch, with what each run's ego did
(:mod:`sumo_rss.report.ego_metrics`): route travel time, settled mean speed, responsible episodes and seconds,
lane changes and merge delay, per seed and summed up per scenario and controller.

    from _ego_comparison import compare
    figures = compare(["highway_overtake", "intersection_tls"], seeds=range(3))

Runs go to a temporary folder (``out``: keep them there) through the batch runner, on ``workers`` processes.
"""
from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from sumo_rss import load_scenario
from sumo_rss.batch.executors import LocalExecutor
from sumo_rss.batch.orchestrator import run_batch
from sumo_rss.batch.runner import run_directory
from sumo_rss.batch.spec import Task, variant_name
from sumo_rss.report.ego_metrics import ego_run_metrics
from sumo_rss.road.network import RoadNetwork

REPO = Path(__file__).resolve().parent.parent
CONTROLLERS = ("epsilon", "sumo", "sumo_restricted", "mpdm")
# Every scenario family issue 48 names (scenarios/<name>.toml).
FAMILIES = ("highway_dense", "highway_sparse", "highway_overtake", "highway_exit", "merge_onramp",
            "intersection_tls", "intersection_priority")


def compare(scenarios: Sequence[str] = FAMILIES, seeds: Iterable[int] = range(3),
            controllers: Sequence[str] = CONTROLLERS, *, duration: float | None = None, workers: int = 2,
            out: Path | None = None) -> dict:
    """Run every scenario x seed x controller (``duration`` [s]: None for each scenario's own) and return
    {scenario: {controller: {"runs": {seed: metrics}, "summary": ...}}}. The summary: median travel time [s] over
    the seeds (a run whose ego did not arrive counts as the longest), mean settled speed [m/s], responsible episodes
    and seconds summed, lane changes summed, median merge delay [s] (where the scenario has a lane that ends), the
    seeds whose ego arrived, and for every controller but sumo the ratios of its median travel time and mean
    settled speed to sumo's."""
    seeds = list(seeds)
    folder = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="sumo_rss_compare_"))
    tasks: dict[tuple[str, str, int], Task] = {}
    for name in scenarios:
        base = load_scenario(REPO / "scenarios" / f"{name}.toml")
        for controller in controllers:
            for seed in seeds:
                spec = base.with_overrides(seed=seed, duration_s=duration, controller=controller)
                tasks[name, controller, seed] = Task(spec, variant_name({"controller": controller}))
    try:
        rows = run_batch(list(tasks.values()), folder, LocalExecutor(workers=workers), progress=False)
        failed = rows[rows.status != "ok"]
        if len(failed):
            raise RuntimeError(f"comparison runs failed: {failed.run_id.tolist()}: {failed.error.tolist()}")
        figures: dict = {}
        for name in scenarios:
            network = RoadNetwork.from_file(tasks[name, controllers[0], seeds[0]].spec.net_file)
            figures[name] = {c: {"runs": {str(seed): ego_run_metrics(run_directory(folder, tasks[name, c, seed]),
                                                                      network).as_dict() for seed in seeds}}
                             for c in controllers}
            for c in controllers:
                figures[name][c]["summary"] = _summary(figures[name][c]["runs"])
            if "sumo" in controllers:
                for c in controllers:
                    if c != "sumo":
                        figures[name][c]["summary"] |= _ratios(figures[name][c]["summary"],
                                                               figures[name]["sumo"]["summary"])
    finally:
        if out is None:
            shutil.rmtree(folder, ignore_errors=True)
    return figures


def _summary(runs: dict[str, dict]) -> dict:
    metrics = list(runs.values())
    travel = [m["travel_time_s"] if m["travel_time_s"] is not None else np.inf for m in metrics]
    settled = [m["settled_mean_speed_ms"] for m in metrics if m["settled_mean_speed_ms"] is not None]
    merges = [m["merge_delay_s"] for m in metrics if m["merge_delay_s"] is not None]
    median_travel = float(np.median(travel))
    return {"median_travel_time_s": median_travel if np.isfinite(median_travel) else None,
            "arrived": sum(np.isfinite(travel)), "seeds": len(metrics),
            "mean_settled_speed_ms": float(np.mean(settled)) if settled else None,
            "responsible_episodes": sum(m["responsible_episodes"] for m in metrics),
            "responsible_s": float(sum(m["responsible_s"] for m in metrics)),
            "collisions": sum(m["collisions"] for m in metrics),
            "lane_changes": sum(m["lane_changes"] for m in metrics),
            "median_merge_delay_s": float(np.median(merges)) if merges else None,
            "max_merge_delay_s": float(np.max(merges)) if merges else None}


def _ratios(summary: dict, sumo: dict) -> dict:
    def ratio(key: str) -> float | None:
        a, b = summary[key], sumo[key]
        return a / b if a is not None and b else None
    return {"travel_time_vs_sumo": ratio("median_travel_time_s"),
            "settled_speed_vs_sumo": ratio("mean_settled_speed_ms")}
