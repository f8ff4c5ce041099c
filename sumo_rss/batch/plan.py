"""Batch files (``[batch]`` scenarios × seeds) and their sequential execution.

Each (scenario, seed) run lands in its own directory via :func:`run_one`; a finished run (its
``summary.json`` exists) is skipped when the batch is run again, and a run that raises is recorded as failed
with its traceback (``failed.json`` in ``<out>/<scenario>/<seed>.failed/``) while the batch goes on.
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from ..errors import ScenarioError
from ..scenario import ScenarioSpec, load_scenario, tomllib
from ..validation import TableReader
from .runner import SUMMARY_FILE, run_directory, run_one, write_json

BATCH_SUMMARY_COLUMNS = ("scenario", "seed", "status", "steps", "sim_time_s", "wall_time_s", "real_time_factor",
                         "vehicles_inserted", "peak_vehicles", "collisions", "teleports", "error")


@dataclass(frozen=True)
class BatchSpec:
    source: Path
    scenarios: tuple[ScenarioSpec, ...]
    seeds: tuple[int, ...]


def is_batch_file(path: Path) -> bool:
    try:
        return "batch" in tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return False


def load_batch(path: str | Path) -> BatchSpec:
    """Read ``[batch] scenarios = [...] seeds = [...]``; scenario paths are relative to the batch file."""
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(path, "", "batch file not found", has_got=False)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(path, "", f"not valid TOML ({exc})", has_got=False) from exc
    top = TableReader(data, path)
    batch = top.table("batch", required=True)
    files = batch.string_list("scenarios")
    seeds = batch.raw("seeds", [0])
    if not isinstance(seeds, list) or not seeds or \
            not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
        raise batch.error("seeds", "expected a non-empty list of integers >= 0", seeds)
    batch.finish()
    top.finish()
    specs = []
    for i, name in enumerate(files):
        scenario_file = path.parent / name
        if not scenario_file.is_file():
            raise batch.error(f"scenarios[{i}]", f"expected an existing scenario file (looked for {scenario_file})",
                              name)
        specs.append(load_scenario(scenario_file))
    return BatchSpec(path, tuple(specs), tuple(dict.fromkeys(seeds)))


def run_batch(batch: BatchSpec, out_dir: Path, *, progress: bool = True) -> list[dict]:
    """Run every (scenario, seed) not finished yet, sequentially; returns one row per run."""
    tasks = [spec.with_overrides(seed=seed) for spec in batch.scenarios for seed in batch.seeds]
    rows = []
    bar = tqdm(tasks, desc="runs", unit="run", disable=not progress, file=sys.stderr)
    failed = 0
    for spec in bar:
        final = run_directory(out_dir, spec)
        if (final / SUMMARY_FILE).is_file():
            rows.append(_row_from_summary(final))
            continue
        failure_dir = final.with_name(f"{final.name}.failed")
        try:
            run_one(spec, out_dir)
            shutil.rmtree(failure_dir, ignore_errors=True)
            rows.append(_row_from_summary(final))
        except Exception as exc:  # a failing run is recorded and never stops the batch
            failed += 1
            failure_dir.mkdir(parents=True, exist_ok=True)
            write_json(failure_dir / "failed.json", {"scenario": spec.name, "seed": spec.seed,
                                                     "error": f"{type(exc).__name__}: {exc}",
                                                     "traceback": traceback.format_exc()})
            rows.append({"scenario": spec.name, "seed": spec.seed, "status": "failed",
                         "error": f"{type(exc).__name__}: {exc}"})
        bar.set_postfix(failed=failed)
    _write_batch_summary(Path(out_dir) / "batch_summary.csv", rows)
    return rows


def _row_from_summary(run_dir: Path) -> dict:
    data = json.loads((run_dir / SUMMARY_FILE).read_text(encoding="utf-8"))
    return {k: data.get(k, "") for k in BATCH_SUMMARY_COLUMNS if k != "error"} | {"error": ""}


def _write_batch_summary(path: Path, rows: list[dict]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=BATCH_SUMMARY_COLUMNS, restval="")
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)
