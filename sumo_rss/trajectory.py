"""Trajectory: a timed sequence of planned states for one vehicle (front-bumper centre, like SUMO)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class TrajectoryState:
    x: float  # [m]
    y: float  # [m]
    heading: float  # [rad], math convention
    speed: float  # [m/s]
    accel: float  # [m/s²]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """States at absolute simulation times ``t`` [s] (strictly increasing), linearly interpolated between."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    accel: np.ndarray

    def __post_init__(self) -> None:
        arrays = [np.asarray(getattr(self, k), dtype=float) for k in ("t", "x", "y", "heading", "speed", "accel")]
        if any(a.ndim != 1 or a.shape != arrays[0].shape for a in arrays) or arrays[0].size < 1:
            raise ValueError("Trajectory arrays must be 1-D, non-empty and of equal length")
        if np.any(np.diff(arrays[0]) <= 0.0):
            raise ValueError("Trajectory times must be strictly increasing")
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise ValueError("Trajectory values must be finite")
        for key, arr in zip(("t", "x", "y", "heading", "speed", "accel"), arrays):
            object.__setattr__(self, key, arr)

    @property
    def start(self) -> float:
        return float(self.t[0])

    @property
    def end(self) -> float:
        return float(self.t[-1])

    def state_at(self, time: float) -> TrajectoryState:
        """Interpolated state at ``time`` [s]; raises ``ValueError`` outside [start, end]."""
        if not self.start - 1e-9 <= time <= self.end + 1e-9:
            raise ValueError(f"time {time:.3f} s is outside the trajectory [{self.start:.3f}, {self.end:.3f}] s")
        heading = np.unwrap(self.heading)
        return TrajectoryState(*(float(np.interp(time, self.t, a))
                                 for a in (self.x, self.y, heading, self.speed, self.accel)))
