"""The ego's planned motion in the planning frame, sampled in time, and its conversion to the world trajectory the
co-simulation executes (epsilon.md §6.8). Units: m, s, m/s, m/s²."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...trajectory import Trajectory
from ..behavior.controllers import VehicleLimits
from ..road_frame import RoadFrame

STILL = 0.1  # [m/s] below this the heading is held (a heading from a near-zero velocity is noise)
# [1/m] The heading turns by at most this per metre of path: the forward simulation's bicycle model's tightest
# curvature (tan of its maximum steering angle over its wheelbase: 0.35). The direction of a velocity of a few cm/s
# is no heading: an ego creeping sideways at the end of a lane stood turned by 1.1 rad (docs/planner.md).
MAX_CURVATURE = float(np.tan(VehicleLimits.max_steer) / VehicleLimits.wheelbase)


@dataclass(frozen=True, eq=False)
class FrenetPlan:
    """The ego centre's (s, d) and their first two time derivatives at absolute times ``t`` [s] in ``frame``."""

    frame: RoadFrame
    t: np.ndarray
    s: np.ndarray
    d: np.ndarray
    s_dot: np.ndarray
    d_dot: np.ndarray
    s_ddot: np.ndarray
    d_ddot: np.ndarray

    def at(self, time: float) -> np.ndarray:
        """(s, d, ṡ, ḋ, s̈, d̈) at ``time`` (held at the ends)."""
        return np.array([np.interp(time, self.t, a) for a in (self.s, self.d, self.s_dot, self.d_dot, self.s_ddot,
                                                               self.d_ddot)])

    def to_world(self, half_length: float, heading_still: float) -> Trajectory:
        """The front-bumper trajectory; speed = |(ṡ, ḋ)|, heading along (ṡ, ḋ) (``heading_still`` [rad, relative
        to the frame] while slower than :data:`STILL`), acceleration its tangential component."""
        speed = np.hypot(self.s_dot, self.d_dot)
        moving = speed >= STILL
        heading = np.where(moving, np.arctan2(self.d_dot, np.maximum(self.s_dot, 0.0)), np.nan)
        heading = _turn_limited(_hold(heading, heading_still), self.s, self.d, heading_still)
        accel = np.where(moving, (self.s_dot * self.s_ddot + self.d_dot * self.d_ddot) / np.maximum(speed, STILL),
                         self.s_ddot)
        x, y, h = self.frame.bumper_at(self.s, self.d, heading, half_length)
        return Trajectory(self.t, x, y, h, speed, accel)


def _hold(values: np.ndarray, first: float) -> np.ndarray:
    """NaNs replaced by the last finite value before them (``first`` before any)."""
    filled = np.concatenate([[first], values])
    idx = np.where(np.isnan(filled), 0, np.arange(filled.size))
    return filled[np.maximum.accumulate(idx)][1:]


def from_samples(frame: RoadFrame, t: np.ndarray, s: np.ndarray, d: np.ndarray, heading: np.ndarray,
                 speed: np.ndarray) -> FrenetPlan:
    """A plan from simulated states (centre, heading relative to the frame, speed) at times ``t``: velocities from
    speed and heading, accelerations their finite differences."""
    s_dot, d_dot = speed * np.cos(heading), speed * np.sin(heading)
    return FrenetPlan(frame, t, s, d, s_dot, d_dot, np.gradient(s_dot, t), np.gradient(d_dot, t))


def _turn_limited(heading: np.ndarray, s: np.ndarray, d: np.ndarray, first: float) -> np.ndarray:
    """``heading`` [rad] with each sample's turn from the one before (``first`` before the first) limited to
    MAX_CURVATURE times the path between their positions ``s``, ``d`` [m] (the first sample's path: none)."""
    path = np.concatenate([[0.0], np.hypot(np.diff(s), np.diff(d))]) * MAX_CURVATURE
    out = np.empty_like(heading)
    previous = first
    for k in range(heading.size):
        previous = out[k] = min(max(heading[k], previous - path[k]), previous + path[k])
    return out
