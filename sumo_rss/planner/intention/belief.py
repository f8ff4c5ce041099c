"""The learned belief CFB uses where lanes branch (epsilon.md port decision 1): the intention network's
P(candidate) summed per lateral class (keep / left / right, cfb.INTENTIONS order).

``LearnedBelief`` remembers each vehicle's recent positions (one entry per planning call) for the network's
past-trajectory input; a vehicle seen for less than the history span gets the missing past extrapolated
backwards at its current speed and heading. Only agents whose own lane branches within the candidates' range (a
junction approach with several turns) or ends (an acceleration lane) are given to the network, as in its
training data; everywhere else the rules stay.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from ...road.network import RoadNetwork
from ...sim.snapshot import WorldSnapshot
from .estimator import IntentionEstimator
from .features import HISTORY_DT, HISTORY_STEPS, CandidateFinder, history_in_agent_frame

MEMORY_SPARE = 2  # planning calls remembered beyond those the history spans (a late or skipped call)


class LearnedBelief:
    def __init__(self, network: RoadNetwork, estimator: IntentionEstimator, period: float = 0.1):
        """``period`` [s]: between two planning calls (the co-simulation step x replan_every); the memory holds
        the calls of the whole history (2 s), however often the planner is called (a fixed 33 calls covered it
        only up to ~16 Hz)."""
        torch.set_num_threads(1)  # the planner runs on one core; tiny batches gain nothing from threads
        self.network = network
        self.estimator = estimator
        self.finder = CandidateFinder(network)
        self.memory = math.ceil((HISTORY_STEPS - 1) * HISTORY_DT / period - 1e-9) + 1 + MEMORY_SPARE  # calls
        self._row: dict[str, int] = {}  # vehicle id → row of the memory
        self._memory = np.full((0, self.memory, 4), np.nan)  # [rows, memory, (time, x, y, signals)], a ring per row
        self._calls = 0
        self._branches: dict[int, bool] = {}

    def observe(self, snapshot: WorldSnapshot) -> None:
        """Remember every vehicle's position and signals at ``snapshot.time``; forget the vehicles that have left."""
        ids = snapshot.ids.tolist()
        present = set(ids)
        kept = {vid: row for vid, row in self._row.items() if vid in present}
        free = sorted(set(range(self._memory.shape[0])) - set(kept.values()))
        new = [vid for vid in ids if vid not in kept]
        if len(new) > len(free):
            grow = np.full((len(new) - len(free), self.memory, 4), np.nan)
            free += list(range(self._memory.shape[0], self._memory.shape[0] + grow.shape[0]))
            self._memory = np.concatenate([self._memory, grow])
        for vid, row in zip(new, free):
            kept[vid] = row
            self._memory[row] = np.nan
        self._row = kept
        rows = np.array([kept[vid] for vid in ids], dtype=int)
        column = self._calls % self.memory
        self._memory[rows, column] = np.column_stack([np.full(len(ids), snapshot.time), snapshot.x, snapshot.y,
                                                      snapshot.signals])
        self._calls += 1

    def branches(self, lane: int) -> bool:
        """Whether an agent on ``lane`` has more than one way ahead along it, or its lane ends."""
        if lane not in self._branches:
            paths = self.finder.paths(lane)
            self._branches[lane] = len(paths) > 1 or any(ends for _, _, ends in paths)
        return self._branches[lane]

    def lateral_probabilities(self, snapshot: WorldSnapshot, rows: np.ndarray,
                              lanes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P(keep, left, right) [n, 3], used [n] bool) for snapshot ``rows`` on ``lanes``; ``used`` is False for
        the agents left to the rules (no branching lane, no branch within the candidates' range, or a single
        candidate)."""
        probs = np.zeros((rows.size, 3))
        used = np.array([self.branches(int(k)) for k in lanes], dtype=bool)
        if not used.any():
            return probs, used
        sel = rows[used]
        x, y, heading = snapshot.x[sel], snapshot.y[sel], snapshot.heading[sel]
        cand = self.finder.candidates(lanes[used], x, y, heading)
        past_x, past_y, past_signals = self._history(snapshot, sel)
        p = self.estimator.probabilities(history_in_agent_frame(past_x, past_y, past_signals, x, y, heading), cand)
        for cls in range(3):
            probs[used, cls] = np.sum(np.where(cand.lateral == cls, p, 0.0), axis=1)
        # As in training: several candidates, and several ways ahead within the candidates' range or a lane end.
        # Far before a junction the turns still coincide; the network has not seen such samples.
        used[used] = (cand.mask.sum(axis=1) > 1) & cand.branching()
        return probs, used

    def _history(self, snapshot: WorldSnapshot, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """[n, HISTORY_STEPS] positions and signals at now − k·HISTORY_DT: positions interpolated in memory and,
        before the first remembered one, extrapolated back from it at the current speed and heading; signals as
        last seen at or before each time (the first remembered ones before memory). A vehicle not yet observed
        drives straight at its current speed with its current signals."""
        n = rows.size
        want = snapshot.time - HISTORY_DT * np.arange(HISTORY_STEPS)[::-1]  # [H]
        memory = np.full((n, self.memory, 4), np.nan)
        known = np.array([self._row.get(vid, -1) for vid in snapshot.ids[rows].tolist()], dtype=int)
        chronological = (self._calls + np.arange(self.memory)) % self.memory  # oldest column first
        memory[known >= 0] = self._memory[known[known >= 0]][:, chronological]
        now = np.column_stack([np.full(n, snapshot.time), snapshot.x[rows], snapshot.y[rows], snapshot.signals[rows]])
        unseen = np.isnan(memory[:, -1, 0])
        memory[unseen, -1] = now[unseen]
        times = memory[..., 0]
        first = np.argmax(~np.isnan(times), axis=1)  # [n] oldest remembered column (NaN columns come first)
        before = np.sum(times[:, None, :] <= want[None, :, None] + 1e-9, axis=2)  # [n, H] columns at or before
        at = np.maximum(first[:, None] + before - 1, first[:, None])
        nxt = np.minimum(at + 1, self.memory - 1)
        i = np.arange(n)[:, None]
        t0, t1 = times[i, at], times[i, nxt]
        frac = np.clip(np.where(t1 > t0, (want[None, :] - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0), 0.0, 1.0)
        back = np.maximum(times[np.arange(n), first][:, None] - want[None, :], 0.0) * snapshot.speed[rows][:, None]
        heading = snapshot.heading[rows][:, None]
        past_x = memory[i, at, 1] + frac * (memory[i, nxt, 1] - memory[i, at, 1]) - back * np.cos(heading)
        past_y = memory[i, at, 2] + frac * (memory[i, nxt, 2] - memory[i, at, 2]) - back * np.sin(heading)
        return past_x, past_y, memory[i, at, 3].astype(int)
