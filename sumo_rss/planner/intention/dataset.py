"""Labelled intention samples from real libsumo runs of the shipped scenarios (issue 7).

One run = one scenario at one seed, without the ego (only SUMO's own traffic). Every ``SAMPLE_EVERY`` seconds
each vehicle with ``HISTORY_STEPS`` of past and ``FUTURE`` seconds of future on the road gives one sample: its
past trajectory and candidate centrelines (features.py) and, as target, the set of candidates that pass where
it actually is ``FUTURE`` seconds later: the nearest one and every other within ``SAME_PATH_M`` of it (a car
that keeps its lane on an approach is still on both its straight and its right-turn path then; which of them it
takes is not known yet, but that it did not change lanes is). Samples with a single candidate, or whose target
is every candidate (nothing decided yet), are left out. By default only the samples where lanes branch are
kept (:func:`~.features.lanes_branch`: where CFB uses the network; elsewhere it keeps the rules). Deterministic given
scenario and seed (SUMO's seed); saved as compressed numpy arrays.
"""
from __future__ import annotations

import dataclasses
import multiprocessing as mp
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from ...errors import ScenarioError
from ...files import atomic_path
from ...road.network import RoadNetwork
from ...scenario import ScenarioSpec, load_scenario
from .features import (HISTORY_DT, HISTORY_FEATURES, HISTORY_STEPS, LANE_POINTS, MAX_CANDIDATES, SAME_PATH_M,
                       CandidateFinder, distance_to_candidates, history_in_agent_frame)

SAMPLE_EVERY = 0.5  # [s]
FUTURE = 3.0  # [s] the target is the candidates followed this much later
OFF_ROAD_M = 3.0  # [m] a future point farther than this from every candidate (a teleport) gives no target
FAMILIES = {"intersection_tls": "intersection", "intersection_priority": "intersection", "merge": "merge",
            "highway": "highway"}
ARRAYS = ("history", "lanes", "mask", "lateral", "target", "offset", "lat_speed", "to_lane_end", "family",
          "scenario", "seed", "time")


def check_step(step_s: float, source: object) -> None:
    """ScenarioError naming ``source`` unless the step ``step_s`` [s] divides the history spacing, the sampling
    period and the horizon (0.25 s made the history 0.25 s apart, 0.5 s divided by zero)."""
    steps = np.array([HISTORY_DT, SAMPLE_EVERY, FUTURE]) / step_s
    if np.any(np.round(steps) < 1) or np.any(np.abs(steps - np.round(steps)) > 1e-6):
        raise ScenarioError(source, "step_s", f"intention samples need a step [s] that divides {HISTORY_DT:g} s (the "
                            f"history's spacing), {SAMPLE_EVERY:g} s (sampling) and {FUTURE:g} s (horizon), e.g. 0.1 "
                            "or 0.05", step_s)


def family_of(network: str) -> str:
    """Scenario family of a network name ('intersection', 'merge', 'highway')."""
    return FAMILIES.get(network, network)


def record_run(spec: ScenarioSpec, all_samples: bool = False) -> dict[str, np.ndarray]:
    """Run ``spec`` without its ego in libsumo and return the samples (arrays named as in ``ARRAYS``); with
    ``all_samples`` also those where lanes do not branch."""
    from ...sim.session import Session  # libsumo is imported only where SUMO runs

    spec = dataclasses.replace(spec, ego=None)
    steps: list[tuple[float, np.ndarray, ...]] = []
    with Session(spec) as session:
        while not session.finished:
            snap = session.step()
            steps.append((snap.time, snap.ids, snap.x, snap.y, snap.heading, snap.lane_id, snap.lat_pos,
                          snap.lat_speed, snap.signals))
    return samples_from_steps(RoadNetwork.from_file(spec.net_file), steps, spec.step_s, spec.name, spec.seed,
                              family_of(spec.network), all_samples)


def samples_from_steps(network: RoadNetwork, steps: list, step_s: float, scenario: str, seed: int,
                       family: str, all_samples: bool = False) -> dict[str, np.ndarray]:
    """Samples from per-step records (time, ids, x, y, heading, lane_id, lat_pos, lat_speed, signals) of one
    run."""
    ids = sorted({vid for rec in steps for vid in rec[1]})
    code = {vid: i for i, vid in enumerate(ids)}
    shape = (len(ids), len(steps))
    x, y, heading, offset, lat_speed = (np.full(shape, np.nan) for _ in range(5))
    lane, signals = np.full(shape, -1, dtype=int), np.zeros(shape, dtype=int)
    for t, (_, vids, vx, vy, vh, vlane, vlat, vls, vsig) in enumerate(steps):
        rows = np.array([code[v] for v in vids], dtype=int)
        if rows.size == 0:
            continue
        x[rows, t], y[rows, t], heading[rows, t] = vx, vy, vh
        offset[rows, t], lat_speed[rows, t], signals[rows, t] = vlat, vls, vsig
        lane[rows, t] = network.lane_indices(vlane)
    times = np.array([rec[0] for rec in steps])
    check_step(step_s, scenario)
    every, back, ahead = (round(v / step_s) for v in (SAMPLE_EVERY, HISTORY_DT, FUTURE))
    past = np.arange(-(HISTORY_STEPS - 1) * back, 1, back)  # step offsets of the history, oldest first
    t_idx = np.arange(-past[0], len(steps) - ahead)
    t_idx = t_idx[np.round(times[t_idx] / step_s).astype(int) % every == 0]
    present = ~np.isnan(x)
    ok = np.all(present[:, t_idx[:, None] + past[None, :]], axis=2) & present[:, t_idx + ahead]  # [V, T]
    veh, col = np.nonzero(ok)
    t = t_idx[col]
    cand = CandidateFinder(network).candidates(lane[veh, t], x[veh, t], y[veh, t], heading[veh, t])
    dist = distance_to_candidates(cand.world, cand.mask, x[veh, t + ahead], y[veh, t + ahead])
    nearest = dist.min(axis=1)
    target = dist < nearest[:, None] + SAME_PATH_M  # padding (inf) never
    real = cand.mask.sum(axis=1)
    decided = (real >= 2) & (nearest <= OFF_ROAD_M) & (target.sum(axis=1) < real)
    keep = np.flatnonzero(decided & (all_samples | cand.branching()))
    veh, t = veh[keep], t[keep]
    hist_t = t[:, None] + past[None, :]
    history = history_in_agent_frame(x[veh[:, None], hist_t], y[veh[:, None], hist_t],
                                     signals[veh[:, None], hist_t], x[veh, t], y[veh, t], heading[veh, t])
    n = keep.size
    return {
        "history": history.astype(np.float32),
        "lanes": cand.lanes[keep].astype(np.float32),
        "mask": cand.mask[keep],
        "lateral": cand.lateral[keep].astype(np.int8),
        "target": target[keep],
        "offset": offset[veh, t].astype(np.float32),
        "lat_speed": lat_speed[veh, t].astype(np.float32),
        "to_lane_end": cand.to_lane_end[keep],
        "family": np.full(n, family),
        "scenario": np.full(n, scenario),
        "seed": np.full(n, seed, dtype=np.int64),
        "time": times[t],
    }


def concatenate(parts: Iterable[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    parts = list(parts)
    if not parts:
        return empty()
    return {name: np.concatenate([p[name] for p in parts]) for name in ARRAYS}


def empty() -> dict[str, np.ndarray]:
    return {"history": np.zeros((0, HISTORY_STEPS, HISTORY_FEATURES), np.float32),
            "lanes": np.zeros((0, MAX_CANDIDATES, LANE_POINTS, 3), np.float32),
            "mask": np.zeros((0, MAX_CANDIDATES), bool), "lateral": np.zeros((0, MAX_CANDIDATES), np.int8),
            "target": np.zeros((0, MAX_CANDIDATES), bool), "offset": np.zeros(0, np.float32),
            "lat_speed": np.zeros(0, np.float32), "to_lane_end": np.zeros(0),
            "family": np.zeros(0, str), "scenario": np.zeros(0, str), "seed": np.zeros(0, np.int64),
            "time": np.zeros(0)}


def _record(job: tuple[str, int, float | None, bool]) -> dict[str, np.ndarray]:
    path, seed, duration, all_samples = job
    spec = dataclasses.replace(load_scenario(path), ego=None)
    return record_run(spec.with_overrides(seed=seed, duration_s=duration), all_samples)


def generate(scenarios: list[Path], seeds: Iterable[int], *, duration_s: float | None = None, workers: int = 1,
             all_samples: bool = False, progress: Callable[[], None] | None = None) -> dict[str, np.ndarray]:
    """Samples of every (scenario file, seed), recorded in ``workers`` spawned processes (libsumo allows one
    simulation per process); in (scenario, seed) order whatever the number of workers."""
    jobs = [(str(p), int(s), duration_s, all_samples) for p in scenarios for s in seeds]
    ctx = mp.get_context("spawn")
    with ctx.Pool(max(1, min(workers, len(jobs)))) as pool:
        parts = []
        for part in pool.imap(_record, jobs):
            parts.append(part)
            if progress is not None:
                progress()
    return concatenate(parts)


def save(data: dict[str, np.ndarray], path: Path) -> None:
    """Write ``data`` as a compressed .npz atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **data)


def load(path: Path) -> dict[str, np.ndarray]:
    """Read a dataset written by :func:`save`; a missing array is an error naming the file and the array."""
    with np.load(path, allow_pickle=False) as f:
        missing = [name for name in ARRAYS if name not in f.files]
        if missing:
            raise ValueError(f"{path}: not an intention dataset (missing arrays: {', '.join(missing)})")
        return {name: f[name] for name in ARRAYS}
