"""Co-simulation speed per shipped scenario, with a WorldSnapshot built every step.

Figures: steps/s, vehicle-steps/s, real-time factor (simulated s per wall s) over the whole run and over the
loaded steps (at least 90% of the peak vehicle count: the run starts from an empty network, and its first
~90 s ran 4-5x faster than the loaded rest), peak vehicles in the network.
Target (issue 2): highway_dense (>= 150 vehicles) >= 50x real time, judged on the loaded steps (their mean vehicle
count must be >= 150, a stricter reading than the peak).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402

SCENARIOS = ["highway_dense", "highway_sparse", "merge_onramp", "intersection_tls", "intersection_priority"]
REPEATS = 3  # best of, to damp machine noise


def measure(name: str) -> dict:
    spec = load_scenario(REPO / "scenarios" / f"{name}.toml")
    best = None
    for _ in range(REPEATS):
        walls, counts = [], []
        started = time.perf_counter()
        with Session(spec) as session:
            while not session.finished:
                t0 = time.perf_counter()
                counts.append(len(session.step()))
                walls.append(time.perf_counter() - t0)
        wall = time.perf_counter() - started
        if best is None or wall < best[0]:
            best = (wall, np.array(walls), np.array(counts), session.peak_vehicles)
    wall, walls, counts, peak = best
    loaded = counts >= 0.9 * peak
    return {"steps_per_s": counts.size / wall, "vehicle_steps_per_s": counts.sum() / wall,
            "real_time_factor": counts.size * spec.step_s / wall,
            "real_time_factor_loaded": loaded.sum() * spec.step_s / walls[loaded].sum(),
            "loaded_steps": int(loaded.sum()), "loaded_mean_vehicles": float(counts[loaded].mean()),
            "peak_vehicles": peak, "sim_time_s": counts.size * spec.step_s, "wall_s": wall}


def main() -> None:
    options = arguments(__doc__, "sim_speed.py")
    figures = {name: measure(name) for name in SCENARIOS}
    dense = figures["highway_dense"]
    figures["target_highway_dense_rtf_50x"] = bool(dense["real_time_factor_loaded"] >= 50 and
                                                   dense["loaded_mean_vehicles"] >= 150)
    record("sim_speed", figures, options)
    for name, f in figures.items():
        if isinstance(f, dict):
            print(f"{name:24s} {f['real_time_factor']:7.1f}x real time ({f['real_time_factor_loaded']:.1f}x loaded)  "
                  f"{f['steps_per_s']:8.0f} steps/s  "
                  f"{f['vehicle_steps_per_s']:9.0f} vehicle-steps/s  peak {f['peak_vehicles']}")


if __name__ == "__main__":
    main()
