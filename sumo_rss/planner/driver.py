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
from .epsilon import EpsilonPlanner, PlannerConfig
from .guard import ProperResponseGuard


def planner_config(spec: ScenarioSpec) -> PlannerConfig:
    """The planner configuration a scenario asks for (``ego.controller`` and ``[ego.planner]``)."""
    ego = spec.ego
    if ego.controller == "mpdm":
        return replace(PlannerConfig.mpdm(ego.desired_speed), output_step=spec.step_s)
    o = ego.planner
    return PlannerConfig(desired_speed=ego.desired_speed, layers=o.layers, layer_duration=o.layer_duration_s,
                         sim_step=o.sim_step_s, scenarios_k=o.scenarios_k, replan_every=o.replan_every,
                         output_step=spec.step_s, intention_net=o.intention_net)


class EgoDriver:
    """One per run. ``command(snapshot, auditor)`` returns where the ego goes at the end of the next step."""

    def __init__(self, spec: ScenarioSpec, network: RoadNetwork, audit_params: ParamResolver,
                 planner_params: ParamResolver):
        self.spec = spec
        self.ego_id = spec.ego.id
        self.planner = EpsilonPlanner(network, planner_params, planner_config(spec))
        self.guard = ProperResponseGuard(audit_params, spec.step_s)
        self._trajectory: Trajectory | None = None
        self._steps = 0
        self.policies: dict[str, int] = {}

    def command(self, snapshot: WorldSnapshot, auditor: Auditor) -> TrajectoryState:
        """Plan if due, then the guarded state for ``snapshot.time + step``."""
        t_next = snapshot.time + self.spec.step_s
        if self._steps % self.planner.config.replan_every == 0 or self._trajectory is None or \
                self._trajectory.end < t_next:
            result = self.planner.plan(snapshot, self.ego_id)
            self._trajectory = result.trajectory
            self.policies[result.policy] = self.policies.get(result.policy, 0) + 1
        self._steps += 1
        ego = snapshot.index_of(self.ego_id)
        return self.guard.apply(snapshot, ego, self.planner.frame_for(snapshot, ego),
                                self._trajectory.state_at(t_next), auditor.owed_by(self.ego_id))

    def summary(self) -> dict:
        """Cycle times [ms], backups, lane changes, guard interventions, chosen policies, and how many agent
        beliefs came from the intention network (per cycle and agent)."""
        times = np.array(self.planner.stats.cycle_times) * 1000.0
        stats = {"cycles": int(times.size), "backups": self.planner.stats.backups,
                 "lane_changes_started": self.planner.manager.lane_changes_started,
                 "lane_changes_completed": self.planner.manager.lane_changes_completed,
                 "guard": self.guard.counts.as_dict(),
                 "intention_net_beliefs": self.planner.stats.learned_beliefs,
                 "stop_line_cycles": {k or "none": v for k, v in sorted(self.planner.stats.stop_lines.items())},
                 "policies": dict(sorted(self.policies.items()))}
        if times.size:
            stats |= {"cycle_ms_median": float(np.median(times)), "cycle_ms_p95": float(np.percentile(times, 95)),
                      "cycle_ms_p99": float(np.percentile(times, 99))}
        return stats
