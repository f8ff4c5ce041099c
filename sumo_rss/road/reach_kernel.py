"""The look-up of :meth:`.reach.GraphReach.between`, compiled with numba: for each (source, target) pair a binary
search of the target among the nodes the source's search reached (its row of the store, sorted). numpy needed a
``unique`` of the sources, a concatenation of their rows and a ``searchsorted`` of one key per pair at every call
(~8 % of a Bologna city audit, a few hundred pairs a step); the loop reads the rows where they lie. The comparison
with the reach limit is numpy's (the source's length plus the reach, in float64). Units: m.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel


@kernel
def distances_between(source, target, start, count, nodes, distances, length, within):
    """[m] for pair i: the distance from the start of node ``source[i]`` to the start of node ``target[i]``, where
    the source's row (``nodes`` / ``distances`` from ``start[source[i]]``, ``count[source[i]]`` long, nodes sorted)
    holds the target within ``length[source[i]] + within`` of the source's start; inf elsewhere."""
    n = source.size
    out = np.full(n, np.inf)
    for i in range(n):
        s, t = source[i], target[i]
        lo, hi = start[s], start[s] + count[s]
        while lo < hi:  # the first node >= t
            mid = (lo + hi) // 2
            if nodes[mid] < t:
                lo = mid + 1
            else:
                hi = mid
        if lo < start[s] + count[s] and nodes[lo] == t and distances[lo] <= length[s] + within:
            out[i] = distances[lo]
    return out


@kernel
def joined_offsets(lane, ref, start, count, nodes, distances, length, within, lane_edge, lane_offset):
    """[m] for pair i: of the lanes that lane ``lane[i]``'s row reaches within ``length[lane[i]] + within`` (in
    lane order) on the edge of lane ``ref[i]``, the offset across the edge from ``ref[i]`` of the nearest (the first
    of equals): ``lane_offset[reached] - lane_offset[ref[i]]``; NaN where none of them is on that edge."""
    n = lane.size
    out = np.full(n, np.nan)
    for i in range(n):
        s, r = lane[i], ref[i]
        edge, best = lane_edge[r], np.inf
        for k in range(start[s], start[s] + count[s]):
            reached = nodes[k]
            if distances[k] <= length[s] + within and lane_edge[reached] == edge:
                offset = lane_offset[reached] - lane_offset[r]
                if abs(offset) < best:
                    best, out[i] = abs(offset), offset
    return out
