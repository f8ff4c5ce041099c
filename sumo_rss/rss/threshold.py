"""The episodes that open at a pair's danger threshold t_b (rss.md §5): what was safe at the step before
(:class:`StepBefore`) decides the response each car owes (:func:`.duties.duties_at_threshold`), and
:func:`new_episodes` makes their rows of the open episodes."""
from __future__ import annotations

import numpy as np

from .compliance import area_progress, instant_brake
from .duties import duties_at_threshold
from .intersection import KIND_SIGNAL
from .moving_off import StandingCars
from .open_episodes import N_CONSTRAINTS, OpenEpisodes
from .situations import FIRST_INTERSECTION_CODE
from .sorted_keys import find_sorted
from .step_input import AREA_KEY, AreaRules, StepInput


class StepBefore:
    """The RULE_* bits, priority and whether the signals decided it, of every pair at the step before (sorted by
    pair key), and of every conflict area of the crossing pairs (:class:`.step_input.AreaRules`)."""

    def __init__(self) -> None:
        self.keys = np.zeros(0, dtype=np.int64)
        self.rules = np.zeros(0, dtype=np.int8)
        self.priority = np.zeros(0, dtype=np.int8)
        self.by_signal = np.zeros(0, dtype=bool)
        self.areas: AreaRules | None = None

    def remember(self, step: StepInput, keys: np.ndarray, order: np.ndarray) -> None:
        """Keep the step's situations (``keys``: their pair keys sorted, ``order``: their rows in that order)."""
        sit = step.situations
        self.keys = keys
        self.areas = step.areas
        self.rules = sit.safe_rules[order]
        self.priority = sit.priority[order] if sit.priority is not None else np.zeros(len(keys), dtype=np.int8)
        self.by_signal = sit.kind[order] == KIND_SIGNAL

    def at(self, keys: np.ndarray, area_number: np.ndarray | None) -> tuple[np.ndarray, ...]:
        """(seen, rules, priority, by_signal) of the pairs ``keys`` at the step before; a crossing pair's (``area_number``
        of its conflict area now, -1 on roads; None: no junctions) in the area it is dangerous in now."""
        seen, pos = find_sorted(self.keys, keys)
        rules = self.rules[pos] if len(self.keys) else np.zeros(len(keys), dtype=np.int8)
        priority = self.priority[pos] if len(self.keys) else np.zeros(len(keys), dtype=np.int8)
        by_signal = self.by_signal[pos] if len(self.keys) else np.zeros(len(keys), dtype=bool)
        if self.areas is not None and len(self.areas.keys) and area_number is not None:
            area_keys = np.empty(len(keys), dtype=AREA_KEY)
            area_keys["pair"], area_keys["area"] = keys, area_number
            found, at = find_sorted(self.areas.keys, area_keys)
            found &= area_number >= 0
            seen = seen | found
            rules = np.where(found, self.areas.rules[at], rules)
            priority = np.where(found, self.areas.priority[at], priority)
            by_signal = np.where(found, self.areas.by_signal[at], by_signal)
        return seen, rules, priority, by_signal


def new_episodes(step: StepInput, keys: np.ndarray, rows: np.ndarray, before: StepBefore, standing: StandingCars,
                 dt: float, serials: np.ndarray) -> OpenEpisodes:
    """The open episodes of the pairs ``keys`` (situation ``rows`` of ``step``) that became dangerous now, with
    their ``serials``; ``standing``: the cars that stood at the step before, ``dt`` [s] ago (0 at the first)."""
    sit = step.situations
    a, b = sit.a[rows], sit.b[rows]
    # What was safe just before t_b decides the owed response (rss.md §5).
    seen, prev_rules, prev_priority, prev_by_signal = before.at(
        keys, step.area_number[rows] if step.area_number is not None else None)
    appeared = ~seen & (step.new_vehicle[a] | step.new_vehicle[b])
    duties = duties_at_threshold(sit, rows, prev_rules, prev_priority, seen, appeared, prev_by_signal)
    # Lateral speed towards the other car at t_b: the left car's is −v_lat, the right car's +v_lat.
    u0 = np.column_stack([np.where(sit.a_is_left[rows], -sit.v_lat_a[rows], sit.v_lat_a[rows]),
                          np.where(sit.a_is_left[rows], sit.v_lat_b[rows], -sit.v_lat_b[rows])])
    n = len(keys)
    # A car that owes braking at a junction and moved off from standing short of the area owes it at once.
    enter = np.column_stack([sit.enter_a[rows], sit.enter_b[rows]]) if sit.enter_a is not None \
        else np.full((n, 2), np.nan)
    moved_off = duties.must_brake & (sit.kind[rows] >= FIRST_INTERSECTION_CODE)[:, None] & \
        standing.moved_off(np.column_stack([step.uids[a], step.uids[b]]),
                           np.column_stack([step.vclass[a], step.vclass[b]]), enter,
                           np.column_stack([sit.v_lon_a[rows], sit.v_lon_b[rows]]), dt)
    return OpenEpisodes(
        keys=keys.astype(np.int64), serial=serials, a_id=step.ids[a].astype(object),
        b_id=step.ids[b].astype(object),
        uids=np.column_stack([step.uids[a], step.uids[b]]),
        a_class=step.vclass[a].astype(object), b_class=step.vclass[b].astype(object),
        kind=sit.kind[rows], t_b=np.full(n, step.time), t_last=np.full(n, step.time),
        window=np.maximum(step.params.response_time[a], step.params.response_time[b]),
        must_brake=duties.must_brake, moved_off=moved_off, front_limited=duties.front_limited,
        brake_correct=duties.brake_correct,
        owed_lat=duties.owed_lat, trigger=duties.trigger, roles=duties.roles, owed=duties.owed,
        area=sit.area[rows].astype(object) if sit.area is not None else np.full(n, "", dtype=object),
        a_left=sit.a_is_left[rows], in_line=np.zeros(n, dtype=bool), u0=u0,
        lat_settled=np.zeros((n, 2), dtype=bool),
        min_lon_margin=sit.lon_gap[rows] - sit.lon_d_min[rows],
        min_lat_margin=sit.lat_gap[rows] - sit.lat_d_min[rows],
        responsible=np.zeros((n, 2), dtype=bool), **area_progress(
            sit, rows, np.column_stack([sit.v_lon_a[rows], sit.v_lon_b[rows]]),
            np.column_stack([step.accel[a], step.accel[b]]), instant_brake(step, np.column_stack([a, b]))),
        active=np.zeros((n, 2, N_CONSTRAINTS), dtype=bool),
        v_start=np.zeros((n, 2, N_CONSTRAINTS)), v_last=np.zeros((n, 2, N_CONSTRAINTS)),
        v_worst=np.zeros((n, 2, N_CONSTRAINTS)), v_bound=np.zeros((n, 2, N_CONSTRAINTS)),
        v_excess=np.full((n, 2, N_CONSTRAINTS), -np.inf))
