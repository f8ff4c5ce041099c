"""The low-speed Frenet primitive of SSC (epsilon.md §6.8), piecewise: s(t) jerk-optimal quintics through the
forward-simulated states at knots (every second of the behaviour trajectory), d(s) quintics in arc length through
the forward trajectory's path at the same knots (offset, slope and its derivative), so the car moves sideways only
while it moves forward and turns no sharper than the simulated bicycle did. Units: m, s, m/s, m/s².

The release joins the initial and the final forward state with one quintic in s(t) and one in d(s). Replanned
every 0.1 s from the measured state, that one minimum-jerk s(t) always postpones what the behaviour layer asked
for: an ego waiting at the end of an acceleration lane accelerated into a gap at 0.4 instead of 0.7 m/s² and lost
it (merge_onramp seed 1). A d(s) that ignores the path's slope and curvature between its ends turned the car by
0.4 rad over 0.3 m at walking pace.
"""
from __future__ import annotations

import numpy as np

KNOT_SPACING = 1.0  # [s]
STANDING = 1e-3  # [m] a lateral piece shorter than this holds the lateral position
MAX_SLOPE = 2.0  # [-] |d'| cap: the path's heading stays within ±63° of the frame


def quintic(x0: float, v0: float, a0: float, x1: float, v1: float, a1: float, T: float) -> np.ndarray:
    """Coefficients c[0..5] of x(τ) = Σ c_k τ^k on [0, T] with the given value, first and second derivative at
    both ends (the minimum-jerk polynomial)."""
    c0, c1, c2 = x0, v0, 0.5 * a0
    m = np.array([[T ** 3, T ** 4, T ** 5], [3 * T ** 2, 4 * T ** 3, 5 * T ** 4], [6 * T, 12 * T ** 2, 20 * T ** 3]])
    rhs = np.array([x1 - (c0 + c1 * T + c2 * T * T), v1 - (c1 + 2 * c2 * T), a1 - 2 * c2])
    return np.concatenate([[c0, c1, c2], np.linalg.solve(m, rhs)])


def _derivatives(c: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = np.polynomial.polynomial
    return p.polyval(x, c), p.polyval(x, p.polyder(c)), p.polyval(x, p.polyder(c, 2))


def knot_indices(t: np.ndarray, last: int) -> np.ndarray:
    """Indices of the forward-simulation samples ``t`` [s] used as knots after sample 0, up to ``last`` (included)."""
    marks = np.searchsorted(t, np.arange(KNOT_SPACING, float(t[last]), KNOT_SPACING) - 1e-9)
    return np.unique(np.append(marks[(marks > 0) & (marks < last)], last))


def path_derivatives(s: np.ndarray, d: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(d, d', d'') [n, 3] of a simulated path: d' = tan(heading) (heading relative to the frame), d'' its central
    difference over s (one-sided at the ends; 0 where the car hardly moved)."""
    slope = np.tan(np.clip(heading, -np.arctan(MAX_SLOPE), np.arctan(MAX_SLOPE)))
    k = np.arange(slope.size)
    lo, hi = np.maximum(k - 1, 0), np.minimum(k + 1, slope.size - 1)  # one-sided at the ends
    ds = s[hi] - s[lo]
    bend = np.where(ds > 0.05, (slope[hi] - slope[lo]) / np.maximum(ds, 0.05), 0.0)
    return np.column_stack([d, slope, bend])


def low_speed_primitive(t: np.ndarray, t_knots: np.ndarray, motion: np.ndarray,
                        path: np.ndarray) -> tuple[np.ndarray, ...]:
    """(s, d, ṡ, ḋ, s̈, d̈) at times ``t`` (relative, from 0 to the last knot) through ``motion`` [m+1, 3] = (s, ṡ, s̈)
    and ``path`` [m+1, 3] = (d, d', d'') at times (0, ``t_knots`` [m]); s never moves backwards (speed ≥ 0)."""
    bounds = np.concatenate([[0.0], t_knots])
    piece = np.clip(np.searchsorted(bounds, t, side="right") - 1, 0, len(t_knots) - 1)
    s_q, vs, a_s = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    for k in range(len(t_knots)):
        on = piece == k
        c = quintic(*motion[k], *motion[k + 1], bounds[k + 1] - bounds[k])
        s_q[on], vs[on], a_s[on] = _derivatives(c, t[on] - bounds[k])
    s = np.maximum.accumulate(s_q)  # where a quintic would reverse, the car waits
    held = (s > s_q + 1e-9) | (vs < 0.0)
    vs, a_s = np.where(held, 0.0, vs), np.where(held, 0.0, a_s)
    # d is a function of s alone, each piece taken by where the car is, not by the time: an s(t) quintic that
    # overshoots its knot is held there into the next time piece, and d must not move while s does not.
    at = np.maximum.accumulate(motion[:, 0])
    on_piece = np.clip(np.searchsorted(at, s, side="right") - 1, 0, len(t_knots) - 1)
    d, slope, bend = np.empty_like(t), np.zeros_like(t), np.zeros_like(t)
    d_now = float(path[0, 0])
    for k in range(len(t_knots)):
        on, length = on_piece == k, at[k + 1] - at[k]
        if length <= STANDING:  # s may still creep over it (a quintic overshooting a knot): along the heading
            d[on], slope[on] = d_now, path[k, 1]  # the car stopped with, not turning to the frame's axis
            continue
        c = quintic(d_now, path[k, 1], path[k, 2], path[k + 1, 0], path[k + 1, 1], path[k + 1, 2], length)
        d[on], slope[on], bend[on] = _derivatives(c, np.clip(s[on] - at[k], 0.0, length))
        d_now = float(path[k + 1, 0])
    return s, d, vs, slope * vs, a_s, bend * vs * vs + slope * a_s
