"""``controller = "sumo_restricted"``: SUMO's own driver models drive the ego, and the ego's RSS proper-response
guard restricts them every step, as CARLA's RssRestrictor restricts its autopilot (epsilon.md port decision 8's
baselines; issue 48, decision 3: a baseline that is held to the same RSS duties as the planner).

Longitudinal: every step the guard (:class:`~.guard.ProperResponseGuard`, fed by the auditor's open episodes)
bounds the speed the ego may have at the end of the step, probed with the ego at SUMO's full acceleration; where
that bound is below what SUMO could reach, it is a speed cap (``setSpeed`` with SUMO's safety checks on, so SUMO's
model still drives slower where it wants to). Lateral: SUMO's lane changes are continuous manoeuvres at a fixed
lateral speed that cannot be called off once started, so the guard's lateral rules apply when one would start: RSS
allows a change to a side if the ego owes no lateral response towards it, and no car that the whole manoeuvre
(not that car's own lateral motion) makes laterally unsafe is then longitudinally unsafe to the ego, at that
moment or ``COMMIT_S`` later at constant speeds (RSS's cut-in rule, as the planner's virtual barrier applies it).
Where RSS allows both sides, SUMO changes lanes on its own, as it would unrestricted; else it changes only on
request, and the change its lane-change model wants is requested (for the next step) only towards an allowed side.
Units: m, s, m/s, m/s².
"""
from __future__ import annotations

import numpy as np

from ..road.network import RoadNetwork
from ..rss import formulas
from ..rss.auditor import Auditor, ParamResolver
from ..scenario import ScenarioSpec
from ..sim import ego as actuation
from ..sim.snapshot import WorldSnapshot
from ..trajectory import TrajectoryState
from .frames import PlanningFrames
from .guard import ProperResponseGuard, lateral_safe_distances, local_scene
from .lanes import LEFT, RIGHT
from .road_frame import RoadFrame

CHECK_STEP = 0.1  # [s] between the checked moments of a lane-change manoeuvre
COMMIT_S = 1.0  # [s] a pair made laterally unsafe must stay longitudinally safe this long (constant speeds)
CAP_TOLERANCE = 1e-3  # [m/s] a cap this far above the probe's speed is none; a speed this close to the cap is it


class RestrictedSumoDriver:
    """One per run. ``command(snapshot, auditor)`` restricts SUMO's models for the coming step and returns None:
    SUMO moves the ego itself."""

    def __init__(self, spec: ScenarioSpec, network: RoadNetwork, audit_params: ParamResolver):
        self.ego_id = spec.ego.id
        self.dt = spec.step_s
        self.accel = spec.ego.vehicle.accel  # [m/s²] the most SUMO's model accelerates the ego
        self.lane_change_s = spec.sumo.lanechange_duration_s
        self.frames = PlanningFrames(network)
        self.guard = ProperResponseGuard(audit_params, spec.step_s)
        self._handed_over = False
        self._capped: float | None = None
        self._own_changes = True  # SUMO's own lane changes are on (its default mode)
        self.steps = 0
        self.capped_steps = 0  # steps that ended at the cap (SUMO's model would have gone at least as fast)
        self.changes_requested = 0  # changes requested where RSS allowed one side only
        self.changes_refused = 0  # steps in which SUMO wanted a change that RSS did not allow

    def command(self, snapshot: WorldSnapshot, auditor: Auditor) -> None:
        """Set the speed cap and request the lane change (if any) for the step from ``snapshot.time``."""
        if not self._handed_over:
            actuation.restrict(self.ego_id)
            self._handed_over = True
        ego = snapshot.index_of(self.ego_id)
        v0 = float(snapshot.speed[ego])
        if self._capped is not None and abs(v0 - self._capped) < CAP_TOLERANCE:  # the cap, not its own model's less
            self.capped_steps += 1
        self.steps += 1
        owed = auditor.owed_by(self.ego_id)
        frame = self.frames.planning_lane(snapshot, ego)[1]
        probe = self._full_acceleration(snapshot, ego, frame)
        guarded = self.guard.apply(snapshot, ego, frame, probe, owed)
        self._capped = guarded.speed if guarded.speed < probe.speed - CAP_TOLERANCE else None
        actuation.cap_speed(self.ego_id, self._capped)
        lane = int(self.frames.network.lane_indices(snapshot.lane_id[ego:ego + 1])[0])
        neighbours = {1: self.frames.network.lane_left[lane], -1: self.frames.network.lane_right[lane]}
        allowed = {side: bool(neighbours[side] < 0 or self.lane_change_allowed(snapshot, ego, frame, side, owed))
                   for side in (1, -1)}
        free = all(allowed.values())
        if free != self._own_changes:
            actuation.own_lane_changes(self.ego_id, free)
            self._own_changes = free
        wanted = 0 if free else actuation.wanted_lane_change(self.ego_id)
        if wanted and allowed[wanted]:
            actuation.change_lane(self.ego_id, wanted, self.dt)
            self.changes_requested += 1
        elif wanted:
            self.changes_refused += 1
        return None

    def _full_acceleration(self, snapshot: WorldSnapshot, ego: int, frame: RoadFrame) -> TrajectoryState:
        """Where the ego is after the step at SUMO's full acceleration, keeping its heading and lateral speed."""
        half = 0.5 * float(snapshot.length[ego])
        s, d, h = frame.centre_of_bumper(snapshot.x[ego], snapshot.y[ego], snapshot.heading[ego], half)
        v0 = float(snapshot.speed[ego])
        v1 = v0 + self.accel * self.dt
        x, y, heading = frame.bumper_at(s + 0.5 * (v0 + v1) * self.dt * np.cos(h),
                                        d + float(snapshot.lat_speed[ego]) * self.dt, h, half)
        return TrajectoryState(float(x[0]), float(y[0]), float(heading[0]), v1, self.accel)

    def lane_change_allowed(self, snapshot: WorldSnapshot, ego: int, frame: RoadFrame, direction: int,
                            owed) -> bool:
        """Whether RSS allows a lane change starting now to the left (``direction`` +1) or right (-1): the
        manoeuvre moves the ego's centre to the target lane's at a constant lateral speed over the lane-change
        duration, the others keep their speeds (see the module docstring)."""
        target = LEFT if direction > 0 else RIGHT
        if not frame.exists[target] or np.any(owed.owed_lat & (owed.other_is_left == (direction > 0))):
            return False
        near, s, d, _, me, others = local_scene(snapshot, ego, frame)
        if others.size == 0:
            return True
        params = self.guard.params.arrays(snapshot)
        p_e, p_o = params.take(np.array([ego])), params.take(near[others])
        s0, d0, v0 = float(s[me]), float(d[me]), float(snapshot.speed[ego])
        shift = float(frame.centre_d(target, s0)) - d0
        u = shift / self.lane_change_s  # [m/s] the ego's lateral speed in the manoeuvre (+ = left)
        t = np.arange(0.0, self.lane_change_s + 0.5 * CHECK_STEP, CHECK_STEP)[:, None]  # [K, 1]
        rows = near[others]
        v_o, u_o = snapshot.speed[rows], snapshot.lat_speed[rows]
        w = 0.5 * (snapshot.width[ego] + snapshot.width[rows])
        other_left = d[others] > d0
        d_o = d[others] + u_o * t
        gap_moving = np.abs(d_o - (d0 + u * t)) - w
        gap_still = np.abs(d_o - d0) - w
        made_unsafe = ~formulas.is_safe_distance(gap_moving, lateral_safe_distances(other_left, u_o, u, p_o, p_e)) & \
            formulas.is_safe_distance(gap_still, lateral_safe_distances(other_left, u_o, 0.0, p_o, p_e))
        safe_now = formulas.is_safe_distance(np.abs(d[others] - d0) - w,
                                             lateral_safe_distances(other_left, u_o, 0.0, p_o, p_e))
        concerned = safe_now & made_unsafe.any(axis=0)
        if not np.any(concerned):
            return True
        when = t[made_unsafe.argmax(axis=0), 0][concerned]  # [s] the first moment each pair turns unsafe
        k = np.flatnonzero(concerned)
        ahead = s[others][k] > s0
        lon_min = np.where(ahead, formulas.lon_safe_distance_same_dir(v0, v_o[k], p_e, p_o.take(k)),
                           formulas.lon_safe_distance_same_dir(v_o[k], v0, p_o.take(k), p_e))
        half = 0.5 * (snapshot.length[ego] + snapshot.length[rows][k])
        for moment in (when, when + COMMIT_S):
            gap = np.abs(s[others][k] + v_o[k] * moment - (s0 + v0 * moment)) - half
            if not np.all(formulas.is_safe_distance(gap, lon_min)):
                return False
        return True

    def summary(self) -> dict:
        """planner.json of a restricted run: steps, steps the speed cap bound, lane changes requested (where RSS
        allowed one side only) and refused, and the guard's counts (taken with the ego probed at full acceleration: how often each rule bounded it)."""
        return {"controller": "sumo_restricted", "steps": self.steps, "capped_steps": self.capped_steps,
                "lane_changes_requested": self.changes_requested, "lane_changes_refused": self.changes_refused,
                "guard_bounds": self.guard.counts.as_dict()}
