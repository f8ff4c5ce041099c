"""Piecewise Bézier curves of degree 5 in the time-scaled form of SSC (epsilon.md §6.6).

Segment j lasts T_j [s] and has scaled control points c_j (6 per dimension); with τ = (t − t_j)/T_j,

    p(t) = T_j · Σ_i c_{j,i} B_{5,i}(τ),

so the k-th time derivative is T_j^(1−k) times the k-th hodograph of c: velocity control points 5·Δc, acceleration
control points 20·Δ²c / T_j, jerk control points 60·Δ³c / T_j². ∫ over the segment of the squared jerk is
cᵀ H c / T_j³ with H the unit-interval jerk Hessian (:data:`JERK_HESSIAN`). Units: m, s.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

DEGREE = 5
N_CTRL = DEGREE + 1


def bernstein(degree: int, tau: np.ndarray) -> np.ndarray:
    """[len(tau), degree+1]: the Bernstein basis B_{degree,i}(τ) at each τ ∈ [0, 1]."""
    tau = np.asarray(tau, dtype=float)[:, None]
    i = np.arange(degree + 1)
    binom = np.array([comb(degree, k) for k in i], dtype=float)
    return binom * tau ** i * (1.0 - tau) ** (degree - i)


def difference_matrix(order: int, n: int = N_CTRL) -> np.ndarray:
    """[n − order, n]: the order-th forward difference Δ^order of n control points."""
    d = np.eye(n)
    for _ in range(order):
        d = d[1:] - d[:-1]
    return d


def _gram(degree: int) -> np.ndarray:
    """∫_0^1 B_{n,i} B_{n,j} dτ = C(n,i)·C(n,j) / ((2n+1)·C(2n,i+j))."""
    i = np.arange(degree + 1)
    c = np.array([comb(degree, k) for k in i], dtype=float)
    c2 = np.array([[comb(2 * degree, a + b) for b in i] for a in i], dtype=float)
    return np.outer(c, c) / ((2 * degree + 1) * c2)


# d³/dτ³ Σ c_i B_{5,i} = 60 Σ_k (Δ³c)_k B_{2,k}, so ∫_0^1 (·)² dτ = cᵀ H c:
D1, D2, D3 = (difference_matrix(k) for k in (1, 2, 3))
JERK_HESSIAN = 3600.0 * D3.T @ _gram(2) @ D3  # [6, 6]
VEL_FACTOR, ACC_FACTOR, JERK_FACTOR = 5.0, 20.0, 60.0  # hodograph factors of degree 5, 4, 3


@dataclass(frozen=True, eq=False)
class PiecewiseBezier:
    """``knots[j]`` .. ``knots[j+1]``: segment j's time span [s] (relative to the plan's start);
    ``ctrl[j, dim, i]``: its scaled control points (dim 0 = s, 1 = d)."""

    knots: np.ndarray  # [N+1]
    ctrl: np.ndarray  # [N, 2, 6]

    @property
    def durations(self) -> np.ndarray:
        return np.diff(self.knots)

    def evaluate(self, t: np.ndarray, derivative: int) -> np.ndarray:
        """[len(t), 2]: the ``derivative``-th time derivative (0..3) of (s, d) at times ``t`` (clamped to the
        span)."""
        t = np.clip(np.asarray(t, dtype=float), self.knots[0], self.knots[-1])
        j = np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.ctrl) - 1)
        tau = (t - self.knots[j]) / self.durations[j]
        return np.einsum("tdi,ti->td", self.control_points(derivative)[j], bernstein(DEGREE - derivative, tau))

    def control_points(self, derivative: int) -> np.ndarray:
        """[N, 2, 6 − k]: the control points (in real units) of the ``derivative``-th time derivative; by the
        convex-hull property the curve lies within their bounds."""
        factor = (1.0, VEL_FACTOR, ACC_FACTOR, JERK_FACTOR)[derivative]
        scale = self.durations ** (1 - derivative)
        return factor * scale[:, None, None] * np.diff(self.ctrl, n=derivative, axis=-1)
