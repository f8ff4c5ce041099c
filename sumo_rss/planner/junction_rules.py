"""Where the ego must stop before a junction (epsilon.md port decision 5: red lights and yield lines are
semantic constraints; a stop line is an s upper bound of the ego's motion).

The ego approaching a junction on its route stops at the stop line (the end of its lane):
- on **red**, and on **yellow** when it can still stop there at its RSS b_min (rss.md's signal rule);
- to **yield** to a vehicle on a conflicting link that has priority over the ego's link (by the signals where
  both links are signalised and their states differ, else by the junction's static priority), unless that
  vehicle reaches the conflict area only ``YIELD_MARGIN`` s or more after the ego would have cleared it, driving
  as the planner drives it (:class:`Crossing`: its acceleration, its reference speed through the turn), and their
  pair stays RSS-safe (rss.md §4) all along the ego's crossing with that vehicle moving on at its speed: once the
  ego cannot stop before the area only "in front" keeps them safe, and where it fails the ego owes braking inside
  the junction (intersection_priority seed 17 with a = 2.6 m/s²: the guard stopped it 1.0 m inside, where it
  stood for the rest of the run; docs/planner.md "A start under way"). An ego already **committed**
  (:meth:`Crossing.stopping_distance`: braking as the planner can, it would stop past the line) goes on unless
  such a vehicle is in the area or reaches it before the ego has cleared it (no margin): stopping would stand it
  inside the junction;
- for **RSS**: while a vehicle stands before a conflict area of the ego's way (slower than ``MIN_SPEED``, or in
  front of the ego on RSS's virtual line and unable to stop before the area) and the ego's crossing, with that
  vehicle held, would make their pair unsafe (rss.md §4) somewhere: the rule keeping it safe is "in front", so
  the ego, its rear car, would owe braking inside the junction. On intersection_tls a car waiting at red 1.2 m
  before the area its left turn shares with the ego's cannot stop before it by RSS's worst case (accelerating
  during ρ), and the ego that entered was held inside the junction for over a minute (docs/planner.md step 2);
- never once it can no longer stop at the line at its RSS b_max (it drives on; the RSS guard still applies).
Vehicles on conflicting approaches are the junction's key vehicles for this rule. Pure numpy, no libsumo.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .behavior.controllers import VehicleLimits
from ..road.junctions import JunctionModel
from ..road.network import RoadNetwork
from ..road.routes import RouteTable
from ..rss.intersection import PRIORITY_B, IntersectionSafety, area_distances, intersection_safety, \
    junction_entries, link_priority, next_route_edge
from ..rss.params import RssParamArrays
from ..sim.snapshot import WorldSnapshot

STOP_RANGE = 150.0  # [m] stop lines farther ahead than this are not considered yet
STOP_MARGIN = 1.0  # [m] the front bumper stops this far before the line
YIELD_MARGIN = 2.0  # [s] time a prioritised vehicle must arrive after the ego has cleared their conflict area
CLEAR_ACCEL = 1.5  # [m/s²] acceleration assumed for the ego crossing the junction (without a Crossing)
MIN_SPEED = 0.5  # [m/s] slower vehicles outside the junction are waiting, not arriving
CROSSING_STEP = 0.5  # [m] spacing of the ego's positions checked against waiting vehicles
RED, YELLOW = "rRs", "yYu"  # SUMO signal characters that stop the ego


@dataclass(frozen=True)
class StopLine:
    """``distance`` [m] from the ego's front bumper to where it must stop (inf: drive on), and why;
    ``area_beyond`` [m]: how far past that point the first conflict area of the ego's way through the junction
    begins (inf: none), where RSS's "able to stop" is judged."""

    distance: float
    reason: str  # 'red' | 'yellow' | 'yield' | 'rss' | 'committed' (would have yielded; goes on) | '' (none)
    area_beyond: float = np.inf


NO_STOP = StopLine(np.inf, "")
COMMITTED = StopLine(np.inf, "committed")
MIN_CAP = 0.5  # [m/s] the lowest crossing speed assumed (a reference speed of 0 would never clear)


def _uncapped(start: float, length: float) -> float:
    return np.inf


@dataclass(frozen=True)
class Crossing:
    """How the ego crosses, for the yield timing and the RSS check along its way: accelerating at ``accel``
    [m/s²], at most at ``speed_cap(start, length)`` [m/s] over ``length`` m from ``start`` m past its front bumper
    (the planner's reference speed there: limits and curvature; slower at once where it is lower). An ego assumed
    to reach the junction faster than it drives started, found a car with priority would now arrive before it had
    cleared, and stopped again (intersection_tls: 1.5 m/s² and no cap assumed; the ego accelerates at 1.0 m/s² and
    turns left at 3 m/s). ``brake`` [m/s²] and ``brake_jerk`` [m/s³]: the hardest braking the planner drives the
    ego at and how fast it gets there (its bicycle model's limits), for whether it can still stop."""

    accel: float = CLEAR_ACCEL
    speed_cap: Callable[[float, float], float] = _uncapped
    brake: float = VehicleLimits.hard_brake
    brake_jerk: float = VehicleLimits.brake_jerk

    def stopping_distance(self, v: float, accel: float) -> float:
        """[m] the ego covers from speed ``v`` [m/s] and acceleration ``accel`` [m/s²] braking as hard as the
        planner can: its acceleration falling at ``brake_jerk`` to −``brake``, then held until it stands."""
        a0, j = max(accel, -self.brake), self.brake_jerk
        ramp = (a0 + self.brake) / j  # [s] until the braking is full
        halt = (a0 + np.sqrt(a0 * a0 + 2.0 * j * v)) / j  # [s] when it would stand while still ramping
        t = min(ramp, halt)
        covered = v * t + 0.5 * a0 * t * t - j * t ** 3 / 6.0
        v_full = max(v + a0 * t - 0.5 * j * t * t, 0.0)
        return float(covered + v_full * v_full / (2.0 * self.brake))

    def segments(self, to_line: float, clear: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """(length [m], speed cap [m/s]) of the way to the stop line ``to_line`` m ahead and of the rest of the
        ``clear`` m to cover."""
        to_line = max(to_line, 0.0)
        beyond = max(clear - to_line, 0.0)
        return ((to_line, max(self.speed_cap(0.0, to_line), MIN_CAP)),
                (beyond, max(self.speed_cap(to_line, beyond), MIN_CAP)))

    def time_to_cover(self, v: float, to_line: float, clear: float) -> float:
        """[s] to cover ``clear`` m from speed ``v`` [m/s], the stop line ``to_line`` m ahead."""
        elapsed = 0.0
        for length, cap in self.segments(to_line, clear):
            v = min(v, cap)
            if length <= 0.0:
                continue
            top = min(cap, float(np.sqrt(v * v + 2.0 * self.accel * length)))
            speeding_up = (top * top - v * v) / (2.0 * self.accel)
            elapsed += (top - v) / self.accel + (length - speeding_up) / top
            v = top
        return elapsed

    def times(self, v: float, covered: np.ndarray, to_line: float, clear: float) -> np.ndarray:
        """[s] to cover ``covered`` [m] (≤ ``clear``) from speed ``v`` [m/s], within the caps of
        :meth:`speeds`: :meth:`time_to_cover`'s steps per element."""
        (_, cap_line), (_, cap_beyond) = self.segments(to_line, clear)
        a, to_line = self.accel, max(to_line, 0.0)
        elapsed, v = np.zeros_like(covered), np.full_like(covered, v)
        for length, cap in ((np.minimum(covered, to_line), cap_line), (np.maximum(covered - to_line, 0.0), cap_beyond)):
            v = np.minimum(v, cap)
            top = np.minimum(cap, np.sqrt(v * v + 2.0 * a * length))
            step = (top - v) / a + (length - (top * top - v * v) / (2.0 * a)) / np.where(top > 0.0, top, 1.0)
            elapsed, v = elapsed + np.where(length > 0.0, step, 0.0), np.where(length > 0.0, top, v)
        return elapsed

    def speeds(self, v: float, covered: np.ndarray, to_line: float, clear: float) -> np.ndarray:
        """[m/s] the ego's speed after ``covered`` [m] (accelerating from ``v``, within the caps)."""
        (_, cap_line), (_, cap_beyond) = self.segments(to_line, clear)
        return np.minimum(np.sqrt(v * v + 2.0 * self.accel * covered), np.where(covered < to_line, cap_line,
                                                                                 cap_beyond))


def stop_line(snapshot: WorldSnapshot, ego: int, network: RoadNetwork, junctions: JunctionModel,
              routes: RouteTable, params: RssParamArrays, ego_moving: RssParamArrays | None = None,
              crossing: Crossing = Crossing()) -> StopLine:
    """Whether and where the ego (snapshot row ``ego``) must stop before the junction ahead; ``params`` are every
    snapshot row's RSS parameters: the ego stops for yellow if it can at its b_min, and for anything if it can at
    its b_max. ``ego_moving`` [1]: the ego's parameters once it moves, for its crossing (default: its row of
    ``params``, which ``ParamResolver.hold_standing`` gives a_acc = 0 while the ego stands); ``crossing``: how
    it drives through the junction."""
    b_min, b_max = float(params.lon_brake_min[ego]), float(params.lon_brake_max[ego])
    lanes = network.lane_indices(snapshot.lane_id)
    next_edge = next_route_edge(routes.remaining(snapshot), network.lane_edge[lanes])
    rows, link, pos = junction_entries(lanes, snapshot.lane_pos, next_edge, network, junctions, np.inf)
    mine = np.flatnonzero(rows == ego)
    if mine.size == 0 or junctions.lane_link[lanes[ego]] >= 0:  # no junction ahead, or already in it
        return NO_STOP
    own = int(link[mine[0]])
    distance = -float(pos[mine[0]]) - STOP_MARGIN
    if distance > STOP_RANGE:
        return NO_STOP
    conflicting = junctions.area_index[own] >= 0
    beyond = STOP_MARGIN + float(junctions.area_start[own, conflicting].min(initial=np.inf))
    v = float(snapshot.speed[ego])
    if distance < v * v / (2.0 * b_max):  # too late to stop at the line even at b_max: it drives on
        return NO_STOP
    # Braking as the planner drives it, it would stop past the line: stopping is no longer the safe choice.
    committed = crossing.stopping_distance(v, float(snapshot.accel[ego])) > distance + STOP_MARGIN
    ranks = junctions.signal_ranks(snapshot.tls_states)
    tls = junctions.link_tls[own]
    if tls and snapshot.tls_states and tls in snapshot.tls_states:
        state = snapshot.tls_states[tls][junctions.link_tls_index[own]]
        if state in RED:
            return StopLine(distance, "red", beyond)
        if state in YELLOW and distance >= v * v / (2.0 * b_min):
            return StopLine(distance, "yellow", beyond)
    foes = np.flatnonzero((rows != ego) & (junctions.area_index[own, link] >= 0))  # entries on conflicting links
    if foes.size == 0:
        return NO_STOP
    fl, cars = link[foes], rows[foes]
    priority = link_priority(junctions, ranks, own, fl)[0]  # as the auditor gives it (PRIORITY_A: the ego's)
    prioritised = priority == PRIORITY_B
    start, end = junctions.area_start[fl, own], junctions.area_end[fl, own]  # along each foe's link
    f_pos, f_v = pos[foes], snapshot.speed[cars]
    inside_area = (f_pos >= start) & (f_pos - snapshot.length[cars] <= end)
    arriving = (f_pos < start) & ((f_v >= MIN_SPEED) | (f_pos >= 0.0))
    t_foe = np.where(inside_area, 0.0, (start - f_pos) / np.maximum(f_v, MIN_SPEED))
    ego_pos = float(pos[mine[0]])
    # Per car, when the ego has cleared that car's own conflict area (a few distinct areas: one time each); the
    # whole crossing ends past the last of them.
    ends, area_of = np.unique(junctions.area_end[own, fl], return_inverse=True)
    to_clear = -ego_pos + ends + float(snapshot.length[ego])  # [m] from the ego's front bumper
    clear = float(to_clear[-1])
    t_clear = np.array([crossing.time_to_cover(v, -ego_pos, float(c)) for c in to_clear])[area_of]
    too_soon = prioritised & arriving & (t_foe < t_clear + YIELD_MARGIN)
    if np.any(prioritised & inside_area) or np.any(too_soon & (t_foe < t_clear if committed else True)):
        return StopLine(distance, "yield", beyond)
    # Who stands before the area while the ego crosses: who waits, and who is (still) in front of the ego on the
    # virtual line now without being able to stop before the area: once the ego closes in, the ego must brake.
    ego_now = params.take(np.array([ego]))
    now = _pair_safety(snapshot, ego, own, ego_pos, v, fl, cars, f_pos, f_v, priority, junctions, ego_now, params)
    ahead_unstoppable = now.b_in_front & now.in_front & ~now.able_to_stop
    waiting = (f_pos < start) & ((f_v < MIN_SPEED) | ahead_unstoppable)
    # Who comes with priority (at its speed): once the ego can not stop before the area, their pair is safe only
    # while the ego stays in front by that car's RSS distance; where that would fail on its way, it would owe
    # braking inside the junction.
    coming = prioritised & arriving & ~waiting & (not committed)
    if not np.any(waiting | coming):
        return COMMITTED if np.any(too_soon) else NO_STOP
    x = np.arange(ego_pos, float(junctions.area_end[own, fl].max()) + float(snapshot.length[ego]) + CROSSING_STEP,
                  CROSSING_STEP)[:, None]  # [k, 1] the ego's front bumper along its crossing
    v_x = crossing.speeds(v, x - ego_pos, -ego_pos, clear)
    crossing_params = ego_now if ego_moving is None else ego_moving
    for check, reason in ((waiting, "rss"), (coming, "yield")):
        w = np.flatnonzero(check)
        if w.size == 0:
            continue
        t_x = crossing.times(v, x - ego_pos, -ego_pos, clear) if reason == "yield" else 0.0
        along = _pair_safety(snapshot, ego, own, x, v_x, fl[w], cars[w], f_pos[w] + f_v[w] * t_x,
                             f_v[w] if reason == "yield" else np.zeros(w.size), priority[w],
                             junctions, crossing_params, params)
        on_way = area_distances(junctions, own, fl[w], x, float(snapshot.length[ego]))[1] > 0.0  # not yet left it
        if np.any(on_way & ~along.safe):
            return StopLine(distance, reason, beyond)
    return COMMITTED if np.any(too_soon) else NO_STOP


def _pair_safety(snapshot: WorldSnapshot, ego: int, own: int, ego_pos: Any, ego_v: Any, links: np.ndarray,
                 cars: np.ndarray, car_pos: np.ndarray, car_v: np.ndarray, priority: np.ndarray,
                 junctions: JunctionModel, ego_params: RssParamArrays, params: RssParamArrays) -> IntersectionSafety:
    """rss.md §4 between the ego on its link ``own`` (front bumper at ``ego_pos`` [m] along it, speed ``ego_v``
    [m/s]; arrays [k, 1] give k states; RSS parameters ``ego_params`` [1]) and ``cars`` on ``links`` (front bumpers
    at ``car_pos``, speeds ``car_v``; parameters: their rows of ``params``), per their conflict area;
    ``priority`` PRIORITY_A: the ego's, PRIORITY_B: the car's."""
    length, o_len = float(snapshot.length[ego]), snapshot.length[cars]
    enter, leave = area_distances(junctions, own, links, ego_pos, length)
    o_enter, o_leave = area_distances(junctions, links, own, car_pos, o_len)
    return intersection_safety(ego_v, enter, leave, length, ego_params, car_v, o_enter, o_leave, o_len,
                               params.take(cars), priority)
