"""What RSS rule 4 (occlusion) adds to a junction audit: intersection_tls (its 5 % buses, 3.4 m high, the only
occluders) and intersection_occluded (four corner buildings and buses), 300 simulated s each, simulated once and
their snapshots kept; then audited as bench/intersection_audit.py audits them, without and with rule 4, alternately,
three times each, timed in CPU seconds of the process (time.process_time: the machine is shared) and the
fastest of the three kept. Figures per scenario: ms of audit per step without and with rule 4, the
overhead (with / without − 1; the issue's bound is 0.30), the hidden pair-steps and the episodes hidden at some
step."""
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
from sumo_rss.rss.occlusion import OcclusionParams, read_occluders  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402
from sumo_rss.sim.vtypes import running_heights  # noqa: E402


def _audit(spec, network: RoadNetwork, snapshots: list, heights: dict[str, float], rule4: bool):
    """(CPU seconds, result) of one audit of ``snapshots``."""
    occluders = spec.rss.occlusion.occluders
    auditor = Auditor(network, param_resolver(spec), occlusion=OcclusionParams(enabled=True) if rule4 else None,
                      heights=heights, occluders=read_occluders(occluders) if rule4 and occluders else None)
    started = time.process_time()
    for snapshot in snapshots:
        auditor.observe(snapshot)
    result = auditor.finish()
    return time.process_time() - started, result


def main() -> None:
    options = arguments(__doc__, "occlusion_audit.py")
    figures = {}
    for name in ("intersection_tls", "intersection_occluded"):
        spec = load_scenario(REPO / "scenarios" / f"{name}.toml")
        snapshots = []
        with Session(spec) as session:
            heights = running_heights()
            while not session.finished:
                snapshots.append(session.step())
        network = RoadNetwork.from_file(spec.net_file)
        plain, with_rule4 = [], []
        for _ in range(3):
            plain.append(_audit(spec, network, snapshots, heights, False)[0])
            seconds, result = _audit(spec, network, snapshots, heights, True)
            with_rule4.append(seconds)
        without_s, with_s = min(plain), min(with_rule4)
        figures[name] = {"audit_ms_per_step": 1000 * without_s / len(snapshots),
                         "rule4_audit_ms_per_step": 1000 * with_s / len(snapshots),
                         "rule4_overhead": with_s / without_s - 1.0, "hidden_pair_steps": result.occluded_pair_steps,
                         "episodes": len(result.episodes), "hidden_episodes": len(result.occlusion)}
        f = figures[name]
        print(f"{name}: {f['audit_ms_per_step']:.2f} ms/step without rule 4, "
              f"{f['rule4_audit_ms_per_step']:.2f} with it (+{100 * f['rule4_overhead']:.0f} %), "
              f"{result.occluded_pair_steps} hidden pair-steps, {len(result.occlusion)} of {len(result.episodes)} "
              "episodes hidden at some step")
    record("occlusion_audit", figures, options)


if __name__ == "__main__":
    main()
