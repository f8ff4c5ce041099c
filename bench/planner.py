"""EPSILON planner benchmarks, one function per figure family, in two parts (``--part``): the timed ones (``jit``,
``families``, ``cycle``; recorded under ``planner``, to be run with the machine alone) and the driving ones
(``closed_loop_highway_dense``, ``ego_comparison``; recorded under ``planner_driving``: the runs are deterministic, so
the load does not change them):

- ``jit``: :func:`jit_times`, the forward-simulation kernel's compile time on a fresh numba cache (a fresh clone's
  first run) and its load time from the cache, each as the first plan() of a process.
- ``families``: :func:`family_figures` per scenario family of FAMILIES, one closed-loop run with the EPSILON ego
  planning every step at 10 Hz and the every-pair audit: planning-cycle median / p95 / p99 over the cycles with
  <= KEY_AGENTS_MAX key agents (and over all cycles), the key-agent counts, and the real-time factor from the ego's
  departure (incl. writing the outputs). Add a family by adding its scenario name to FAMILIES (bench/_ego_comparison.py).
- ``cycle``: :func:`cycle_times`, the cycle with 10 / 20 / 40 key agents on synthetic highway snapshots (the full
  cycle and its motion-layer part).
- ``closed_loop_highway_dense``: :func:`compare_controllers`, ego speed / responsibility / RMS jerk of the epsilon
  (with and without the SSC motion layer, and planning every second step), sumo and mpdm controllers on the same
  highway_dense seeds.
- ``ego_comparison``: :func:`_ego_comparison.compare`, epsilon vs sumo vs sumo_restricted vs mpdm side by side on
  every family and seeds SEEDS in one batch (route travel time, settled mean speed, responsible episodes and
  seconds, lane changes, merge delay; per seed and summed up).

Targets: issue 48: a cycle with <= 20 key agents median <= 15 ms and p99 <= 40 ms on every family; closed loop
>= 5x real time on highway_dense and >= 4x on intersection_tls and merge_onramp; a fresh clone's first run compiles
for <= 30 s. Issue 5: ego mean speed >= the sumo baseline's on the same seeds while never responsible. Issue 6:
lower RMS jerk with SSC than with the behaviour trajectory. For reading the speed comparison, each run also gives
the ego's mean speed from SETTLED_S after its insertion (without the response to where it was inserted) and how
long the ego was responsible, summed over its episodes (which may overlap) [s].
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _ego_comparison import FAMILIES, compare  # noqa: E402
from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.batch.runner import run_one  # noqa: E402
from sumo_rss.planner.epsilon import EpsilonPlanner, PlannerConfig  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.rss.auditor import ParamResolver  # noqa: E402
from sumo_rss.sim.snapshot import WorldSnapshot  # noqa: E402

RTF_TARGETS = {"highway_dense": 5.0, "intersection_tls": 4.0, "merge_onramp": 4.0}  # closed loop, x real time
FAMILY_S = 150.0  # simulated seconds of a family's closed-loop run (the ego departs at 20-30 s)
FAMILY_SEED = 0
KEY_AGENTS_MAX = 20  # the cycle targets hold for cycles with at most this many key agents
CYCLE_MEDIAN_MS, CYCLE_P99_MS, JIT_S = 15.0, 40.0, 30.0
CYCLES = 60
WARMUP_CYCLES = 3  # not timed: they build the planner's caches
REPEATS = 3  # passes of the cycle benchmark, best of (machine noise)
SEEDS = (0, 1, 2)
CLOSED_LOOP_S = 150.0  # simulated seconds per comparison run (the ego departs at 30 s)
SETTLED_S = 20.0  # [s] after the ego's insertion (its first trace row; SUMO may insert it after depart_s)
LANES_Y = (-8.75, -5.25, -1.75)  # hw0 lane centres
SLOT_M = 14.5  # [m] between the slots of one lane in the synthetic snapshots (4.5 m cars, 1 m jitter each)
# The compared egos: name -> (scenario controller, [ego.planner] settings). epsilon_replan2 plans every second
# step (5 Hz, the executed trajectory and the RSS guard still every step): measured for the owner's choice on the
# 5x target, which is judged on the default (every step, epsilon.md port decision 6).
VARIANTS = {"epsilon": ("epsilon", {}), "epsilon_behaviour": ("epsilon", {"motion_layer": False}),
            "epsilon_replan2": ("epsilon", {"replan_every": 2}), "sumo": ("sumo", {}), "mpdm": ("mpdm", {})}
EGO_CLEAR_M = 30.0  # [m] no synthetic car this near the ego in its lane (centre to centre): a 1 s gap at 25 m/s


def synthetic_snapshot(agents: int, rng: np.random.Generator) -> WorldSnapshot:
    """The ego at x = 600 m in the middle lane of hw0 at 25 m/s; ``agents`` cars on the three lanes from 100 m
    behind to 160 m ahead, some drifting towards a lane boundary (uncertain intentions). A plausible traffic
    state: each car takes a distinct slot of its lane (slots SLOT_M apart: bumper gaps >= 8 m), and none is in
    the ego's lane from EGO_CLEAR_M behind to EGO_CLEAR_M ahead of it. Cars placed anywhere overlapped the ego
    or stood a few metres from it in most cycles, and the motion layer failed there (corridor blocked)."""
    n = agents + 1
    slots = np.arange(-100.0, 160.0 + 1e-9, SLOT_M)
    free = [(k, at) for k in range(3) for at in slots if k != 1 or abs(at) >= EGO_CLEAR_M]
    if agents > len(free):
        raise ValueError(f"at most {len(free)} agents fit the synthetic road, asked for {agents}")
    taken = np.array(free)[np.sort(rng.choice(len(free), agents, replace=False))]
    x = np.concatenate([[600.0], 600.0 + taken[:, 1] + rng.uniform(-1.0, 1.0, agents)])
    lane = np.concatenate([[1], taken[:, 0].astype(int)])
    drift = np.concatenate([[0.0], rng.choice([0.0, 0.0, 0.6, -0.6], agents)])
    y = np.array(LANES_Y)[lane] + drift
    speed = np.concatenate([[25.0], rng.uniform(18.0, 30.0, agents)])
    z = np.zeros(n)
    lat_speed = np.sign(drift) * 0.5
    return WorldSnapshot(time=40.0, ids=np.array([f"v{i}" for i in range(n)]), x=x, y=y, heading=z.copy(),
                         speed=speed, accel=z.copy(), lat_speed=lat_speed, length=np.full(n, 4.5),
                         width=np.full(n, 1.8), lane_id=np.array([f"hw0_{k}" for k in lane]),
                         edge_id=np.full(n, "hw0"), lane_index=lane, lane_pos=x, lat_pos=drift,
                         vclass=np.array(["ego"] + ["background"] * agents), vtype=np.full(n, "car"),
                         signals=np.zeros(n, int), route_index=np.zeros(n, int),
                         route_edges=tuple(("hw0", "hw1", "hw2") for _ in range(n)))


def cycle_times(network: RoadNetwork, agents: int) -> dict:
    """The planning cycle over CYCLES synthetic snapshots, best (lowest median) of REPEATS passes over the same
    snapshots: one pass on this 2-core host read 43.6 ms where four more read 32.8-35.9 ms."""
    return min((_cycle_pass(network, agents) for _ in range(REPEATS)), key=lambda figures: figures["median_ms"])


def _cycle_pass(network: RoadNetwork, agents: int) -> dict:
    rng = np.random.default_rng(agents)
    times, motion, scenarios, key = [], [], [], []
    # One planner for all cycles, as in a run: its planning frame is built once per lane and route and cached.
    planner = EpsilonPlanner(network, ParamResolver(), PlannerConfig(desired_speed=30.0))
    for k in range(CYCLES):
        if k == WARMUP_CYCLES:  # the motion outcomes of the cycles timed below
            warm = dict(planner.motion.stats.outcomes)
        snapshot = synthetic_snapshot(agents, rng)
        started = time.perf_counter()
        result = planner.plan(snapshot, "v0")
        times.append(time.perf_counter() - started)
        motion.append(result.timings["motion"])
        scenarios.append(result.scenarios)
        key.append(result.agents)
    ms = np.array(times[WARMUP_CYCLES:]) * 1000.0  # the first cycles build caches
    ssc = np.array(motion[WARMUP_CYCLES:]) * 1000.0
    outcomes = {name: count - warm.get(name, 0) for name, count in planner.motion.stats.outcomes.items()
                if count > warm.get(name, 0)}
    behaviour = ms - ssc
    return {"key_agents_mean": float(np.mean(key)), "scenarios_mean": float(np.mean(scenarios)),
            "median_ms": float(np.median(ms)), "p95_ms": float(np.percentile(ms, 95)),
            "p99_ms": float(np.percentile(ms, 99)), "behaviour_median_ms": float(np.median(behaviour)),
            "behaviour_p99_ms": float(np.percentile(behaviour, 99)), "ssc_median_ms": float(np.median(ssc)),
            "ssc_p99_ms": float(np.percentile(ssc, 99)), "motion_outcomes": outcomes}


def jit_times() -> dict:
    """The first plan() of a process on an empty numba cache (the kernel compiles: a fresh clone's first run) and
    then on that cache (it loads), each in its own process [s, wall and CPU]."""
    code = ("import sys, time; sys.path.insert(0, %r); import numpy as np; from planner import synthetic_snapshot, "
            "first_plan_seconds; print(*first_plan_seconds())" % str(Path(__file__).resolve().parent))
    cache = tempfile.mkdtemp(prefix="sumo_rss_numba_")
    try:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(REPO)}
        runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
                for _ in range(2)]
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    (cold_wall, cold_cpu), (warm_wall, warm_cpu) = (map(float, run.stdout.split()) for run in runs)
    return {"first_plan_empty_cache_s": cold_wall, "first_plan_empty_cache_cpu_s": cold_cpu,
            "first_plan_cached_s": warm_wall, "first_plan_cached_cpu_s": warm_cpu,
            "compile_s": cold_wall - warm_wall, "compile_cpu_s": cold_cpu - warm_cpu}


def first_plan_seconds() -> tuple[float, float]:
    """Wall and CPU seconds of a new planner's first plan() on a synthetic snapshot with 20 agents."""
    network = RoadNetwork.from_file(REPO / "networks" / "highway" / "highway.net.xml")
    planner = EpsilonPlanner(network, ParamResolver(), PlannerConfig(desired_speed=30.0))
    snapshot = synthetic_snapshot(20, np.random.default_rng(20))
    wall, cpu = time.perf_counter(), time.process_time()
    planner.plan(snapshot, "v0")
    return time.perf_counter() - wall, time.process_time() - cpu


@contextlib.contextmanager
def recorded_cycles() -> Iterator[list[tuple[float, int]]]:
    """(seconds, key agents) of every EpsilonPlanner.plan() call while open."""
    cycles: list[tuple[float, int]] = []
    plan = EpsilonPlanner.plan

    def timed(self: EpsilonPlanner, *args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        started = time.perf_counter()
        result = plan(self, *args, **kwargs)
        cycles.append((time.perf_counter() - started, result.agents))
        return result
    EpsilonPlanner.plan = timed
    try:
        yield cycles
    finally:
        EpsilonPlanner.plan = plan


def family_figures(family: str) -> dict:
    """One closed-loop run of ``family`` (seed FAMILY_SEED, FAMILY_S s) with the EPSILON ego planning every step:
    cycle times [ms] over the cycles with <= KEY_AGENTS_MAX key agents and over all, the key agents, and the
    real-time factor from the ego's departure."""
    spec = load_scenario(REPO / "scenarios" / f"{family}.toml").with_overrides(seed=FAMILY_SEED,
                                                                              duration_s=FAMILY_S)
    spec = replace(spec, ego=replace(spec.ego, controller="epsilon"))
    with recorded_cycles() as cycles:
        run = _closed_loop_run(spec)
    seconds, agents = (np.array(column) for column in zip(*cycles[WARMUP_CYCLES:]))
    ms = seconds * 1000.0
    within = ms[agents <= KEY_AGENTS_MAX]
    return {"cycles": int(ms.size), "cycles_le_20_agents": int(within.size),
            "key_agents_mean": float(agents.mean()), "key_agents_max": int(agents.max()),
            "median_ms": float(np.median(within)), "p95_ms": float(np.percentile(within, 95)),
            "p99_ms": float(np.percentile(within, 99)), "all_median_ms": float(np.median(ms)),
            "all_p99_ms": float(np.percentile(ms, 99)), "real_time_factor_with_ego": run["real_time_factor_with_ego"],
            "ego_responsible_episodes": run["ego_responsible_episodes"], "ego_collisions": run["ego_collisions"]}


def closed_loop(variant: str, seed: int) -> dict:
    """highway_dense with the ego of ``variant`` (a key of VARIANTS)."""
    spec = load_scenario(REPO / "scenarios" / "highway_dense.toml").with_overrides(seed=seed,
                                                                                  duration_s=CLOSED_LOOP_S)
    controller, planner_settings = VARIANTS[variant]
    planner = replace(spec.ego.planner, **planner_settings)
    return _closed_loop_run(replace(spec, ego=replace(spec.ego, controller=controller, planner=planner)))


def _closed_loop_run(spec) -> dict:  # noqa: ANN001 (a ScenarioSpec)
    out = Path(tempfile.mkdtemp(prefix="sumo_rss_bench_"))
    departed: list[float] = []  # wall clock when the simulation reached the ego's departure time

    def clock(simulated: float) -> None:
        if not departed and simulated >= spec.ego.depart_s - 1e-9:
            departed.append(time.perf_counter())

    try:
        summary = run_one(spec, out, on_step=clock)
        finished = time.perf_counter()
        trace = pd.read_csv(next(out.rglob("ego_trace.csv")))
        episodes = pd.read_csv(next(out.rglob("episodes.csv")))
    finally:
        shutil.rmtree(out, ignore_errors=True)
    settled = trace["speed_ms"][trace["time_s"] >= trace["time_s"].iloc[0] + SETTLED_S]
    ego, who = summary.ego_id, episodes["responsible"]
    ego_responsible = ((episodes["vehicle_a"] == ego) & who.isin(["a", "both"])) | \
        ((episodes["vehicle_b"] == ego) & who.isin(["b", "both"]))
    responsible_s = float(episodes["duration_s"][ego_responsible].sum())
    ego_collisions = sum(summary.ego_id in (c["collider"], c["victim"]) for c in summary.collision_events)
    planner = summary.planner or {}
    with_ego = (summary.sim_time_s - spec.ego.depart_s) / (finished - departed[0])  # incl. writing the outputs
    return {"real_time_factor": summary.real_time_factor, "real_time_factor_with_ego": with_ego,
            "ego_mean_speed_ms": summary.ego_mean_speed_ms,
            "ego_mean_speed_settled_ms": float(settled.mean()), "ego_responsible_s": responsible_s,
            "ego_responsible_episodes": summary.ego_responsible_episodes, "ego_collisions": ego_collisions,
            "lane_changes": planner.get("lane_changes_completed"), "cycle_ms_median": planner.get("cycle_ms_median"),
            "guard": planner.get("guard"), "rms_jerk_lon": planner.get("rms_jerk_lon"),
            "rms_jerk_lat": planner.get("rms_jerk_lat"), "motion": planner.get("motion")}


def compare_controllers() -> dict:
    """Every VARIANTS ego on highway_dense, seeds SEEDS: the runs, and the mean speeds and RMS jerks."""
    runs = {c: {str(seed): closed_loop(c, seed) for seed in SEEDS} for c in VARIANTS}
    speed, settled = ({c: float(np.mean([r[key] for r in by_seed.values()])) for c, by_seed in runs.items()}
                      for key in ("ego_mean_speed_ms", "ego_mean_speed_settled_ms"))
    jerk = {c: float(np.mean([r["rms_jerk_lon"] for r in runs[c].values()])) for c in ("epsilon", "epsilon_behaviour")}
    return {"runs": runs, "ego_mean_speed_ms": speed, "ego_mean_speed_settled_ms": settled, "ego_rms_jerk_lon": jerk}


def timing_targets(figures: dict) -> dict:
    """The targets of the timed part (``--part timing``): cycle times, closed-loop speed, the first compile."""
    families = figures["families"]
    return {
        "cycle_median_le_15ms_every_family": all(f["median_ms"] <= CYCLE_MEDIAN_MS for f in families.values()),
        "cycle_p99_le_40ms_every_family": all(f["p99_ms"] <= CYCLE_P99_MS for f in families.values()),
        "closed_loop_real_time": all(families[name]["real_time_factor_with_ego"] >= factor
                                     for name, factor in RTF_TARGETS.items() if name in families),
        "first_run_compiles_le_30s": figures["jit"]["compile_s"] <= JIT_S,
        "never_responsible": all(f["ego_responsible_episodes"] == 0 for f in families.values())}


def driving_targets(figures: dict) -> dict:
    """The targets of the driving part (``--part driving``), which do not depend on the machine's load."""
    comparison = figures["closed_loop_highway_dense"]
    return {
        "ssc_lowers_rms_jerk": comparison["ego_rms_jerk_lon"]["epsilon"] < comparison["ego_rms_jerk_lon"][
            "epsilon_behaviour"],
        "ego_speed_ge_sumo": comparison["ego_mean_speed_ms"]["epsilon"] >= comparison["ego_mean_speed_ms"]["sumo"],
        "never_responsible": all(r["ego_responsible_episodes"] == 0 for r in comparison["runs"]["epsilon"].values())}


def _part(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--part", choices=("timing", "driving", "all"), default="all",
                        help="timing: jit, families, cycle (recorded as 'planner'; needs the machine alone); "
                             "driving: the controller comparisons, deterministic whatever the load (recorded as "
                             "'planner_driving'); all: both (default)")


def main() -> None:
    options = arguments(__doc__, "planner.py", _part)
    if options.part in ("timing", "all"):
        network = RoadNetwork.from_file(REPO / "networks" / "highway" / "highway.net.xml")
        jit = jit_times()
        first_plan_seconds()  # this process compiles (after an edit of a kernel source) or loads its kernels untimed
        timing: dict = {"jit": jit, "families": {family: family_figures(family) for family in FAMILIES},
                        "cycle": {str(n): cycle_times(network, n) for n in (10, 20, 40)}}
        timing["targets"] = timing_targets(timing)
        record("planner", timing, options)
        print(json.dumps({key: timing[key] for key in ("jit", "families", "targets")}, indent=1))
    if options.part in ("driving", "all"):
        driving: dict = {"closed_loop_highway_dense": compare_controllers(),
                         "ego_comparison": compare(FAMILIES, seeds=SEEDS)}
        driving["targets"] = driving_targets(driving)
        record("planner_driving", driving, options)
        print(json.dumps(driving["targets"], indent=1))


if __name__ == "__main__":
    main()
