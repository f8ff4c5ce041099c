"""Audit speed at a signalised junction: intersection_tls (300 simulated s) is simulated once and its snapshots
kept; then they are audited (every pair, road and junction situations; no signal rule, no collisions), timed on
their own. Figures: pair-steps/s of the audit, real-time factors of the simulation alone, the audit alone and the
two timings added (``sim_plus_audit_rtf``: not one co-simulation), ms of audit per step, and how many of the
pair-steps were junction situations (``junction_pair_steps``: pairs in a conflict area, one per pair and step)."""
from __future__ import annotations

import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.batch.runner import param_resolver  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.rss.auditor import Auditor  # noqa: E402
from sumo_rss.rss.situations import FIRST_INTERSECTION_CODE  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402


def main() -> None:
    options = arguments(__doc__, "intersection_audit.py")
    spec = load_scenario(REPO / "scenarios" / "intersection_tls.toml")
    snapshots = []
    started = time.perf_counter()
    with Session(spec) as session:
        while not session.finished:
            snapshots.append(session.step())
    sim_wall = time.perf_counter() - started
    auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec))
    junction_pair_steps = 0
    started = time.perf_counter()
    for snapshot in snapshots:
        junction_pair_steps += int((auditor.observe(snapshot).kind >= FIRST_INTERSECTION_CODE).sum())
    result = auditor.finish()
    audit_wall = time.perf_counter() - started
    junction = result.episodes.situation.str.startswith("intersection").sum()
    figures = {"sim_s": spec.duration_s, "sim_only_rtf": spec.duration_s / sim_wall,
               "audit_only_rtf": spec.duration_s / audit_wall, "sim_plus_audit_rtf": spec.duration_s / (sim_wall + audit_wall),
               "audit_ms_per_step": 1000 * audit_wall / len(snapshots), "pair_steps": auditor.pair_steps,
               "pair_steps_per_s": auditor.pair_steps / audit_wall, "junction_pair_steps": junction_pair_steps,
               "episodes": len(result.episodes), "junction_episodes": int(junction)}
    record("intersection_audit", figures, options)
    print(f"intersection_tls: audit {figures['audit_only_rtf']:.0f}x real time alone, sim+audit "
          f"{figures['sim_plus_audit_rtf']:.0f}x, {figures['pair_steps_per_s'] / 1e6:.2f} M pair-steps/s, "
          f"{figures['audit_ms_per_step']:.2f} ms/step, {junction} junction episodes")


if __name__ == "__main__":
    main()
