"""Curvature of SUMO lane polylines, robust to how SUMO samples and rounds them.

SUMO writes lane shapes with 0.01 m precision and splits a junction's turn into internal lanes at points on the
chord between two samples of its curve. The heading change per vertex over the mean length of the two adjacent
segments then spikes at such a split: the intersection_tls left turn (SUMO's five-point curve, ≈ 0.11 1/m at
its middle) read 0.155–0.19 1/m there, with 0.74 m left of a 4.4 m chord. So the polyline is first simplified
(Douglas–Peucker: drop every vertex within ``tolerance`` of the chord that replaces it), which removes such
split points and rounding noise and keeps the real samples of a curve (a 2000 m radius keeps a vertex every
~28 m at 0.05 m); the curvature at each remaining vertex is that of the circle through it and its two
neighbours (Menger curvature), exact for points on a circle whatever their spacing.
"""
from __future__ import annotations

import numpy as np

SIMPLIFY_TOLERANCE_M = 0.05  # [m] 5x SUMO's shape precision


def simplified(points: np.ndarray, tolerance: float = SIMPLIFY_TOLERANCE_M) -> np.ndarray:
    """Indices of the vertices of ``points`` [n, 2] that Douglas–Peucker keeps at ``tolerance`` [m] (first and
    last always), in order."""
    n = len(points)
    if n <= 2:
        return np.arange(n)
    keep = np.zeros(n, dtype=bool)
    keep[[0, n - 1]] = True
    stack = [(0, n - 1)]
    while stack:
        first, last = stack.pop()
        if last - first < 2:
            continue
        a, b = points[first], points[last]
        inner = points[first + 1:last]
        chord = b - a
        length = np.hypot(*chord)
        if length > 0.0:
            off = np.abs(chord[0] * (inner[:, 1] - a[1]) - chord[1] * (inner[:, 0] - a[0])) / length
        else:
            off = np.hypot(inner[:, 0] - a[0], inner[:, 1] - a[1])
        k = int(np.argmax(off))
        if off[k] > tolerance:
            split = first + 1 + k
            keep[split] = True
            stack.extend([(first, split), (split, last)])
    return np.flatnonzero(keep)


def vertex_curvature(points: np.ndarray, cumulative: np.ndarray,
                     tolerance: float = SIMPLIFY_TOLERANCE_M) -> tuple[np.ndarray, np.ndarray]:
    """(s [m], |κ| [1/m]) at the interior vertices of the simplified polyline ``points`` [n, 2] whose arc lengths
    are ``cumulative`` [n]; empty when nothing bends."""
    idx = simplified(points, tolerance)
    if idx.size < 3:
        return np.zeros(0), np.zeros(0)
    p = points[idx]
    u, w = p[1:-1] - p[:-2], p[2:] - p[1:-1]
    cross = np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0])
    lengths = np.hypot(*u.T) * np.hypot(*w.T) * np.hypot(*(p[2:] - p[:-2]).T)
    kappa = 2.0 * cross / np.maximum(lengths, 1e-12)
    return cumulative[idx[1:-1]], kappa
