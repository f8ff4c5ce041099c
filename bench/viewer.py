"""The replay viewer on a 300 s highway_dense run (~190 vehicles), every vehicle recorded (as with --fcd).

Figures: what recording costs a run per step (the trajectory recorder, near the ego and of every vehicle; the
auditor's step-by-step states of every episode) next to a step's simulation and audit; the size of view.html (every
vehicle, and near the ego only, the default without --fcd); in headless Chromium: the time from navigation to the
first frame drawn, and frames drawn per second while playing at 1x following the ego and with the whole network
in view (with the median and 95th percentile of the script's time per frame, and the CPU time the browser's
processes spent per frame drawn: user + system of every process under this one, from /proc, which a loaded machine
moves far less than it moves the frame rate).
Targets (issue 51): loads in under 3 s, plays at 30 fps in both views, the file under 20 MB.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.batch.runner import param_resolver  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.rss.auditor import Auditor  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402
from sumo_rss.sim.snapshot import EGO_CLASS  # noqa: E402
from sumo_rss.view import NEAR_EGO_M, TRAJECTORY_FILE, TrajectoryRecorder, write_view  # noqa: E402
from sumo_rss.view.browser import headless_chromium, missing_browser, open_view  # noqa: E402

PLAY_S = 5.0  # [s] of playback per measurement


def record_run(folder: Path) -> dict:
    """Co-simulate highway_dense for 300 s, audit every step with and without the episodes' states, record the
    trajectories near the ego and of every vehicle (each timed apart), and write two run folders for the viewer."""
    spec = load_scenario(REPO / "scenarios" / "highway_dense.toml")
    network = RoadNetwork.from_file(spec.net_file)
    plain = Auditor(network, param_resolver(spec), "bench", trace_class=EGO_CLASS, signal_rule=spec.rss.signal_rule)
    traced = Auditor(network, param_resolver(spec), "bench", trace_class=EGO_CLASS, signal_rule=spec.rss.signal_rule,
                     record_states=True)
    near, every = TrajectoryRecorder(spec.net_file, NEAR_EGO_M), TrajectoryRecorder(spec.net_file)
    walls = {name: [] for name in ("step", "audit", "audit_with_states", "record_near_ego", "record_all")}
    counts = []
    with Session(spec) as session:
        while not session.finished:
            t0 = time.perf_counter()
            snapshot = session.step()
            t1 = time.perf_counter()
            plain.observe(snapshot, session.new_collisions)
            t2 = time.perf_counter()
            traced.observe(snapshot, session.new_collisions)
            t3 = time.perf_counter()
            near.add(snapshot)
            t4 = time.perf_counter()
            every.add(snapshot)
            t5 = time.perf_counter()
            for name, wall in zip(walls, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4)):
                walls[name].append(wall)
            counts.append(len(snapshot))
    result = traced.finish()
    for name, recorder in (("all", every), ("near", near)):
        (folder / name).mkdir()
        result.to_csv(folder / name)
        recorder.write(folder / name / TRAJECTORY_FILE)
    mean = {name: float(np.mean(w)) * 1e6 for name, w in walls.items()}
    return {"steps": len(counts), "peak_vehicles": max(counts), "mean_vehicles": float(np.mean(counts)),
            "episodes": len(result.episodes), "episode_state_rows": len(result.episode_states.time),
            "us_per_step": mean,
            "recording_share_of_step_and_audit": (mean["record_near_ego"] + mean["audit_with_states"] - mean["audit"])
            / (mean["step"] + mean["audit"])}


def browser_cpu_s() -> float:
    """[s] user + system CPU time so far of every process below this one (the browser, its driver), 0 without /proc."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = entry.read_text().rsplit(")", 1)[1].split()
        except OSError:  # it ended meanwhile
            continue
        children.setdefault(int(fields[1]), []).append(int(entry.parent.name))
    total, todo = 0, list(children.get(os.getpid(), []))
    while todo:
        pid = todo.pop()
        todo += children.get(pid, [])
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime [clock ticks]
    return total / os.sysconf("SC_CLK_TCK")


def measure_page(browser, page_file: Path) -> dict:
    started = time.perf_counter()
    page = open_view(browser, page_file)
    wall = time.perf_counter() - started
    figures = {"load_s": page.evaluate("sumoRssViewer.loadMs") / 1000.0, "load_wall_s": wall,
               "console_errors": len(page.errors)}
    for name, setup in (("follow_ego", "sumoRssViewer.follow('ego'); sumoRssViewer.seek(1200)"),
                        ("whole_network", "document.getElementById('fit').click(); sumoRssViewer.seek(1200)")):
        page.evaluate(setup)
        frames, cpu = page.evaluate("sumoRssViewer.stats.frames"), browser_cpu_s()
        page.evaluate("sumoRssViewer.play(1)")
        page.wait_for_timeout(PLAY_S * 1000)
        page.evaluate("sumoRssViewer.pause()")
        cpu, drawn = browser_cpu_s() - cpu, page.evaluate("sumoRssViewer.stats.frames") - frames
        ms = np.array(page.evaluate(f"sumoRssViewer.stats.renderMs.slice(-{drawn})"))
        figures[name] = {"fps": drawn / PLAY_S, "script_ms_median": float(np.median(ms)),
                         "script_ms_p95": float(np.percentile(ms, 95)), "browser_cpu_ms_per_frame": cpu * 1e3 / drawn}
    page.close()
    return figures


def main() -> None:
    options = arguments(__doc__, "viewer.py")
    with tempfile.TemporaryDirectory(prefix="bench-viewer-") as tmp:
        folder = Path(tmp)
        figures = {"recording": record_run(folder)}
        for name in ("all", "near"):
            started = time.perf_counter()
            page = write_view(folder / name)
            figures[f"write_view_s_{name}"] = time.perf_counter() - started
            figures[f"view_mb_{name}"] = page.stat().st_size / 1e6
        figures["targets"] = {"file_under_20_mb": figures["view_mb_all"] < 20.0}
        reason = missing_browser()
        if reason is None:
            with headless_chromium() as browser:
                page = figures["browser_all"] = measure_page(browser, folder / "all" / "view.html")
            slowest = min(page["follow_ego"]["fps"], page["whole_network"]["fps"])
            figures["targets"].update(load_under_3_s=page["load_s"] < 3.0, plays_at_30_fps=slowest >= 30.0)
        else:
            figures["browser_all"] = f"not measured: {reason}"
    record("viewer", figures, options)
    rec = figures["recording"]
    print(f"recording per step [us]: {', '.join(f'{k} {v:.0f}' for k, v in rec['us_per_step'].items())}; "
          f"view {figures['view_mb_all']:.1f} MB (near the ego: {figures['view_mb_near']:.1f} MB); "
          f"in the browser: {figures['browser_all']}")


if __name__ == "__main__":
    main()
