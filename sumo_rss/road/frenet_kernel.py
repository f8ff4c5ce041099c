"""The loops of :class:`~.frenet.LaneShapes`, compiled with numba: the search of ``project`` (each point against
the segments of its own lane, one at a time, instead of numpy's arrays of points x segments: a dozen temporaries of
that size per call, ~0.5 ms for the 1,400 cars of a Bologna step) and the segment, point and lane-position look-ups
(numpy's [points x lane points] comparisons and a dozen small temporaries per call). The arithmetic is numpy's,
operation for operation, so the results are the same to the bit (the lane headings at the foot points are left to
numpy's arctan2). Units: m.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel


@kernel
def nearest_segments(points, cumulative, count, lane, x, y, first, width):
    """For point i (``x[i]``, ``y[i]``) on lane ``lane[i]``: of the segments ``first[i]`` to ``first[i] +
    width[i] - 1`` of the lane (those beyond its ends left out, each clipped to the padded shape as numpy's search
    does), the nearest's (s along the lane, d left of it, its direction's x and y components). ``points``,
    ``cumulative``, ``count``: the :class:`~.frenet.LaneShapes` arrays. The first segment reaches back and the last
    one on beyond the lane's ends."""
    n = lane.size
    last_padded = points.shape[1] - 2
    s_out, d_out = np.empty(n), np.empty(n)
    dx_out, dy_out = np.empty(n), np.empty(n)
    for i in range(n):
        k, px, py = lane[i], x[i], y[i]
        n_seg = count[k] - 1
        best_d2, best = np.inf, -1
        best_t = best_ax = best_ay = best_sx = best_sy = best_l2 = 0.0
        for c in range(width[i]):
            raw = first[i] + c
            j = min(max(raw, 0), last_padded)
            ax, ay = points[k, j, 0], points[k, j, 1]
            sx, sy = points[k, j + 1, 0] - ax, points[k, j + 1, 1] - ay
            length2 = sx * sx + sy * sy
            real = raw >= 0 and raw < n_seg and length2 > 0.0
            t = ((px - ax) * sx + (py - ay) * sy) / (length2 if real else 1.0)
            lo = -np.inf if j == 0 else 0.0
            hi = np.inf if j == n_seg - 1 else 1.0
            t = min(max(t, lo), hi)
            ex, ey = px - (ax + t * sx), py - (ay + t * sy)
            d2 = ex * ex + ey * ey if real else np.inf
            if best < 0 or d2 < best_d2 or (d2 != d2 and best_d2 == best_d2):  # the first least (a NaN first)
                best_d2, best = d2, j
                best_t, best_ax, best_ay, best_sx, best_sy, best_l2 = t, ax, ay, sx, sy, length2
        seg_len = np.sqrt(best_l2)
        s_out[i] = cumulative[k, best] + best_t * seg_len
        d_out[i] = (best_sx * (py - best_ay) - best_sy * (px - best_ax)) / seg_len
        dx_out[i], dy_out[i] = best_sx, best_sy
    return s_out, d_out, dx_out, dy_out


@kernel
def segments_at(cumulative, count, lane, s):
    """Index of the segment of lane ``lane[i]`` that holds ``s[i]`` [m] along it (the first or last one beyond the
    lane's ends; a NaN: the first), as numpy's count of the lane's points at or before ``s`` gives it."""
    out = np.empty(lane.size, dtype=np.int64)
    for i in range(lane.size):
        k = lane[i]
        at = -1
        for j in range(count[k]):
            if cumulative[k, j] <= s[i]:
                at += 1
        out[i] = min(max(at, 0), count[k] - 2)
    return out


@kernel
def remap_along(source, target, count, lane, value):
    """``value[i]`` mapped from one measure along lane ``lane[i]`` (``source``, non-decreasing) to another
    (``target``): see :func:`.frenet._along`, whose numpy arithmetic this repeats operation for operation."""
    out = np.empty(lane.size)
    for i in range(lane.size):
        k, v = lane[i], value[i]
        last = count[k] - 1
        at = -1
        for j in range(count[k]):
            if source[k, j] <= v:
                at += 1
        at = min(max(at, 0), last - 1)
        x0, x1, y0, y1 = source[k, at], source[k, at + 1], target[k, at], target[k, at + 1]
        total_x, total_y = source[k, last], target[k, last]
        whole = total_y / total_x if total_x > 0.0 else 1.0
        rate = (y1 - y0) / (x1 - x0) if x1 > x0 else whole
        out[i] = y0 + (v - x0) * rate
    return out


@kernel
def points_at(points, cumulative, count, lane, s, d):
    """(x, y) of the points ``s[i]`` along lane ``lane[i]`` and ``d[i]`` left of it [m]: see
    :meth:`.frenet.LaneShapes.point_at`, whose numpy arithmetic this repeats operation for operation."""
    k = segments_at(cumulative, count, lane, s)
    x_out, y_out = np.empty(lane.size), np.empty(lane.size)
    for i in range(lane.size):
        ln, j = lane[i], k[i]
        ax, ay = points[ln, j, 0], points[ln, j, 1]
        sx, sy = points[ln, j + 1, 0] - ax, points[ln, j + 1, 1] - ay
        norm = np.sqrt(sx * sx + sy * sy)
        ux, uy = sx / norm, sy / norm
        along = s[i] - cumulative[ln, j]
        x_out[i] = ax + along * ux + d[i] * -uy
        y_out[i] = ay + along * uy + d[i] * ux
    return x_out, y_out
