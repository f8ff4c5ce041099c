"""Audit speed at a signalised junction: intersection_tls (300 simulated s) is simulated once and its snapshots kept;
then they are audited (every pair, road and junction situations; no signal rule, no collisions), timed on their own.
Figures: pair-steps/s of the audit (wall; ``pair_steps_per_cpu_s``: per CPU second), real-time factors of the
simulation alone, the audit alone and the two timings added (``sim_plus_audit_rtf``: not one co-simulation), ms of
audit per step, and how many of the pair-steps were junction situations (``junction_pair_steps``: pairs in a
conflict area, one per pair and step). The junction situations alone (``intersection_situations`` over the same
snapshots, their vehicle frames built untimed; CPU time): ms per step and situation rows (one per pair and conflict
area) per second (``junction_rows_per_s``). The junction kernel's first call in a fresh process (``jit_compile_s``:
an empty numba cache, as in a fresh clone; ``jit_cached_s``: from the cache it left), each with numba's import.

The same figures again, prefixed ``saturated_``, for the same network, signal program and seed with every flow
scaled by SATURATED_DEMAND (as a batch's ``demand_scale``): ~200 vehicles at once queue at red and cross, ~2,000
junction rows a step, where a throughput is judged with the per-step cost amortised, as the road figure is on
bench/rss_vs_adrss's dense 500-vehicle world (docs/city_scale.md). With the shipped demand (~64 junction rows a
step) the figure is bounded by the fixed cost of a step, not by the cost of a row.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.batch.spec import apply_variant  # noqa: E402
from sumo_rss.batch.runner import param_resolver  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.road.routes import RouteTable  # noqa: E402
from sumo_rss.rss.auditor import Auditor  # noqa: E402
from sumo_rss.rss.intersection import intersection_situations  # noqa: E402
from sumo_rss.rss.situations import FIRST_INTERSECTION_CODE, vehicle_frame  # noqa: E402
from sumo_rss.scenario import ScenarioSpec  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402
SATURATED_DEMAND = 4.0  # every flow x4: 1,200 veh/h straight and 320 per turn from each approach
# The kernel's first call, timed in a fresh process: numba's import and the compile (or the cache load).
FIRST_CALL = """
import time
started, cpu = time.perf_counter(), time.process_time()
import numpy as np
from sumo_rss.rss.junction_kernel import junction_pairs
i, f = np.zeros(0, dtype=np.int64), np.zeros(0)
junction_pairs(i, i, f, i, np.zeros(1, dtype=np.int64), i, i, f, f, np.zeros(0, dtype=np.int8), i,
               np.zeros(0, dtype=bool), i, i, f, f, np.zeros((10, 0)).T)
print(time.perf_counter() - started, time.process_time() - cpu)
"""


def first_call_s() -> list[list[float]]:
    """[s] [wall, CPU] of the junction kernel's first call with an empty numba cache, then from the cache it
    left."""
    with tempfile.TemporaryDirectory(prefix="numba_cache_") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(REPO)}
        return [[float(x) for x in subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, check=True, text=True,
                                                  capture_output=True).stdout.split()] for _ in range(2)]


def junction_time(snapshots: list, network: RoadNetwork, auditor: Auditor) -> tuple[float, int]:
    """([s] CPU spent in the junction situations of ``snapshots``, their rows), each step's vehicle frame built as
    the auditor builds it (untimed)."""
    routes, spent, rows = RouteTable(network), 0.0, 0
    for snapshot in snapshots:
        moving = auditor.params.arrays(snapshot, held=False)
        frame = vehicle_frame(snapshot, network, auditor.params.hold(moving, snapshot), routes.remaining(snapshot),
                              moving)
        started = time.process_time()
        rows += len(intersection_situations(snapshot, frame, network, auditor.junctions,
                                            horizon=2.0 * float(frame.reach.max(initial=0.0)) + 20.0))
        spent += time.process_time() - started
    return spent, rows


def audit_figures(spec: ScenarioSpec) -> tuple[dict, int]:
    """The figures of one run of ``spec`` (simulated, then its snapshots audited and their junction situations
    timed alone), and its number of junction episodes."""
    snapshots, peak = [], 0
    started = time.perf_counter()
    with Session(spec) as session:
        while not session.finished:
            snapshots.append(session.step())
            peak = max(peak, len(snapshots[-1].ids))
    sim_wall = time.perf_counter() - started
    network = RoadNetwork.from_file(spec.net_file)
    auditor = Auditor(network, param_resolver(spec))
    auditor.observe(snapshots[0])  # the junction kernel loaded (its first call is timed on its own below)
    auditor = Auditor(network, param_resolver(spec))
    junction_pair_steps = 0
    started, cpu = time.perf_counter(), time.process_time()
    for snapshot in snapshots:
        junction_pair_steps += int((auditor.observe(snapshot).kind >= FIRST_INTERSECTION_CODE).sum())
    result = auditor.finish()
    audit_wall, audit_cpu = time.perf_counter() - started, time.process_time() - cpu
    junction = int(result.episodes.situation.str.startswith("intersection").sum())
    spent, rows = junction_time(snapshots, network, auditor)
    return {"sim_s": spec.duration_s, "peak_vehicles": peak, "sim_only_rtf": spec.duration_s / sim_wall,
            "audit_only_rtf": spec.duration_s / audit_wall,
            "sim_plus_audit_rtf": spec.duration_s / (sim_wall + audit_wall),
            "audit_ms_per_step": 1000 * audit_wall / len(snapshots), "pair_steps": auditor.pair_steps,
            "pair_steps_per_s": auditor.pair_steps / audit_wall, "pair_steps_per_cpu_s": auditor.pair_steps / audit_cpu,
            "junction_pair_steps": junction_pair_steps,
            "episodes": len(result.episodes), "junction_episodes": junction,
            "junction_ms_per_step": 1000 * spent / len(snapshots), "junction_rows": rows,
            "junction_rows_per_s": rows / spent}, junction


def main() -> None:
    options = arguments(__doc__, "intersection_audit.py")
    spec = load_scenario(REPO / "scenarios" / "intersection_tls.toml")
    figures, junction = audit_figures(spec)
    saturated, _ = audit_figures(apply_variant(spec, {"demand_scale": SATURATED_DEMAND}))
    figures.update({"saturated_demand_scale": SATURATED_DEMAND, **{f"saturated_{k}": v for k, v in saturated.items()
                                                                   if k != "sim_s"}})
    (compile_s, compile_cpu), (cached_s, cached_cpu) = first_call_s()
    figures.update({"jit_compile_s": compile_s, "jit_compile_cpu_s": compile_cpu, "jit_cached_s": cached_s,
                    "jit_cached_cpu_s": cached_cpu})
    record("intersection_audit", figures, options)
    print(f"intersection_tls: audit {figures['audit_only_rtf']:.0f}x real time alone, sim+audit "
          f"{figures['sim_plus_audit_rtf']:.0f}x, {figures['pair_steps_per_s'] / 1e6:.2f} M pair-steps/s, "
          f"{figures['audit_ms_per_step']:.2f} ms/step, {junction} junction episodes; junction situations "
          f"{figures['junction_ms_per_step']:.3f} ms/step, {figures['junction_rows_per_s'] / 1e6:.2f} M rows/s (CPU); "
          f"saturated (demand x{SATURATED_DEMAND:g}, peak {saturated['peak_vehicles']} vehicles): "
          f"{saturated['pair_steps_per_s'] / 1e6:.2f} M pair-steps/s ({saturated['pair_steps_per_cpu_s'] / 1e6:.2f} M "
          f"per CPU s), junction situations "
          f"{saturated['junction_ms_per_step']:.3f} ms/step, {saturated['junction_rows_per_s'] / 1e6:.2f} M rows/s; "
          f"kernel's first call {compile_s:.1f} s compiling ({compile_cpu:.1f} s CPU), {cached_s:.1f} s from the cache")


if __name__ == "__main__":
    main()
