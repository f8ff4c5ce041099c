"""Batch outputs: one summary row per run and the runs' CSVs concatenated with their run keys."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from ..files import read_json_object, write_csv
from .executors import FAILED_FILE, failure_directory
from .runner import SUMMARY_FILE, run_directory
from .spec import Task

SUMMARY_COLUMNS = ["run_id", "scenario", "variant", "seed", "status", "sim_time_s", "wall_time_s",
                   "real_time_factor", "steps", "vehicles_inserted", "peak_vehicles", "episodes", "violations",
                   "collisions", "teleports", "ego_responsible_episodes", "ego_mean_speed_ms", "error"]
COUNT_COLUMNS = ("seed", "steps", "vehicles_inserted", "peak_vehicles", "episodes", "violations", "collisions",
                 "teleports", "ego_responsible_episodes")
CONCATENATED = ("episodes", "violations", "collisions", "pair_states")


def summary_row(out_dir: Path, task: Task) -> dict:
    """The batch_summary.csv row of a task: from its summary.json, its failed.json, or 'missing'."""
    base = {"run_id": task.run_id, "scenario": task.spec.name, "variant": task.variant, "seed": task.spec.seed}
    summary = run_directory(out_dir, task) / SUMMARY_FILE
    if summary.is_file():
        data = read_json_object(summary)
        if data is None:
            return base | {"status": "failed", "error": f"{summary}: damaged (not a JSON object)"}
        return base | {k: data.get(k) for k in SUMMARY_COLUMNS if k not in base and k != "error"} | {"error": ""}
    failed = failure_directory(out_dir, task) / FAILED_FILE
    if failed.is_file():
        return base | {"status": "failed", "error": json.loads(failed.read_text(encoding="utf-8"))["error"]}
    return base | {"status": "missing", "error": "not run (interrupted?)"}


def write_batch_outputs(out_dir: Path, tasks: list[Task]) -> pd.DataFrame:
    """batch_summary.csv and the concatenated episodes / violations / collisions / pair_states CSVs."""
    rows = pd.DataFrame([summary_row(out_dir, t) for t in tasks], columns=SUMMARY_COLUMNS)
    rows = rows.astype({name: "Int64" for name in COUNT_COLUMNS})  # integers also where a run failed (empty)
    write_csv(rows, out_dir / "batch_summary.csv")
    ok = [t for t, status in zip(tasks, rows.status) if status == "ok"]
    for name in CONCATENATED:
        parts = []
        for task in ok:
            path = run_directory(out_dir, task) / f"{name}.csv"
            if path.is_file():  # the cells as the run wrote them (text), so the rows are exact copies
                frame = pd.read_csv(path, dtype=str, keep_default_na=False)
                frame.insert(1, "scenario", task.spec.name)
                frame.insert(2, "variant", task.variant)
                frame.insert(3, "seed", str(task.spec.seed))
                parts.append(frame)
        if parts:
            write_csv(pd.concat(parts, ignore_index=True), out_dir / f"{name}.csv")
        else:  # no run has it now: an older batch's file must not stand for this one
            (out_dir / f"{name}.csv").unlink(missing_ok=True)
    return rows

