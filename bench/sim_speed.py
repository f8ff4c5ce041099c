"""Co-simulation speed per shipped scenario, with a WorldSnapshot built every step.

Figures: steps/s, vehicle-steps/s, real-time factor (simulated s per wall s), peak vehicles in the network.
Target (issue 2): highway_dense (>= 150 vehicles at peak) >= 50x real time.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402

SCENARIOS = ["highway_dense", "highway_sparse", "merge_onramp", "intersection_tls", "intersection_priority"]
REPEATS = 3  # best of, to damp machine noise


def measure(name: str) -> dict:
    spec = load_scenario(REPO / "scenarios" / f"{name}.toml")
    best = None
    for _ in range(REPEATS):
        vehicle_steps = 0
        started = time.perf_counter()
        with Session(spec) as session:
            while not session.finished:
                vehicle_steps += len(session.step())
        wall = time.perf_counter() - started
        if best is None or wall < best[0]:
            best = (wall, session.steps, vehicle_steps, session.peak_vehicles, session.steps * spec.step_s)
    wall, steps, vehicle_steps, peak, sim_time = best
    return {"steps_per_s": steps / wall, "vehicle_steps_per_s": vehicle_steps / wall,
            "real_time_factor": sim_time / wall, "peak_vehicles": peak, "sim_time_s": sim_time, "wall_s": wall}


def main() -> None:
    figures = {name: measure(name) for name in SCENARIOS}
    dense = figures["highway_dense"]
    figures["target_highway_dense_rtf_50x"] = bool(dense["real_time_factor"] >= 50 and dense["peak_vehicles"] >= 150)
    record("sim_speed", figures)
    for name, f in figures.items():
        if isinstance(f, dict):
            print(f"{name:24s} {f['real_time_factor']:7.1f}x real time  {f['steps_per_s']:8.0f} steps/s  "
                  f"{f['vehicle_steps_per_s']:9.0f} vehicle-steps/s  peak {f['peak_vehicles']}")


if __name__ == "__main__":
    main()
