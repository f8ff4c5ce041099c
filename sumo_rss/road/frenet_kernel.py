"""The search of :meth:`~.frenet.LaneShapes.project`, compiled with numba: each point against the segments of its
own lane, one at a time, instead of numpy's arrays of points x segments (a dozen temporaries of that size per call,
~0.5 ms for the 1,400 cars of a Bologna step). The arithmetic is numpy's, operation for operation, so the results are
the same to the bit (the lane headings at the foot points are left to numpy's arctan2). Units: m.
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
