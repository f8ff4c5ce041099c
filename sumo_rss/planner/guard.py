"""RSS proper-response guard on the executed ego command (epsilon.md port decision 4; rss.md §5), in the manner
of ad_rss's ProperResponse / CARLA's RssRestrictor.

Before the planned state for the next step is sent to SUMO it is restricted by
- the responses the ego owes in its open RSS episodes (from the auditor): no more than a_acc during ρ, at least
  b_min (b_corr) braking after ρ until stopped and then no moving off while the episode lasts (it would owe
  braking again at once), never harder than b_max where the ego is the front car, and a
  lateral speed towards the other car inside its braking envelope, towards the side the auditor will judge at
  the step planned (the cars as they will be then, in line or not);
- two predictive rules that keep the ego from *entering* danger by its own motion: no acceleration while the
  gap to a car ahead in its path is not RSS-safe (where the ego owes that car no longitudinal braking, e.g. it
  cut in, the ego may keep up with it but not close in), and no lateral motion that would make a pair
  laterally unsafe while it is longitudinally unsafe;
- emergency braking: where a car ahead in its path, going on as it does (braking at its present deceleration),
  would be hit unless the ego brakes harder than b_min, the ego brakes as hard as that needs, up to its b_max
  (a car that cut in close and then braked hard: the planner, within its comfort limits, brakes at most 5 m/s²
  and ramps up to it).
Every restriction that changes the command beyond the guard's own margins is counted. Units: m, s, m/s, m/s².
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..rss import formulas
from ..rss.auditor import ParamResolver
from ..rss.params import RssParamArrays
from ..rss.compliance import in_line, lateral_speed_bound
from ..rss.owed_responses import OwedResponses
from ..rss.sorted_keys import find_sorted
from ..sim.snapshot import WorldSnapshot
from ..trajectory import TrajectoryState
from .road_frame import RoadFrame

ACCEL_MARGIN = 0.1  # [m/s²] kept inside every acceleration bound (the auditor's tolerance is 0.05)
STOPPED = 0.05  # [m/s]
COUNT_TOLERANCE = 1e-3  # [m/s] smaller lateral corrections are made but not counted as interventions
NEIGHBOURHOOD = 150.0  # [m] other cars farther than this are ignored
EMERGENCY_GAP = 1.0  # [m] emergency braking stops the ego this far behind the car ahead
MIN_DECEL, MAX_DECEL = 1e-3, 1e3  # [m/s²] avoiding_decel's range
PREDICTION_ITERATIONS = 3  # fixed-point steps for the speed that is RSS-safe at the next step (converge ~10x each)


@dataclass
class GuardCounts:
    """How often each restriction changed the command."""

    lon_owed: int = 0
    lat_owed: int = 0
    lon_predictive: int = 0
    lat_predictive: int = 0
    emergency: int = 0
    steps: int = 0
    log: list[tuple[float, str]] = field(default_factory=list)

    def as_dict(self) -> dict[str, int]:
        return {"lon_owed": self.lon_owed, "lat_owed": self.lat_owed, "lon_predictive": self.lon_predictive,
                "lat_predictive": self.lat_predictive, "emergency": self.emergency, "steps": self.steps}


def avoiding_decel(gap: np.ndarray, v: float, v_lead: np.ndarray, b_lead: np.ndarray) -> np.ndarray:
    """[m/s²] The least constant deceleration that keeps a car at ``v`` [m/s] from reaching a car ``gap`` [m] ahead
    at ``v_lead`` that brakes at ``b_lead`` (≥ 0) until it stands: 0 where below MIN_DECEL, at most MAX_DECEL.

    Braking at a, the gap is least where both stand or where the speeds meet while both move. Both standing
    needs a ≥ a_rest = v²/(2·(gap + S_lead)), S_lead the leader's stopping distance (inf: it goes on). The
    speeds meet while both move iff the car is faster and would stop first, a·v_lead > b_lead·v; the gap then
    shrinks by (v − v_lead)²/(2·(a − b_lead)), which needs a ≥ a_meet = b_lead + (v − v_lead)²/(2·gap). So
    a_rest is the answer where braking at it the car stops no sooner than the leader, else max(a_rest, a_meet)
    (at a = b_lead·v/v_lead both gaps agree, so the answer is where the gap first stays ≥ 0)."""
    gap, v_lead, b_lead = (np.asarray(x, dtype=float) for x in (gap, v_lead, b_lead))
    with np.errstate(divide="ignore", invalid="ignore"):
        lead_stop = np.where(v_lead <= 0.0, 0.0, np.where(b_lead > 0.0, v_lead * v_lead / (2.0 * b_lead), np.inf))
        a_rest = v * v / (2.0 * (gap + lead_stop)) if v > 0.0 else np.zeros(gap.shape)
        a_meet = b_lead + (v - v_lead) ** 2 / (2.0 * gap)
        meets_first = (v > v_lead) & (np.maximum(a_rest, MIN_DECEL) * v_lead > b_lead * v)
    least = np.where(meets_first, np.maximum(a_rest, a_meet), a_rest)
    return np.where(least <= MIN_DECEL, 0.0, np.minimum(least, MAX_DECEL))


def local_scene(snapshot: WorldSnapshot, ego: int, frame: RoadFrame
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, np.ndarray]:
    """The cars within NEIGHBOURHOOD of the ego in ``frame``: their snapshot rows, centres (s, d) [m] and headings
    relative to the frame [rad], the ego's position among them (its centre from its bumper, as the planner places
    it: RoadFrame.bumper_at) and the others' positions."""
    cx, cy = snapshot.centres()
    near = np.flatnonzero(np.hypot(cx - cx[ego], cy - cy[ego]) < NEIGHBOURHOOD)
    s, d, h = frame.to_frame(cx[near], cy[near], snapshot.heading[near])
    me = int(np.flatnonzero(near == ego)[0])
    s_c, d_c, h_c = frame.centre_of_bumper(snapshot.x[ego], snapshot.y[ego], snapshot.heading[ego],
                                           0.5 * float(snapshot.length[ego]))
    s[me], d[me], h[me] = s_c[0], d_c[0], h_c[0]
    return near, s, d, h, me, np.delete(np.arange(near.size), me)


class ProperResponseGuard:
    def __init__(self, params: ParamResolver, step: float):
        self.params = params
        self.dt = step
        self.counts = GuardCounts()

    def apply(self, snapshot: WorldSnapshot, ego: int, frame: RoadFrame, planned: TrajectoryState,
              owed: OwedResponses) -> TrajectoryState:
        """The planned state for ``snapshot.time + dt``, restricted as above."""
        dt, c = self.dt, self.counts
        c.steps += 1
        p_all = self.params.arrays(snapshot)
        p_e = p_all.take(np.array([ego]))
        near, s, d, h, me, others = local_scene(snapshot, ego, frame)
        half = 0.5 * float(snapshot.length[ego])
        s_c, d_c, h_c = frame.centre_of_bumper(planned.x, planned.y, planned.heading, half)
        s0, d0, v0 = float(s[me]), float(d[me]), float(snapshot.speed[ego])
        s1, d1, h1 = float(s_c[0]), float(d_c[0]), float(h_c[0])
        accel = (planned.speed - v0) / dt
        t_next = snapshot.time + dt

        # 1. Owed longitudinal responses.
        tau = t_next - owed.t_b
        rho, a_acc = float(p_e.response_time[0]), float(p_e.lon_accel_max[0])
        upper, lower = np.inf, -np.inf
        rho_owed = np.where(owed.no_response_time, 0.0, rho)  # none after moving off from standing (moving_off.py)
        if np.any(owed.must_brake & (tau <= rho_owed + 1e-9)):
            upper = a_acc - ACCEL_MARGIN
        late = owed.must_brake & (tau > rho_owed + 1e-9)
        if np.any(late) and v0 >= STOPPED:
            brake = np.where(owed.brake_correct[late], p_e.lon_brake_min_correct[0], p_e.lon_brake_min[0])
            upper = min(upper, -float(brake.max()) - ACCEL_MARGIN)
        elif np.any(late):  # stopped while braking is owed: it stays stopped (moving off would owe b_min again)
            upper = min(upper, 0.0)
        if np.any(owed.front_limited):
            lower = -float(p_e.lon_brake_max[0]) + ACCEL_MARGIN
        if upper < lower:  # braking owed as the rear car, b_max as the front car, closer than two margins
            upper = lower = 0.5 * (upper + lower)  # between b_min and b_max: both duties met
        limited = float(np.clip(accel, lower, upper))
        if limited != accel:
            # Counted where the plan itself broke the duty, not where only the guard's margin moved it.
            c.lon_owed += int(abs(limited - accel) > ACCEL_MARGIN + 1e-9)
            accel = limited

        # 2. No acceleration while a car ahead in the ego's path is closer than the RSS distance.
        ds = s[others] - s0
        v_o = snapshot.speed[near[others]]
        lat_gap = np.abs(d[others] - d0) - 0.5 * (snapshot.width[ego] + snapshot.width[near[others]])
        p_o = p_all.take(near[others])
        lat_min_now = formulas.lat_safe_distance(0.0, 0.0, p_e, p_o)
        in_path = (ds > 0.0) & ~formulas.is_safe_distance(lat_gap, lat_min_now)
        gap_ahead = ds[in_path] - 0.5 * (snapshot.length[ego] + snapshot.length[near[others]][in_path])  # bumpers
        if accel > 0.0 and np.any(in_path):
            # Safe at the next step: the gap then, closed at the mean of the ego's speeds against the other's.
            p_path = p_o.take(np.flatnonzero(in_path))
            # The iterates alternate around that speed: the lesser of the last two is on the safe side of it.
            v_up = previous = formulas.max_safe_speed_behind(gap_ahead, v_o[in_path], p_e, p_path)
            for _ in range(PREDICTION_ITERATIONS):
                gap_next = np.maximum(gap_ahead - (0.5 * (v0 + np.maximum(v_up, 0.0)) - v_o[in_path]) * dt, 0.0)
                previous, v_up = v_up, formulas.max_safe_speed_behind(gap_next, v_o[in_path], p_e, p_path)
            v_up = np.minimum(v_up, previous)
            # A car going its way that the ego owes no longitudinal braking (it cut in): the ego may keep up with
            # it, not close in.
            cut_in = np.isin(snapshot.ids[near[others]][in_path], list(owed.without_lon_duty()))
            v_up = np.where(cut_in, np.maximum(v_up, v_o[in_path]), v_up)
            cap = max(0.0, (float(np.min(v_up)) - v0) / dt)
            if cap < accel:
                c.lon_predictive += 1
                accel = cap
        # 2b. Emergency braking for a car in the path that would be hit otherwise.
        if np.any(in_path) and v0 >= STOPPED:
            b_lead = np.maximum(-snapshot.accel[near[others]][in_path], 0.0)
            needed = float(np.max(avoiding_decel(np.maximum(gap_ahead - EMERGENCY_GAP, 0.0), v0, v_o[in_path],
                                                 b_lead)))
            if needed > float(p_e.lon_brake_min[0]):
                cap = -min(needed + ACCEL_MARGIN, float(p_e.lon_brake_max[0]) - ACCEL_MARGIN)
                if cap < accel:
                    c.emergency += 1
                    accel = cap
        v1 = max(v0 + accel * dt, 0.0)

        # 3. Owed lateral responses: speed towards the other inside the envelope. The auditor measures the
        # lateral speed of the front bumper across the ego's SUMO lane (the frame's centre line), so the envelope
        # is checked on the bumper's lateral speed and the correction applied to the bumper's offset.
        bumper_d0 = float(d[me]) + half * np.sin(float(h[me]))
        u_plan = (d1 + half * np.sin(h1) - bumper_d0) / dt  # + = left
        u_planned = u_plan
        duty = np.asarray(owed.lat_duty, dtype=bool)
        if np.any(duty):
            # The auditor's envelope with ACCEL_MARGIN kept inside both of its accelerations.
            bound = np.where(owed.lat_settled, 0.0,
                             lateral_speed_bound(owed.u0, tau, rho, float(p_e.lat_accel_max[0]) - ACCEL_MARGIN,
                                                 float(p_e.lat_brake_min[0]) + ACCEL_MARGIN))
            sides = _SidesAtNextStep(owed, duty, snapshot, p_all, near, d, u_planned, d1, dt,
                                     float(p_e.lat_fluctuation_margin[0]))
            # Each restriction moves the ego away from a side (towards 0 lateral speed, never past it), which can
            # only end an in-line exemption: repeated until the sides judged after the move stand.
            for _ in range(len(owed) + 1):
                left, right = sides.judged(u_plan)
                limited = float(np.clip(u_plan, -np.min(bound[right], initial=np.inf),
                                        np.min(bound[left], initial=np.inf)))
                if limited == u_plan:
                    break
                u_plan = limited
            c.lat_owed += int(abs(u_plan - u_planned) > COUNT_TOLERANCE)

        # 4. No lateral motion into a pair that is longitudinally unsafe.
        if abs(u_plan) > 1e-9:
            other_left = d[others] > d0
            u_towards = np.where(other_left, u_plan, -u_plan)

            def lat_min(u_other: np.ndarray, u_ego: float) -> np.ndarray:
                return lateral_safe_distances(other_left, u_other, u_ego, p_o, p_e)

            u_other = snapshot.lat_speed[near[others]]
            lat_min_now = lat_min(u_other, float(snapshot.lat_speed[ego]))
            # The others keep their lateral speeds over the step; the gap then with and without the ego's move.
            still_gap = lat_gap - np.where(other_left, -u_other, u_other) * dt
            gap = np.abs(ds) - 0.5 * (snapshot.length[ego] + snapshot.length[near[others]])
            lon_min = np.where(ds > 0.0, formulas.lon_safe_distance_same_dir(v1, v_o, p_e, p_o),
                               formulas.lon_safe_distance_same_dir(v_o, v1, p_o, p_e))
            # Pairs laterally safe now that the ego's move (and not the other's alone) would make unsafe while
            # they are longitudinally unsafe.
            entering = (u_towards > 0.0) & ~formulas.is_safe_distance(gap, lon_min) & \
                formulas.is_safe_distance(lat_gap, lat_min_now) & \
                formulas.is_safe_distance(still_gap, lat_min(u_other, 0.0)) & \
                ~formulas.is_safe_distance(still_gap - u_towards * dt, lat_min(u_other, u_plan))
            if np.any(entering):
                c.lat_predictive += int(abs(u_plan) > COUNT_TOLERANCE)
                u_plan = 0.0

        lateral_changed = abs(u_plan - u_planned) > 1e-9
        if v1 == planned.speed and not lateral_changed:
            return TrajectoryState(planned.x, planned.y, planned.heading, v1, (v1 - v0) / dt)
        # The planned heading is kept; the centre moves by the guarded speed along it and the bumper's
        # offset by the guarded lateral speed.
        travelled = 0.5 * (v0 + v1) * dt
        s_new = s0 + travelled * np.cos(h1) if v1 != planned.speed else s1
        d_new = d1 + (u_plan - u_planned) * dt
        x, y, heading = frame.bumper_at(np.array([s_new]), np.array([d_new]), np.array([h1]), half)
        return TrajectoryState(float(x[0]), float(y[0]), float(heading[0]), v1, (v1 - v0) / dt)


class _SidesAtNextStep:
    """The sides towards which the auditor will judge the ego's lateral speed at the step being planned, per open
    episode that owes the lateral response, for a lateral speed u [m/s] of the ego's bumper: the side each other car
    is on then, or none where the two are in line then (compliance.in_line, the auditor's own test).

    The other car is taken anywhere between where it is and where its present lateral speed takes it over the
    step (a car in a lane change: its centre moves slower than its bumper while it turns in); every side it can be
    on apart from the ego there is judged. Another car outside the guard's neighbourhood keeps the side the
    auditor last saw (in line now: none)."""

    def __init__(self, owed: OwedResponses, duty: np.ndarray, snapshot: WorldSnapshot, p_all: RssParamArrays,
                 near: np.ndarray, d: np.ndarray, u_planned: float, d1: float, dt: float, mu_ego: float):
        ids = snapshot.ids[near]
        order = np.argsort(ids)
        found, at = find_sorted(ids[order], owed.other_id)
        found &= duty
        k = order[at]
        d_other = d[k]
        # Where the other car can be at the next step.
        self.d_other = np.stack([d_other, d_other + snapshot.lat_speed[near[k]] * dt])
        self.mu_other, self.mu_ego = p_all.lat_fluctuation_margin[near[k]], mu_ego
        self.found = found
        self.fallback_left = duty & ~found & owed.owed_lat & owed.other_is_left
        self.fallback_right = duty & ~found & owed.owed_lat & ~owed.other_is_left
        self.u_planned, self.d1, self.dt = u_planned, d1, dt

    def judged(self, u: float) -> tuple[np.ndarray, np.ndarray]:
        """(towards the left, towards the right) per episode, the ego's bumper moving across at ``u``."""
        d_ego = self.d1 + (u - self.u_planned) * self.dt  # its centre at the next step
        offset = self.d_other - d_ego
        apart = ~in_line(np.abs(offset), self.mu_other, self.mu_ego) & self.found
        left = np.any(apart & (offset > 0.0), axis=0) | self.fallback_left
        right = np.any(apart & (offset < 0.0), axis=0) | self.fallback_right
        return left, right


def lateral_safe_distances(other_left: np.ndarray, u_other: Any, u_ego: Any, p_o: RssParamArrays, p_e: RssParamArrays
             ) -> np.ndarray:
    """Safe lateral distances [m] between the ego and cars on its left (``other_left``) or right, for their and
    the ego's lateral speeds (+ = left), each car's reach with its own parameters (rss.md §2)."""
    return formulas.combine_lateral(formulas.lateral_reach(np.where(other_left, -u_other, u_other), p_o),
                                    formulas.lateral_reach(np.where(other_left, u_ego, -u_ego), p_e),
                                    p_o.lat_fluctuation_margin, p_e.lat_fluctuation_margin)
