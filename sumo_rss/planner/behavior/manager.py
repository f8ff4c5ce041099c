"""EUDM manager (epsilon.md §2.7): ongoing action, lane-change context with hysteresis, reselection.

The planner itself proposes lane changes: when the cheapest policy is the same lane change for
``consistency_frames`` cycles in a row, a context is created whose operation time lies at least
``min_operation_delay`` s ahead on the decision grid. Until then only keep sequences may be executed; from then
on keep sequences or the context's direction (which the navigation cost rewards). A *mandatory* change (the
ego's lane ends ahead) skips the speed window and the cool-down, and its context does not expire while the ego
waits for a gap: dropping it would shut lane changes out for the next ``min_operation_delay`` s and more, which
at the end of an acceleration lane is just when a gap may come.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .dcp_tree import Action, Lat, Policy, ongoing_action
from .evaluation import Navigation


@dataclass(frozen=True)
class ManagerSettings:
    """epsilon.md §9 'active LC' defaults."""

    cold_duration: float = 5.0  # [s] between two triggers
    min_speed: float = 4.0  # [m/s] speed window of discretionary changes
    # Its upper end as a multiple of the ego's desired speed: the release's 24 m/s is 1.2 x its demo's 20 m/s; a
    # fixed 24 m/s would rule out discretionary changes at highway cruising speeds.
    max_speed_ratio: float = 1.2
    max_operation_delay: float = 3.8  # [s]
    min_operation_delay: float = 2.0  # [s]
    consistency_gap: float = 0.5  # [s]
    consistency_frames: int = 4
    outdated_after: float = 15.0  # [s] a context is dropped this long after its operation time


@dataclass(frozen=True)
class LaneChangeContext:
    direction: Lat
    trigger_time: float  # [s]
    operation_time: float  # [s] from when the change may be executed
    start_lanes: frozenset[int]  # the lanes of the chain the ego started on
    mandatory: bool = False  # the ego's lane ends: the context stays until the change is done


class Manager:
    """State kept between planning cycles."""

    def __init__(self, settings: ManagerSettings = ManagerSettings(), layer_duration: float = 1.0,
                 desired_speed: float = 20.0):
        """``layer_duration`` [s]: the decision grid; ``desired_speed`` [m/s]: the ego's."""
        self.settings = settings
        self.layer_duration = layer_duration
        self.max_speed = settings.max_speed_ratio * desired_speed  # [m/s] top of the speed window
        self.policy: Policy | None = None
        self.policy_start = 0.0
        self.context: LaneChangeContext | None = None
        self.last_trigger = -math.inf
        self._proposals: list[tuple[Lat, int, float]] = []
        self.lane_changes_started = 0
        self.lane_changes_completed = 0
        self.lane_changes_called_off = 0

    def ongoing(self, now: float) -> Action:
        """The action in force now; its lateral part is kept only while a lane-change context is active."""
        return ongoing_action(self.policy, now - self.policy_start, self.layer_duration,
                              lane_change_active=self.context is not None)

    def update_context(self, now: float, ego_lane: int) -> None:
        """Complete the context once the ego left its starting lanes; drop it when outdated."""
        ctx = self.context
        if ctx is None:
            return
        if ego_lane not in ctx.start_lanes:
            self.context = None
            self.lane_changes_completed += 1
        elif not ctx.mandatory and now > ctx.operation_time + self.settings.outdated_after:
            self.context = None

    def navigation(self, now: float) -> Navigation:
        ctx = self.context
        due = ctx is not None and now >= ctx.operation_time - 1e-9
        return Navigation(recommended=ctx.direction if due else None)

    def select(self, policies: list[Policy], cost: np.ndarray, valid: np.ndarray, now: float) -> int | None:
        """Index of the cheapest valid policy the context allows (None: nothing allowed)."""
        ctx = self.context
        allowed = np.array([self._allowed(p, ctx, now) for p in policies], dtype=bool) & valid
        if not np.any(allowed):
            return None
        return int(np.flatnonzero(allowed)[np.argmin(cost[allowed])])

    def _allowed(self, policy: Policy, ctx: LaneChangeContext | None, now: float) -> bool:
        keep_only = all(lat is Lat.KEEP for lat in policy.lats)
        if ctx is None or now < ctx.operation_time - 1e-9:  # before the operation time only the change under way
            return keep_only or (ctx is not None and policy.lats[0] is ctx.direction)
        return keep_only or policy.lateral is ctx.direction

    def propose(self, winner: Policy | None, now: float, speed: float, ego_lane: int, start_lanes: frozenset[int],
                mandatory: Lat | None) -> None:
        """Track the unconstrained winner; trigger a lane-change context after enough consistent cycles."""
        s = self.settings
        if self.context is not None or winner is None or winner.lateral is Lat.KEEP or winner.is_cancel:
            self._proposals.clear()
            return
        forced = mandatory is winner.lateral
        if not forced and (now - self.last_trigger < s.cold_duration or not s.min_speed <= speed <= self.max_speed):
            self._proposals.clear()  # the consistent cycles must all be eligible ones (as the release clears them)
            return
        operation = sum(winner.durations[:winner.lats.index(winner.lateral)])  # time until the change starts
        self._proposals.append((winner.lateral, ego_lane, now + operation))
        self._proposals = self._proposals[-s.consistency_frames:]
        if len(self._proposals) < s.consistency_frames or operation > s.max_operation_delay:
            return
        first = self._proposals[0]
        if any(p[0] is not first[0] or p[1] != first[1] or abs(p[2] - first[2]) > s.consistency_gap
               for p in self._proposals):
            return
        earliest = now + max(operation, s.min_operation_delay)
        operation_time = math.ceil(earliest / self.layer_duration - 1e-9) * self.layer_duration
        self.context = LaneChangeContext(winner.lateral, now, operation_time, start_lanes, forced)
        self.last_trigger = now
        self.lane_changes_started += 1
        self._proposals.clear()

    def call_off(self) -> None:
        """Drop the lane-change context (a discretionary change that cannot get going: see EpsilonPlanner.plan);
        the cool-down since its trigger still applies to the next proposal."""
        self.context = None
        self.lane_changes_called_off += 1

    def commit(self, policy: Policy, now: float) -> None:
        self.policy, self.policy_start = policy, now
