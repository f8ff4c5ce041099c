"""Run a batch: skip finished runs, execute the rest (locally or on Ray), show progress, write the outputs.

A batch folder is locked while a batch runs in it (an flock on ``.batch.lock``, which holds the process id); the
kernel drops the lock of a process that dies, and the next batch removes the half-written ``*.partial`` folders that
process left behind for the batch's own runs (only those: another batch may be writing elsewhere below the folder).
"""
from __future__ import annotations

import fcntl
import os
import shutil
import sys
import warnings
from collections import Counter
from pathlib import Path
from typing import IO

import pandas as pd
from tqdm import tqdm

from ..errors import SumoRssError
from ..files import make_folder, read_json_object
from .aggregate import RESERVED_NAMES, write_batch_outputs
from .executors import LocalExecutor, Outcome, RayExecutor
from .integrity import damage
from .runner import MANIFEST_FILE, PARTIAL_SUFFIX, STARTING_SUFFIX, SUMMARY_FILE, partial_run_is_live, run_directory
from .spec import Task

LOCK_FILE = ".batch.lock"


def run_batch(tasks: list[Task], out_dir: Path, executor: LocalExecutor | RayExecutor, *,
              progress: bool = True) -> pd.DataFrame:
    """Run every task not finished yet; returns the batch summary (one row per task)."""
    out_dir = Path(out_dir)
    ids = [t.run_id for t in tasks]
    twice = sorted(run_id for run_id, count in Counter(ids).items() if count > 1)
    if twice:
        sources = sorted({str(t.spec.source) for t in tasks if t.run_id in twice})
        raise SumoRssError(f"the batch names run {twice[0]} twice (the same scenario name, variant and seed, from "
                           f"{' and '.join(sources)})")
    clash = next((t for t in tasks if t.run_id.split("/", 1)[0] in RESERVED_NAMES), None)
    if clash is not None:
        raise SumoRssError(f"{clash.spec.source}: name: the runs of scenario {clash.spec.name!r} would be a folder "
                           f"{out_dir / clash.run_id.split('/', 1)[0]}, where the batch writes its own file (expected "
                           f"a name other than {', '.join(RESERVED_NAMES)})")
    if out_dir.exists() and not out_dir.is_dir():
        raise SumoRssError(f"{out_dir}: expected a folder for the batch's results, got a file")
    make_folder(out_dir)
    with _BatchLock(out_dir, tasks):
        todo, stale = [], {}
        for task in tasks:
            reason = _unfinished(out_dir, task)
            if reason is not None:
                todo.append(task)
                if run_directory(out_dir, task).exists():
                    stale[run_directory(out_dir, task)] = reason
        if stale:
            first = "; ".join(list(stale.values())[:3])
            warnings.warn(f"{out_dir}: {len(stale)} run folder(s) are not a finished run of the batch's scenarios "
                          f"(made from other scenario parameters, interrupted or damaged: {first}"
                          f"{'; ...' if len(stale) > 3 else ''}); running them again", stacklevel=2)
            for folder in stale:  # gone first: a rerun that fails must not leave the old results standing for it
                if folder.is_dir() and not folder.is_symlink():
                    shutil.rmtree(folder)
                else:  # a file (or a link) where the run's folder belongs
                    folder.unlink()
        failed, outcomes = 0, {}
        with tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc="runs", unit="run", disable=not progress,
                  file=sys.stderr, dynamic_ncols=True) as bar:
            def on_result(outcome: Outcome) -> None:
                nonlocal failed
                outcomes[outcome.run_id] = outcome
                failed += outcome.status != "ok"
                bar.set_postfix(failed=failed, refresh=False)
                bar.update(1)

            try:
                executor.run(todo, out_dir, on_result)
            finally:  # also after Ctrl-C: what finished is summarised, what was killed leaves nothing behind
                _remove_partial_runs(out_dir, tasks)
                rows = write_batch_outputs(out_dir, tasks, outcomes)
    return rows


def _unfinished(out_dir: Path, task: Task) -> str | None:
    """Why ``task``'s run folder does not hold a complete run of the same resolved scenario (None: it does). Not
    when the folder is missing, its summary or manifest cannot be read or are not what a finished run writes, the
    run was interrupted, the scenario changed since (the parameter hash of its manifest differs: it is run again, not
    reported from the old run), or a file its manifest lists is missing or not as the run wrote it."""
    folder = run_directory(out_dir, task)
    if not folder.exists():
        return "not run"
    manifest, summary = read_json_object(folder / MANIFEST_FILE), read_json_object(folder / SUMMARY_FILE)
    if manifest is None or summary is None or summary.get("run_id") != task.run_id:
        return f"{folder}: its {MANIFEST_FILE if manifest is None else SUMMARY_FILE} is missing or damaged"
    if summary.get("status") != "ok":
        return f"{folder}: status {summary.get('status')!r}, not 'ok'"
    if manifest.get("parameter_hash") != task.parameter_hash():
        return f"{folder}: made from other scenario parameters"
    return damage(folder, manifest.get("files"))


class _BatchLock:
    """An exclusive lock (flock) on ``<out>/.batch.lock``, which holds the process id for the error message. The
    kernel releases it when its process dies, so a lock file left behind by a killed batch is simply locked anew."""

    def __init__(self, out_dir: Path, tasks: list[Task]):
        self.path = out_dir / LOCK_FILE
        self.out_dir = out_dir
        self.tasks = tasks
        self._file: IO[str] | None = None

    def __enter__(self) -> _BatchLock:
        while True:
            fh = open(self.path, "a+", encoding="utf-8")
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                fh.seek(0)
                holder = fh.read().strip() or "?"
                fh.close()
                raise SumoRssError(f"{self.out_dir}: another batch (process {holder}) is running in this "
                                   "folder") from None
            try:
                same = os.stat(self.path).st_ino == os.fstat(fh.fileno()).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            fh.close()  # locked a file its holder removed on release meanwhile: lock the one there now
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()}\n")
        fh.flush()
        self._file = fh
        _remove_partial_runs(self.out_dir, self.tasks)  # left by a batch that died mid-run
        return self

    def __exit__(self, *exc: object) -> None:
        self.path.unlink(missing_ok=True)  # removed while still locked, so a waiting batch re-checks (above)
        if self._file is not None:
            self._file.close()
            self._file = None


def _remove_partial_runs(out_dir: Path, tasks: list[Task]) -> None:
    """Remove the half-written folders of ``tasks``' runs (``<scenario folder>/.<seed>.*.partial`` and
    ``.<seed>.*.starting``, see :func:`run_one`) whose process has died (a live run holds its folder's writer lock:
    a ``sumo-rss run`` of the same run may be writing there); only safe while holding the batch lock. Other
    ``.partial`` folders below ``out_dir`` may be runs of another batch in progress, and are left alone."""
    for folder in {run_directory(out_dir, t) for t in tasks}:
        for partial in (*folder.parent.glob(f".{folder.name}.*{PARTIAL_SUFFIX}"),
                        *folder.parent.glob(f".{folder.name}.*{STARTING_SUFFIX}")):
            if not partial_run_is_live(partial):
                shutil.rmtree(partial, ignore_errors=True)
