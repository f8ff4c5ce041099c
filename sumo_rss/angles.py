"""Angle helpers shared by the snapshot, the auditor and the planner.

numpy's float64 sin, cos and mod are several times slower than tan here (no vector path for them), so the
helpers that run every step of the planner's forward simulation avoid them.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .jit import as_float, compiled_as, jitable, select


def wrap_angle(angle: Any) -> np.ndarray:
    """``angle`` [rad] wrapped into (-π, π] (returned unchanged, as a new array, where it already is)."""
    angle = np.array(angle, dtype=float)
    if angle.min(initial=0.0) > -np.pi and angle.max(initial=0.0) <= np.pi:
        return angle[()]  # a scalar for a scalar, as below
    return _wrapped(angle)


@compiled_as(wrap_angle)
def _wrap_scalar(angle: float) -> float:
    """:func:`wrap_angle` of one angle, in numba code."""
    return select((angle > -np.pi) & (angle <= np.pi), angle, _wrapped(angle))


@jitable
def _wrapped(angle: Any) -> np.ndarray:
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


@jitable
def cos_sin(angle: Any) -> tuple[np.ndarray, np.ndarray]:
    """(cos, sin) of ``angle`` [rad] from the tangent of its half (exact to ~1 ulp for any angle)."""
    t = np.tan(0.5 * as_float(angle))
    t2 = t * t
    scale = 1.0 / (1.0 + t2)
    return (1.0 - t2) * scale, 2.0 * t * scale
