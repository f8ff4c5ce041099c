"""The motion layer of EPSILON (epsilon.md §6): the behaviour layer's chosen ego trajectory and the agents'
simulated trajectories become a spatio-temporal corridor, and a piecewise Bézier QP inside it gives the executed
trajectory. Below ``low_speed`` the quintic Frenet primitive is executed instead when it stays inside the
corridor. When no trajectory is found (corridor or QP failure) the previous motion-layer trajectory is kept for
up to ``keep_previous`` seconds after it was planned, then the behaviour layer's emergency backup is executed.
Units: m, s, m/s, m/s².
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ...trajectory import Trajectory
from ..road_frame import RoadFrame
from .corridor import Corridor, CorridorSettings, RoadLayer, build_corridor, occupancy
from .frenet_plan import FrenetPlan
from .primitive import knot_indices, low_speed_primitive, path_derivatives
from .ssc_qp import DynamicBounds, MotionFailure, QpProblem, SscSolver

OUTCOMES = ("ssc", "primitive", "previous", "backup")


@dataclass(frozen=True)
class MotionSettings:
    """``enabled`` False executes the behaviour trajectory as it is (the comparison baseline)."""

    enabled: bool = True
    weight_s: float = 1.0  # [1/s⁵] tracking weight of s against the jerk cost (∫jerk²dt: m²/s⁵)
    weight_d: float = 100.0  # [1/s⁵] and of d: the lateral profile the behaviour layer checked is kept
    low_speed: float = 2.0  # [m/s] at or below this the quintic primitive is preferred
    keep_previous: float = 1.0  # [s] how long after planning a trajectory may stand in for failed ones
    corridor: CorridorSettings = CorridorSettings()
    bounds: DynamicBounds = DynamicBounds()


@dataclass(frozen=True, eq=False)
class MotionInput:
    """One cycle's inputs. Sample times ``t`` [K] relative to ``now``; the ego's simulated centre states ``ego`` =
    (s, d, heading, speed, accel) arrays [K] (sample 0 is its measured state); the agents' (s, d, heading)
    [K, n] and (length, width) [n]; the ego's centre may not pass ``stop_s``."""

    frame: RoadFrame
    now: float
    t: np.ndarray
    ego: tuple[np.ndarray, ...]
    ego_length: float
    ego_width: float
    agents: tuple[np.ndarray, ...]
    stop_s: float


@dataclass
class MotionStats:
    outcomes: dict[str, int] = field(default_factory=lambda: {k: 0 for k in OUTCOMES})
    failures: dict[str, int] = field(default_factory=dict)  # reason → cycles
    start_clipped: int = 0  # QP cycles whose start velocity or acceleration lay outside the dynamic bounds
    cycle_times: list[float] = field(default_factory=list)  # [s]


class MotionLayer:
    """One per ego and run: keeps the previous trajectory and the QP solvers between cycles."""

    def __init__(self, settings: MotionSettings, output_step: float):
        self.settings = settings
        self.output_step = output_step
        self.solver = SscSolver()
        self.stats = MotionStats()
        self._previous: tuple[float, FrenetPlan, Trajectory] | None = None
        self._roads: dict[tuple[RoadFrame, float, float], RoadLayer] = {}  # per planning frame and ego size

    def plan(self, inp: MotionInput, backup: Callable[[], tuple[FrenetPlan, Trajectory]]
             ) -> tuple[FrenetPlan, Trajectory]:
        """The ego's plan and its world trajectory for this cycle (``backup`` gives the behaviour layer's emergency
        backup, executed when nothing better exists; called only then)."""
        clock = time.perf_counter()
        half, heading = 0.5 * inp.ego_length, float(inp.ego[2][0])
        try:
            plan, outcome = self._solve(inp)
            trajectory = plan.to_world(half, heading)
            self._previous = (inp.now, plan, trajectory)
        except MotionFailure as failure:
            self.stats.failures[failure.reason] = self.stats.failures.get(failure.reason, 0) + 1
            previous = self._previous
            if previous is not None and inp.now - previous[0] <= self.settings.keep_previous + 1e-9 and \
                    previous[2].end >= inp.now + self.output_step:
                plan, trajectory, outcome = previous[1], previous[2], "previous"
            else:
                (plan, trajectory), outcome = backup(), "backup"
                self._previous = None
        self.stats.outcomes[outcome] += 1
        self.stats.cycle_times.append(time.perf_counter() - clock)
        return plan, trajectory

    def _solve(self, inp: MotionInput) -> tuple[FrenetPlan, str]:
        cfg = self.settings
        s, d, heading, speed, accel = inp.ego
        start = self._initial_state(inp)
        grid = occupancy(self._road(inp), inp.t, float(s[0]), inp.ego_length, inp.ego_width, inp.agents,
                         inp.stop_s, cfg.corridor, heading, float(d[0]))
        corridor = build_corridor(grid, s, d, float(speed[0]))
        k_end = int(corridor.cells[-1, 5])
        t_out = np.arange(0.0, float(inp.t[k_end]) + 0.5 * self.output_step, self.output_step)
        t_out[-1] = min(t_out[-1], float(inp.t[k_end]))
        if speed[0] <= cfg.low_speed:
            k = np.concatenate([[0], knot_indices(inp.t, k_end)])
            motion = np.column_stack([s[k], speed[k] * np.cos(heading[k]), accel[k] * np.cos(heading[k])])
            motion[0] = start[[0, 2, 4]]
            states = low_speed_primitive(t_out, inp.t[k[1:]], motion,
                                         path_derivatives(s[:k_end + 1], d[:k_end + 1], heading[:k_end + 1])[k])
            if corridor.contains(t_out, states[0], states[1]).all():
                return FrenetPlan(inp.frame, inp.now + t_out, *states), "primitive"
        end = np.array([s[k_end], d[k_end], speed[k_end] * np.cos(heading[k_end]),
                        speed[k_end] * np.sin(heading[k_end]), accel[k_end]])
        curve = self.solver.solve(self._problem(corridor, start, end, inp, k_end))
        (s_o, d_o), (vs, vd), (a_s, a_d) = (curve.evaluate(t_out, k).T for k in range(3))
        return FrenetPlan(inp.frame, inp.now + t_out, s_o, d_o, np.maximum(vs, 0.0), vd, a_s, a_d), "ssc"

    def _road(self, inp: MotionInput) -> RoadLayer:
        key = (inp.frame, inp.ego_length, inp.ego_width)
        road = self._roads.get(key)
        if road is None:
            if len(self._roads) > 64:
                self._roads.clear()
            road = self._roads[key] = RoadLayer(inp.frame, inp.ego_length, inp.ego_width, self.settings.corridor)
        return road

    def _initial_state(self, inp: MotionInput) -> np.ndarray:
        """(s, d, ṡ, ḋ, s̈, d̈) now: the measured position, velocity and longitudinal acceleration; the lateral
        acceleration of the previous plan when it is in the same frame (else 0). (Starting from the previous
        plan's longitudinal acceleration instead, as EPSILON does, made the executed motion jerkier: merge_onramp
        seeds 0 and 1, 60 s, RMS jerk 0.19 and 0.34 against 0.17 and 0.29 m/s³.)"""
        s, d, heading, speed, accel = (float(a[0]) for a in inp.ego)
        d_ddot = 0.0
        if self._previous is not None and self._previous[1].frame is inp.frame:
            d_ddot = float(self._previous[1].at(inp.now)[5])
        return np.array([s, d, speed * np.cos(heading), speed * np.sin(heading), accel * np.cos(heading), d_ddot])

    def _problem(self, corridor: Corridor, start: np.ndarray, end: np.ndarray, inp: MotionInput,
                 k_end: int) -> QpProblem:
        b = self.settings.bounds
        start_s = [start[0], np.clip(start[2], *b.s_speed), np.clip(start[4], *b.s_accel)]
        start_d = [start[1], np.clip(start[3], *b.d_speed), np.clip(start[5], *b.d_accel)]
        # Outside its bounds the QP could not start at the ego's state: it starts at the nearest bound (counted).
        self.stats.start_clipped += int(start_s[1:] != [start[2], start[4]] or start_d[1:] != [start[3], start[5]])
        end_s = [end[0], np.clip(end[2], *b.s_speed)]
        end_d = [end[1], np.clip(end[3], *b.d_speed)]
        ref = np.column_stack([inp.ego[0][:k_end + 1], inp.ego[1][:k_end + 1]])
        return QpProblem(corridor.knots, corridor.bounds, np.array([start_s, start_d]), np.array([end_s, end_d]),
                         inp.t[:k_end + 1], ref, np.array([self.settings.weight_s, self.settings.weight_d]), b)
