"""Batch outputs: one summary row per run and the runs' CSVs concatenated with their run keys."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..files import csv_writer, read_json_object, write_file_set
from .executors import FAILED_FILE, Outcome, failure_directory
from .runner import SUMMARY_FILE, run_directory
from .spec import Task

SUMMARY_COLUMNS = ["run_id", "scenario", "variant", "seed", "status", "sim_time_s", "wall_time_s",
                   "real_time_factor", "steps", "vehicles_inserted", "peak_vehicles", "episodes", "violations",
                   "collisions", "teleports", "ego_responsible_episodes", "ego_mean_speed_ms", "error"]
COUNT_COLUMNS = ("seed", "steps", "vehicles_inserted", "peak_vehicles", "episodes", "violations", "collisions",
                 "teleports", "ego_responsible_episodes")
CONCATENATED = ("episodes", "violations", "collisions", "pair_states", "occlusion")  # occlusion: rule 4 runs only
BATCH_FILES = ("batch_summary.csv", *(f"{name}.csv" for name in CONCATENATED))  # a batch writes into its folder
# Names in a batch folder that are the batch's own (`sumo-rss report` adds report.html and report/): no scenario's
# runs folder may have one.
RESERVED_NAMES = (*BATCH_FILES, "report.html", "report", ".batch.lock")


def summary_row(out_dir: Path, task: Task, outcome: Outcome | None = None) -> dict:
    """The batch_summary.csv row of a task: from its summary.json, its failed.json, the ``outcome`` of its run in
    this batch where the run could not write either, or 'missing'."""
    base = {"run_id": task.run_id, "scenario": task.spec.name, "variant": task.variant, "seed": task.spec.seed}
    summary = run_directory(out_dir, task) / SUMMARY_FILE
    if summary.is_file():
        data = read_json_object(summary)
        if data is None:
            return base | {"status": "failed", "error": f"{summary}: damaged (not a JSON object)"}
        return base | {k: data.get(k) for k in SUMMARY_COLUMNS if k not in base and k != "error"} | {"error": ""}
    failed = read_json_object(failure_directory(out_dir, task) / FAILED_FILE)
    if failed is not None:
        return base | {"status": "failed", "error": str(failed.get("error", ""))}
    if outcome is not None and outcome.status != "ok":
        return base | {"status": "failed", "error": outcome.error}
    return base | {"status": "missing", "error": "not run (interrupted?)"}


def write_batch_outputs(out_dir: Path, tasks: list[Task], outcomes: dict[str, Outcome] | None = None) -> pd.DataFrame:
    """batch_summary.csv and the concatenated episodes / violations / collisions / pair_states CSVs (``outcomes``:
    of the runs this batch ran, by run id)."""
    outcomes = outcomes or {}
    rows = pd.DataFrame([summary_row(out_dir, t, outcomes.get(t.run_id)) for t in tasks], columns=SUMMARY_COLUMNS)
    rows = rows.astype({name: "Int64" for name in COUNT_COLUMNS})  # integers also where a run failed (empty)
    ok = [t for t, status in zip(tasks, rows.status) if status == "ok"]
    writers = {out_dir / "batch_summary.csv": csv_writer(rows)}
    absent = []  # no run has it now: an older batch's file must not stand for this one
    for name in CONCATENATED:
        runs = [(task, run_directory(out_dir, task) / f"{name}.csv") for task in ok]
        runs = [(task, path) for task, path in runs if path.is_file()]
        if runs:
            writers[out_dir / f"{name}.csv"] = _concatenated(runs)
        else:
            absent.append(out_dir / f"{name}.csv")
    write_file_set(writers)  # all of them or, where one cannot be written (disk full), none
    for path in absent:
        path.unlink(missing_ok=True)
    return rows


def _concatenated(runs: list[tuple[Task, Path]]):
    """A writer of the runs' CSVs (``runs``: (task, its CSV)) as one, each row with its run's keys; the cells as the
    runs wrote them (text), so the rows are exact copies. Read when it writes, so that one batch CSV at a time is
    in memory."""
    def write(path: Path) -> None:
        parts = []
        for task, csv in runs:
            frame = pd.read_csv(csv, dtype=str, keep_default_na=False)
            frame.insert(1, "scenario", task.spec.name)
            frame.insert(2, "variant", task.variant)
            frame.insert(3, "seed", str(task.spec.seed))
            parts.append(frame)
        csv_writer(pd.concat(parts, ignore_index=True))(path)
    return write
