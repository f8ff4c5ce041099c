"""The low-speed Frenet primitive of SSC (epsilon.md §6.8): s(t) the jerk-optimal quintic between the initial and
the final forward-simulated state, d(s) a quintic in arc length (so the car moves sideways only while it moves
forward). Units: m, s, m/s, m/s²."""
from __future__ import annotations

import numpy as np

VIRTUAL_LENGTH = 100.0  # [m] d(s) is spread over this when the car hardly moves
TINY_PROGRESS = 1.0  # [m]


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


def low_speed_primitive(t: np.ndarray, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, ...]:
    """(s, d, ṡ, ḋ, s̈, d̈) at times ``t`` (relative, from 0 to the end) from ``start`` = (s, d, ṡ, ḋ, s̈, d̈) to
    ``end`` = (s, d, ṡ, ḋ, s̈); s never moves backwards (speed ≥ 0)."""
    s0, d0, vs0, vd0, as0, _ = start
    s1, d1, vs1, vd1, as1 = end
    T = float(t[-1])
    s_q, vs, a_s = _derivatives(quintic(s0, vs0, as0, s1, vs1, as1, T), t)
    s = np.maximum.accumulate(s_q)  # where the quintic would reverse, the car waits
    held = (s > s_q + 1e-9) | (vs < 0.0)
    vs, a_s = np.where(held, 0.0, vs), np.where(held, 0.0, a_s)
    progress = s1 - s0
    length = progress if progress > TINY_PROGRESS else VIRTUAL_LENGTH
    slope0 = vd0 / vs0 if vs0 > 0.1 else 0.0
    slope1 = vd1 / vs1 if vs1 > 0.1 else 0.0
    d, dd_ds, d2d_ds2 = _derivatives(quintic(d0, slope0, 0.0, d1 if progress > TINY_PROGRESS else d0, slope1, 0.0,
                                             length), np.clip(s - s0, 0.0, length))
    return s, d, vs, dd_ds * vs, a_s, d2d_ds2 * vs * vs + dd_ds * a_s
