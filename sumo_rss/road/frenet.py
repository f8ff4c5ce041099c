"""Vectorised projection of points onto lane centre lines: (x, y) ⇄ (s, d).

Lane shapes are stored padded in one array (lanes × points), so that any number of points, each with its own
lane, is projected in one call (the nearest segment found by :mod:`.frenet_kernel`, compiled, as are the look-ups
of a segment, a point and a lane position along a lane). The first and last segment of every lane extend beyond its ends, so a
point before the start of a lane gets s < 0 and one after its end s > length (the frame of a lane continues
straight ahead and behind it).

Two distances along a lane: *shape metres* (s, along the 2-D centre line, what projections give) and SUMO's *lane
positions* (``pos``, along the lane's own length, which includes elevation: SUMO places position ``pos`` at
``pos * length3d / length`` along the 3-D shape, so on a slope, and on the inner lanes of a curved edge, the two
differ). :meth:`LaneShapes.lane_pos` and :meth:`LaneShapes.shape_s` convert between them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class LaneShapes:
    """Padded lane centre lines. ``points[k, :count[k]]`` is lane k's polyline [m]."""

    points: np.ndarray  # [lanes, max_points, 2]
    count: np.ndarray  # [lanes] number of points (>= 2)
    cumulative: np.ndarray  # [lanes, max_points] distance along the lane's 2-D shape at each point [m]
    positions: np.ndarray  # [lanes, max_points] SUMO's lane position of each point [m]

    @classmethod
    def from_polylines(cls, polylines: list[np.ndarray], lengths: np.ndarray | None = None) -> LaneShapes:
        """Shapes from polylines of (x, y) or (x, y, z) points [m]; ``lengths``: SUMO's length of each lane [m]
        (default: its 2-D shape's), which SUMO spreads over the 3-D shape (:meth:`lane_pos`)."""
        count = np.array([len(p) for p in polylines], dtype=int)
        if np.any(count < 2):
            raise ValueError("every lane shape needs at least two points")
        # Lane by lane into the padded arrays (padding repeats each lane's last value: zero-length segments), so
        # that no temporary is as large as the padded 3-D shapes (MoST: 23,794 lanes, the longest of 233 points).
        width = int(count.max())
        points = np.empty((len(polylines), width, 2))
        cumulative = np.empty((len(polylines), width))
        positions = cumulative if lengths is None else np.empty((len(polylines), width))
        for k, poly in enumerate(polylines):
            poly = np.asarray(poly, dtype=float)
            points[k, :len(poly)], points[k, len(poly):] = poly[:, :2], poly[-1, :2]
            along = _cumulative(poly[None, :, :2])[0]
            cumulative[k, :len(poly)], cumulative[k, len(poly):] = along, along[-1]
            if lengths is not None:
                along_3d = _cumulative(poly[None])[0]
                total_3d = along_3d[-1]
                pos = along_3d * float(lengths[k]) / total_3d if total_3d > 0.0 else along
                positions[k, :len(poly)], positions[k, len(poly):] = pos, pos[-1]
        return cls(points, count, cumulative, positions)

    def lane_pos(self, lane: np.ndarray, s: np.ndarray) -> np.ndarray:
        """SUMO lane positions [m] of the points ``s`` shape metres along lanes ``lane`` (beyond a lane's ends at
        the rate of its first or last segment)."""
        return _along(self.cumulative, self.positions, self.count, np.asarray(lane, dtype=int), s)

    def shape_s(self, lane: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Shape metres along lanes ``lane`` [m] of SUMO lane positions ``pos`` [m] (the inverse of
        :meth:`lane_pos`)."""
        return _along(self.positions, self.cumulative, self.count, np.asarray(lane, dtype=int), pos)

    def project(self, lane: np.ndarray, x: np.ndarray, y: np.ndarray, s_hint: np.ndarray | None = None,
                window: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Project points (x, y) [m] onto lanes ``lane`` (indices): s along the lane [m], d signed offset
        (+ = left of the driving direction) [m] and the lane's heading at the foot point [rad].

        Each point is projected onto the nearest of its lane's segments (the first of equally near ones). With
        ``s_hint`` [m] (roughly where along the lane each point is), only the ``window`` segments on each side of
        the hinted one are searched instead of all of them.
        """
        from .frenet_kernel import nearest_segments  # numba: compiled at the first projection

        lane, x, y = _flat(lane, x, y)
        if s_hint is not None:
            first = self._segment_at(lane, s_hint) - window
            width = np.full(lane.shape, 2 * window + 1)
        else:
            first, width = np.zeros(lane.shape, dtype=int), self.count[lane] - 1
        s, d, dx, dy = nearest_segments(self.points, self.cumulative, self.count, lane, x, y, first, width)
        return s, d, np.arctan2(dy, dx)

    def point_at(self, lane: np.ndarray, s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) [m] of the points ``s`` along lanes ``lane`` and ``d`` left of them [m] (the inverse of
        :meth:`project`; beyond a lane's ends along its first or last segment's extension)."""
        from .frenet_kernel import points_at

        lane, s, d = _flat(lane, s, d)
        return points_at(self.points, self.cumulative, self.count, lane, s, d)

    def heading_at(self, lane: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Heading [rad] of lanes ``lane`` at distances ``s`` [m] along them."""
        lane = np.asarray(lane, dtype=int)
        k = self._segment_at(lane, s)
        seg = self.points[lane, k + 1] - self.points[lane, k]  # [n, 2]
        return np.arctan2(seg[:, 1], seg[:, 0])

    def _segment_at(self, lane: np.ndarray, s: Any) -> np.ndarray:
        """Index of the segment of lanes ``lane`` (indices) that holds the distances ``s`` [m] along them (the first
        or last one beyond a lane's ends)."""
        from .frenet_kernel import segments_at

        lane, s = _flat(lane, s)
        return segments_at(self.cumulative, self.count, lane, s)


def _flat(lane: Any, *values: Any) -> tuple[np.ndarray, ...]:
    """``lane`` as a 1-D array of lane indices, and ``values`` as floats of its shape (contiguous, as the compiled
    loops of :mod:`.frenet_kernel` take them)."""
    lane = np.asarray(lane, dtype=np.int64).reshape(-1)
    return (lane, *(np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), lane.shape)) for v in values))


def _cumulative(points: np.ndarray) -> np.ndarray:
    """[lanes, points] distance along each padded polyline at each of its points [m]."""
    seg = np.linalg.norm(np.diff(points, axis=1), axis=2)
    return np.concatenate([np.zeros((points.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)


def _along(source: np.ndarray, target: np.ndarray, count: np.ndarray, lane: np.ndarray, value: Any) -> np.ndarray:
    """Map ``value`` from one measure along lanes (``source`` [lanes, points], non-decreasing per lane) to another
    (``target``): piecewise linear between the lanes' points; beyond a lane's ends at the rate of its first or
    last segment (of the whole lane where that segment has no length in ``source``)."""
    from .frenet_kernel import remap_along

    lane, value = _flat(lane, value)
    return remap_along(source, target, count, lane, value)
