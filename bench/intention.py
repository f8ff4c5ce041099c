"""Intention estimator: time per planning cycle for 20 agents, all on branching approach lanes, with the shipped
weights on one core. The network judges the agents it finds two or more candidate lanes for (recorded as
``agents_using_the_network``: 14 of 20 in the recorded run); the others get the rule-based belief.

The agents are real: the busiest snapshot of 200 s of intersection_priority traffic, its vehicles on branching
approach lanes repeated up to 20. Timed: candidate centrelines + history + network (LearnedBelief), and the
network alone. Target (issue 7): <= 5 ms per cycle for 20 agents.
"""
from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.planner.intention.belief import LearnedBelief  # noqa: E402
from sumo_rss.planner.intention.estimator import load_estimator  # noqa: E402
from sumo_rss.planner.intention.features import history_in_agent_frame  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402
from sumo_rss.sim.snapshot import WorldSnapshot  # noqa: E402

AGENTS = 20
CYCLES = 200


def busiest_branching_snapshot(belief: LearnedBelief) -> tuple[WorldSnapshot, np.ndarray]:
    spec = dataclasses.replace(load_scenario(REPO / "scenarios" / "intersection_priority.toml"), ego=None)
    best: tuple[WorldSnapshot, np.ndarray] | None = None
    with Session(spec.with_overrides(duration_s=200.0)) as session:
        while not session.finished:
            snapshot = session.step()
            belief.observe(snapshot)
            lanes = belief.network.lane_indices(snapshot.lane_id)
            rows = np.flatnonzero([belief.branches(int(k)) for k in lanes])
            if best is None or rows.size > best[1].size:
                best = (snapshot, rows)
    assert best is not None and best[1].size > 0
    return best


def main() -> None:
    options = arguments(__doc__, "intention.py")
    network = RoadNetwork.from_file(REPO / "networks" / "intersection_priority" / "intersection_priority.net.xml")
    estimator = load_estimator()
    if estimator is None:
        raise SystemExit("the shipped intention weights do not load")
    belief = LearnedBelief(network, estimator)
    snapshot, branching = busiest_branching_snapshot(belief)
    rows = np.resize(branching, AGENTS)
    lanes = network.lane_indices(snapshot.lane_id[rows])
    full, net_only = [], []
    for _ in range(CYCLES):
        started = time.perf_counter()
        probs, used = belief.lateral_probabilities(snapshot, rows, lanes)
        full.append(time.perf_counter() - started)
    cand = belief.finder.candidates(lanes, snapshot.x[rows], snapshot.y[rows], snapshot.heading[rows])
    zeros = np.zeros((AGENTS, 11))
    history = history_in_agent_frame(zeros + snapshot.x[rows, None], zeros + snapshot.y[rows, None], zeros,
                                     snapshot.x[rows], snapshot.y[rows], snapshot.heading[rows])
    for _ in range(CYCLES):
        started = time.perf_counter()
        estimator.probabilities(history, cand)
        net_only.append(time.perf_counter() - started)

    def stats(times: list[float]) -> dict:
        ms = np.array(times[5:]) * 1000.0
        return {"median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95)),
                "p99_ms": float(np.percentile(ms, 99))}

    figures = {"agents": AGENTS, "distinct_agents": int(branching.size), "agents_using_the_network": int(used.sum()),
               "per_cycle": stats(full), "network_only": stats(net_only)}
    figures["targets"] = {"per_cycle_20_agents_le_5ms": figures["per_cycle"]["median_ms"] <= 5.0}
    record("intention", figures, options)
    print(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
