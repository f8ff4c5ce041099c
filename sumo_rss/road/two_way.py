"""Two-way roads: which pairs of edges are the two directions of one road, and how a lane of one maps onto a lane
of the other.

Two edges between the same nodes in opposite directions are not necessarily one road: OSM-derived nets join two
one-way streets round a block (22 m apart in Bologna's acosta, up to 194 m in Monaco) or a loop by the same node
pair. They are one road only if their shapes run side by side, against each other, within about a lane width,
along most of their length (:data:`BESIDE_SHARE`). For such a road the auditor frames a car of one direction in
the other's lane by the road's own geometry (lane-based, as on one edge): its position along its lane maps to the
other lane by the reversed path length, and across by the measured distance between the two lanes' centre lines.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frenet import LaneShapes

SAMPLES = 16  # points of a lane's centre line sampled to compare it with a lane of the other direction
BESIDE_SHARE = 0.5  # the share of both edges' lengths along which they must run side by side
ANTIPARALLEL_COS = -0.5  # two lanes run against each other where their headings are more than 120° apart
CHUNK_POINTS = 2048  # points sampled and projected at once (memory: points x shape points)


@dataclass(frozen=True, eq=False)
class TwoWayRoads:
    """Per normal edge e its opposite edge (``edge_opposite[e]``, -1 for none); per lane k of an edge with an
    opposite and lane index j of that opposite edge (NaN elsewhere): ``offset[k, j]`` [m] the lateral position of lane
    j's centre line in lane k's frame (+ = left), ``start[k, j]`` / ``end[k, j]`` [m] where lane j's start and end
    lie along lane k, as SUMO lane positions of lane k (start > end: the lanes run against each other)."""

    edge_opposite: np.ndarray
    offset: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def in_lane_frame(self, lane: np.ndarray, other_lane: np.ndarray, other_index: np.ndarray,
                      other_pos: np.ndarray, other_length: np.ndarray, other_d: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """(lane position [m], lateral offset [m], + = left) in the frames of lanes ``lane`` of points on lanes
        ``other_lane`` of the opposite edge (their lane index ``other_index``, SUMO length ``other_length``) at
        lane positions ``other_pos`` [m] and ``other_d`` [m] left of those lanes' centre lines."""
        start, end = self.start[lane, other_index], self.end[lane, other_index]
        pos = start + (end - start) * other_pos / other_length
        return pos, self.offset[lane, other_index] - other_d


def two_way_roads(candidates: list[tuple[int, int]], edge_lanes: list[list[int]], shapes: LaneShapes,
                  lane_width: np.ndarray, lane_index: np.ndarray, n_edges: int) -> TwoWayRoads:
    """The two-way roads among ``candidates`` (pairs of normal edges (e, f) between the same nodes in opposite
    directions, each pair once) and their lane-pair frames. ``edge_lanes[e]``: the lane indices of edge e."""
    n_lanes = len(lane_width)
    width = max((len(lanes) for lanes in edge_lanes), default=1)
    offset, start, end = (np.full((n_lanes, width), np.nan) for _ in range(3))
    opposite = np.full(n_edges, -1)
    # Every lane of one edge against every lane of the other, in both directions: (lane, other lane).
    pairs = np.array([(k, j) for e, f in candidates for a, b in ((e, f), (f, e))
                      for k in edge_lanes[a] for j in edge_lanes[b]], dtype=int).reshape(-1, 2)
    if not len(pairs):
        return TwoWayRoads(opposite, offset, start, end)
    beside, median = _compare(pairs[:, 0], pairs[:, 1], shapes, lane_width)
    k, j = pairs[:, 0], pairs[:, 1]
    tips = np.concatenate([shapes.points[j, 0], shapes.points[j, shapes.count[j] - 1]])
    s_tips = shapes.project(np.tile(k, 2), tips[:, 0], tips[:, 1])[0]
    pos_tips = shapes.lane_pos(np.tile(k, 2), s_tips)
    # An edge pair is one road if its nearest lanes (the inner ones) run side by side both ways.
    pair_of = {(int(a), int(b)): m for m, (a, b) in enumerate(pairs)}
    for e, f in candidates:
        near = min(((a, b) for a in edge_lanes[e] for b in edge_lanes[f]),
                   key=lambda ab: abs(median[pair_of[ab]]))
        if beside[pair_of[near]] < BESIDE_SHARE or beside[pair_of[near[::-1]]] < BESIDE_SHARE:
            continue
        opposite[e], opposite[f] = f, e
        for a, b in ((e, f), (f, e)):
            for lane in edge_lanes[a]:
                for other in edge_lanes[b]:
                    m = pair_of[(lane, other)]
                    offset[lane, lane_index[other]] = median[m]
                    start[lane, lane_index[other]] = pos_tips[m]
                    end[lane, lane_index[other]] = pos_tips[m + len(pairs)]
    return TwoWayRoads(opposite, offset, start, end)


def _compare(lane: np.ndarray, other: np.ndarray, shapes: LaneShapes,
             lane_width: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per lane pair: (the share of ``other``'s centre line that runs beside ``lane``'s, against it, with at most a
    lane width between the two lanes' facing borders; the median lateral position [m] of ``other``'s centre line
    in ``lane``'s frame, over that share, or over all of it where there is none)."""
    n = len(lane)
    fraction = (np.arange(SAMPLES) + 0.5) / SAMPLES
    rows = np.repeat(np.arange(n), SAMPLES)
    lk, lj = lane[rows], other[rows]
    s_j = np.tile(fraction, n) * shapes.cumulative[lj, shapes.count[lj] - 1]
    s, d, heading_k, heading_j = (np.empty(len(lk)) for _ in range(4))
    for c in range(0, len(lk), CHUNK_POINTS):
        part = slice(c, c + CHUNK_POINTS)
        x, y = shapes.point_at(lj[part], s_j[part], np.zeros(len(lj[part])))
        heading_j[part] = shapes.heading_at(lj[part], s_j[part])
        s[part], d[part], heading_k[part] = shapes.project(lk[part], x, y)
    reach = 0.5 * (lane_width[lk] + lane_width[lj]) + np.maximum(lane_width[lk], lane_width[lj])
    inside = (s >= 0.0) & (s <= shapes.cumulative[lk, shapes.count[lk] - 1])
    close = inside & (np.abs(d) <= reach) & (np.cos(heading_j - heading_k) < ANTIPARALLEL_COS)
    close, d = close.reshape(n, SAMPLES), d.reshape(n, SAMPLES)
    median = np.median(d, axis=1)
    some = np.flatnonzero(close.any(axis=1))
    median[some] = np.nanmedian(np.where(close[some], d[some], np.nan), axis=1)
    return close.mean(axis=1), median
