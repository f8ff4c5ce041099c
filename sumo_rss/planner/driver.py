"""Drives the ego of a run with a planner: plan every ``replan_every`` steps, pass the state for the next step
through the RSS proper-response guard, and keep the numbers a run reports about its planner."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..road.network import RoadNetwork
from ..rss.auditor import Auditor, ParamResolver
from ..scenario import ScenarioSpec
from ..sim.snapshot import WorldSnapshot
from ..trajectory import Trajectory, TrajectoryState
from .behavior.cost_weights import CostWeights
from .epsilon import EpsilonPlanner, PlannerConfig
from .guard import ProperResponseGuard
from .motion.frenet_plan import FrenetPlan
from .motion.ssc import MotionSettings


def planner_config(spec: ScenarioSpec) -> PlannerConfig:
    """The planner configuration a scenario asks for (``ego.controller`` and ``[ego.planner]``)."""
    ego = spec.ego
    o = ego.planner
    if ego.controller == "mpdm":
        return replace(PlannerConfig.mpdm(ego.desired_speed), output_step=spec.step_s, replan_every=o.replan_every)
    return PlannerConfig(desired_speed=ego.desired_speed, layers=o.layers, layer_duration=o.layer_duration_s,
                         sim_step=o.sim_step_s, scenarios_k=o.scenarios_k, replan_every=o.replan_every,
                         output_step=spec.step_s, intention_net=o.intention_net, lane_changes=o.lane_changes,
                         motion=MotionSettings(enabled=o.motion_layer), costs=replace(CostWeights(), **o.costs))


class EgoDriver:
    """One per run. ``command(snapshot, auditor)`` returns where the ego goes at the end of the next step."""

    def __init__(self, spec: ScenarioSpec, network: RoadNetwork, audit_params: ParamResolver,
                 planner_params: ParamResolver):
        self.spec = spec
        self.ego_id = spec.ego.id
        self.planner = EpsilonPlanner(network, planner_params, planner_config(spec))
        self._own_params = planner_params is not audit_params  # [ego.planner] rss_preset names another preset
        self.guard = ProperResponseGuard(audit_params, spec.step_s)
        self._trajectory: Trajectory | None = None
        self._frenet: FrenetPlan | None = None
        self._velocity: list[tuple[float, float]] = []  # executed speed, planned lateral speed in the frame [m/s]
        self._steps = 0
        self.policies: dict[str, int] = {}

    def command(self, snapshot: WorldSnapshot, auditor: Auditor) -> TrajectoryState:
        """Plan if due, then the guarded state for ``snapshot.time + step``."""
        t_next = snapshot.time + self.spec.step_s
        owed = auditor.owed_by(self.ego_id)
        if self._steps % self.planner.config.replan_every == 0 or self._trajectory is None or \
                self._trajectory.end < t_next:
            result = self.planner.plan(snapshot, self.ego_id, owed)
            self._trajectory, self._frenet = result.trajectory, result.frenet
            self.policies[result.policy] = self.policies.get(result.policy, 0) + 1
        self._steps += 1
        ego = snapshot.index_of(self.ego_id)
        state = self.guard.apply(snapshot, ego, self.planner.frame_for(snapshot, ego),
                                 self._trajectory.state_at(t_next), owed)
        self._velocity.append((state.speed, float(self._frenet.at(t_next)[3])))
        return state

    def summary(self) -> dict:
        """Cycle times [ms], backups, lane changes, guard interventions, chosen policies, how many agent
        beliefs came from the intention network (per cycle and agent), the motion layer's outcomes, and the RMS
        jerk [m/s³] of the executed motion: the second differences of the executed speed (longitudinal) and of
        the planned lateral speed in the planning frame (lateral) over the steps. With a preset of its own, the
        RSS parameters the planner used (as rss_params.json has the auditor's)."""
        times = np.array(self.planner.stats.cycle_times) * 1000.0
        stats = {"cycles": int(times.size), "backups": self.planner.stats.backups,
                 "lane_changes_started": self.planner.manager.lane_changes_started,
                 "lane_changes_completed": self.planner.manager.lane_changes_completed,
                 "lane_changes_called_off": self.planner.manager.lane_changes_called_off,
                 "gap_seek_cycles": self.planner.stats.gap_seek_cycles,
                 "overtake_seek_cycles": self.planner.stats.overtake_seek_cycles,
                 "guard": self.guard.counts.as_dict(),
                 "intention_net_beliefs": self.planner.stats.learned_beliefs,
                 "stop_line_cycles": {k or "none": v for k, v in sorted(self.planner.stats.stop_lines.items())},
                 "policies": dict(sorted(self.policies.items())), **self._jerk()}
        motion = self.planner.motion
        if motion is not None:
            ms = np.array(motion.stats.cycle_times) * 1000.0
            stats["motion"] = {"outcomes": dict(motion.stats.outcomes),
                               "failures": dict(sorted(motion.stats.failures.items())),
                               "start_clipped": motion.stats.start_clipped,
                               "qp_refined": motion.solver.refinements,
                               "ms_median": float(np.median(ms)) if ms.size else None,
                               "ms_p99": float(np.percentile(ms, 99)) if ms.size else None}
        if self._own_params:
            stats["rss_params"] = self.planner.params.resolved()
        if times.size:
            stats |= {"cycle_ms_median": float(np.median(times)), "cycle_ms_p95": float(np.percentile(times, 95)),
                      "cycle_ms_p99": float(np.percentile(times, 99))}
        return stats

    def _jerk(self) -> dict[str, float | None]:
        if len(self._velocity) < 3:
            return {"rms_jerk_lon": None, "rms_jerk_lat": None}
        jerk = np.diff(np.array(self._velocity), n=2, axis=0) / self.spec.step_s ** 2
        rms = np.sqrt(np.mean(jerk * jerk, axis=0))
        return {"rms_jerk_lon": float(rms[0]), "rms_jerk_lat": float(rms[1])}
