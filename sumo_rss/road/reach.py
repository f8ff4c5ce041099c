"""Shortest distances along a road graph within a horizon, searched from each source once, on first need.

The nodes are edges (or lanes) with lengths; going from a node to a successor costs the node's length, so a
distance runs from the start of the source to the start of the target. A search from a source stops at the
nodes that start farther than the horizon beyond the source's end: what lies beyond is no situation with a car
on the source (its path gap exceeds every safe distance the audit can ask, see :meth:`GraphReach.require`).
Memory is the sources asked about times what lies within the horizon of each, never nodes²: on MoST's Monaco
(18,732 edges), a 150 m horizon reaches ~60 edges from an edge.
"""
from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

HORIZON_STEP_M = 50.0  # [m] a horizon that must grow grows to a multiple of this, a quarter beyond what is asked


class ReachRows(NamedTuple):
    """The searches kept by a :class:`GraphReach`, laid end to end: source ``s``'s row is ``nodes`` (sorted) and
    ``distances`` [m] from ``start[s]`` (-1: not searched), ``count[s]`` long; what lies within ``length[s] + within``
    [m] of the source's start is what the look-ups see."""

    start: np.ndarray
    count: np.ndarray
    nodes: np.ndarray
    distances: np.ndarray
    length: np.ndarray
    within: float


class GraphReach:
    """Distances [m] from the start of a source node to the start of every node reached by following successors
    whose start lies within ``within`` [m] of the source's end (the source itself at 0): the reach the current
    step asks for (:meth:`require`). Searched per source (Dijkstra) on first need, up to ``horizon`` >= ``within``,
    and kept; the horizon only grows, which drops what was kept. What is looked up depends on ``within`` alone,
    never on how far earlier steps searched."""

    def __init__(self, successors: Sequence[Sequence[int]], length: np.ndarray):
        self._successors = successors
        self._lengths = np.asarray(length, dtype=float)
        self._length = self._lengths.tolist()  # Python floats: the search adds them one by one
        self.horizon = 0.0  # [m] how far the kept searches reach
        self.within = 0.0  # [m] how far the look-ups reach (the current step's)
        self._clear()

    def _clear(self) -> None:
        """Forget every search. The searches kept are rows of one store laid end to end (``_nodes``, sorted per
        row, and ``_distances``, filled up to ``_used``; grown by doubling): source ``s``'s row starts at
        ``_start[s]`` (-1: not searched) and is ``_count[s]`` long."""
        self._start = np.full(len(self._length), -1, dtype=np.int64)
        self._count = np.zeros(len(self._length), dtype=np.int64)
        self._nodes = np.zeros(0, dtype=np.int64)
        self._distances = np.zeros(0)
        self._used = 0

    def __getstate__(self) -> dict:
        """Pickled without what was searched (a cached road model starts afresh)."""
        return {"_successors": self._successors, "_lengths": self._lengths, "_length": self._length, "horizon": 0.0,
                "within": 0.0}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._clear()

    def require(self, horizon: float) -> None:
        """Make the look-ups reach ``horizon`` [m] beyond the source's end, searching farther if the kept searches
        do not reach that far (they are then dropped)."""
        self.within = horizon
        if horizon > self.horizon:
            self.horizon = math.ceil(1.25 * horizon / HORIZON_STEP_M) * HORIZON_STEP_M
            self._clear()

    def row(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        """(nodes reached from ``source`` within the look-ups' reach, sorted; their distances [m])."""
        nodes, distances = self._searched(source)
        keep = distances <= self._length[source] + self.within
        return nodes[keep], distances[keep]

    def _searched(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        """(nodes reached from ``source`` within the horizon, sorted; their distances [m])."""
        if self._start[source] < 0:
            self._search_missing(np.array([source], dtype=np.int64))
        start, stop = self._start[source], self._start[source] + self._count[source]
        return self._nodes[start:stop], self._distances[start:stop]

    def _search_missing(self, source: np.ndarray) -> None:
        """Search from every node of ``source`` not searched yet, and keep the rows in the store."""
        missing = source[self._start[source] < 0]
        if not missing.size:
            return
        missing = np.unique(missing).tolist()
        rows = [self._search(s) for s in missing]
        size = self._used + sum(len(nodes) for nodes, _ in rows)
        if size > len(self._nodes):
            capacity = max(size, 2 * len(self._nodes), 1024)
            self._nodes = np.concatenate([self._nodes[:self._used], np.zeros(capacity - self._used, np.int64)])
            self._distances = np.concatenate([self._distances[:self._used], np.zeros(capacity - self._used)])
        for s, (nodes, distances) in zip(missing, rows):
            self._start[s], self._count[s] = self._used, len(nodes)
            self._nodes[self._used:self._used + len(nodes)] = nodes
            self._distances[self._used:self._used + len(nodes)] = distances
            self._used += len(nodes)

    def rows(self, source: np.ndarray) -> ReachRows:
        """The kept searches, with those of every node of ``source`` (int64) searched where not yet: what the
        compiled look-ups (:mod:`.reach_kernel`) read."""
        self._search_missing(source)
        return ReachRows(self._start, self._count, self._nodes, self._distances, self._lengths, float(self.within))

    def between(self, source: np.ndarray, target: np.ndarray) -> np.ndarray:
        """[m] distance from each ``source`` node to each ``target`` node (index arrays of one length); inf where
        the target is not reached within the look-ups' reach (:func:`.reach_kernel.distances_between`)."""
        from .reach_kernel import distances_between  # numba: compiled at the first look-up

        source = np.asarray(source, dtype=np.int64)
        target = np.asarray(target, dtype=np.int64)
        if not source.size:
            return np.full(source.shape, np.inf)
        flat = source.reshape(-1)
        return distances_between(flat, target.reshape(-1), *self.rows(flat)).reshape(source.shape)

    def _search(self, source: int) -> tuple[np.ndarray, np.ndarray]:
        length, successors = self._length, self._successors
        limit = length[source] + self.horizon
        reached: dict[int, float] = {}
        best, queue = {source: 0.0}, [(0.0, source)]
        while queue:
            d, e = heapq.heappop(queue)
            if d > best[e]:
                continue
            reached[e] = d
            nd = d + length[e]
            if nd > limit:
                continue
            for f in successors[e]:
                if nd < best.get(f, math.inf):
                    best[f] = nd
                    heapq.heappush(queue, (nd, f))
        nodes = np.fromiter(reached.keys(), dtype=np.int64, count=len(reached))
        order = np.argsort(nodes)
        return nodes[order], np.fromiter(reached.values(), dtype=float, count=len(reached))[order]

