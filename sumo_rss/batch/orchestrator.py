"""Run a batch: skip finished runs, execute the rest (locally or on Ray), show progress, write the outputs.

A batch folder is locked while a batch runs in it (``.batch.lock`` with the process id); a lock left by a dead
process is taken over, together with the half-written ``*.partial`` run folders that process left behind.
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from ..errors import SumoRssError
from .aggregate import write_batch_outputs
from .executors import LocalExecutor, Outcome, RayExecutor
from .runner import SUMMARY_FILE, run_directory
from .spec import Task

LOCK_FILE = ".batch.lock"


def run_batch(tasks: list[Task], out_dir: Path, executor: LocalExecutor | RayExecutor, *,
              progress: bool = True) -> pd.DataFrame:
    """Run every task not finished yet; returns the batch summary (one row per task)."""
    out_dir = Path(out_dir)
    ids = [t.run_id for t in tasks]
    if len(set(ids)) != len(ids):
        raise SumoRssError("the batch names some run twice (same scenario, variant and seed)")
    out_dir.mkdir(parents=True, exist_ok=True)
    with _BatchLock(out_dir):
        todo = [t for t in tasks if not (run_directory(out_dir, t) / SUMMARY_FILE).is_file()]
        failed = 0
        with tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc="runs", unit="run", disable=not progress,
                  file=sys.stderr, dynamic_ncols=True) as bar:
            def on_result(outcome: Outcome) -> None:
                nonlocal failed
                failed += outcome.status != "ok"
                bar.set_postfix(failed=failed, refresh=False)
                bar.update(1)

            try:
                executor.run(todo, out_dir, on_result)
            finally:  # also after Ctrl-C: what finished is summarised, what was killed leaves nothing behind
                _remove_partial_runs(out_dir)
                rows = write_batch_outputs(out_dir, tasks)
    return rows


class _BatchLock:
    def __init__(self, out_dir: Path):
        self.path = out_dir / LOCK_FILE
        self.out_dir = out_dir

    def __enter__(self) -> _BatchLock:
        if self.path.is_file():
            holder = int(self.path.read_text().strip() or 0)
            if holder and holder != os.getpid() and _alive(holder):
                raise SumoRssError(f"{self.out_dir}: another batch (process {holder}) is running in this folder")
        _remove_partial_runs(self.out_dir)  # left by a batch that died mid-run
        self.path.write_text(f"{os.getpid()}\n")
        return self

    def __exit__(self, *exc: object) -> None:
        self.path.unlink(missing_ok=True)


def _remove_partial_runs(out_dir: Path) -> None:
    """Remove half-written run folders; only safe while holding the batch lock."""
    for partial in out_dir.glob("**/.*.partial"):
        shutil.rmtree(partial, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
