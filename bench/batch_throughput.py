"""Batch throughput with 1 and 2 local workers (runs per minute) and the speed-up.

Eight runs of the shipped highway_sparse scenario (300 simulated seconds, co-simulation + audit each), as a
user's batch runs them; each configuration measured twice, alternating (1, 2, 1, 2 workers), best of the two (the
first batch also paid for cold caches: measured once each, 1 worker first, the speed-up read 2.19x on 2 cores).
Target (issue 8): a speed-up >= 1.8x on 2 cores.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.batch.executors import LocalExecutor  # noqa: E402
from sumo_rss.batch.orchestrator import run_batch  # noqa: E402
from sumo_rss.batch.spec import Task  # noqa: E402

RUNS = 8


def runs_per_minute(workers: int) -> float:
    spec = load_scenario(REPO / "scenarios" / "highway_sparse.toml")
    tasks = [Task(spec.with_overrides(seed=seed), "") for seed in range(RUNS)]
    out = Path(tempfile.mkdtemp(prefix="sumo_rss_bench_"))
    try:
        started = time.perf_counter()
        rows = run_batch(tasks, out, LocalExecutor(workers), progress=False)
        wall = time.perf_counter() - started
    finally:
        shutil.rmtree(out, ignore_errors=True)
    if not (rows.status == "ok").all():
        raise RuntimeError(f"failed runs: {rows[rows.status != 'ok'].error.tolist()}")
    return RUNS / wall * 60.0


def main() -> None:
    options = arguments(__doc__, "batch_throughput.py")
    rates = {1: [], 2: []}
    for workers in (1, 2, 1, 2):
        rates[workers].append(runs_per_minute(workers))
    one, two = max(rates[1]), max(rates[2])
    figures = {"runs": RUNS, "scenario": "highway_sparse (300 s)", "runs_per_min_1_worker": one,
               "runs_per_min_2_workers": two, "speedup_2_workers": two / one,
               "target_speedup_1_8x": bool(two / one >= 1.8)}
    record("batch_throughput", figures, options)
    print(f"1 worker {one:.1f} runs/min, 2 workers {two:.1f} runs/min, speed-up {two / one:.2f}x")


if __name__ == "__main__":
    main()
