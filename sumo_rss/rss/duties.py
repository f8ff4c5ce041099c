"""The proper response each car owes from the danger threshold on (rss.md §5), decided from what was still
safe at the step before t_b.

Roads: lateral safe before → a lateral response by both; longitudinal safe before → a longitudinal one (the rear
car brakes at b_min, the front car must not brake harder than b_max; opposite directions: both brake at b_corr);
both safe → both responses; a pair that appears already dangerous (a car entered the data, or the two cars were
no road situation at the previous step: a ramp car reaching the motorway's edge beside a car) owes the
longitudinal response unless the cars overlap longitudinally, then the lateral one.
Intersections: able-to-stop held → the car(s) without priority under that step's priority brake (a signal that
changes at t_b does not turn the car that was allowed through into the one that yields; but where the signals gave
no priority then, as at an all-red step, and give it now, the signals now decide), a priority car may drive on; in-front held → the rear car brakes (both, if neither is in front at t_b); otherwise (no time overlap,
or dangerous when first seen) both brake.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .intersection import KIND_SIGNAL
from .situations import (FIRST_INTERSECTION_CODE, RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_LAT, RULE_LON,
                         SAME_DIRECTION_CODES, PairSituations)


@dataclass(frozen=True, eq=False)
class Duties:
    """Per new episode (rows) and car (columns a, b)."""

    must_brake: np.ndarray  # [n, 2] at most a_acc during ρ, then at least b_min (b_corr) until stopped
    front_limited: np.ndarray  # [n, 2] must not brake harder than b_max
    brake_correct: np.ndarray  # [n, 2] opposite directions, in its correct lane: the braking owed is b_corr
    owed_lat: np.ndarray  # [n] the lateral response (both cars)
    trigger: np.ndarray  # [n] what was lost at t_b
    roles: np.ndarray  # [n, 2] e.g. 'rear', 'front+left', 'yielding'
    owed: np.ndarray  # [n, 2] e.g. 'lon:brake-min+lat:brake'; '' when nothing is owed


def _join(*parts: np.ndarray) -> np.ndarray:
    """Element-wise '+'-join of string arrays, skipping empty parts."""
    out = np.full(parts[0].shape, "", dtype=object)
    for part in parts:
        out = np.where(part == "", out, np.where(out == "", part, out + "+" + part))
    return out


def duties_at_threshold(sit: PairSituations, rows: np.ndarray, prev_rules: np.ndarray, prev_priority: np.ndarray,
                        seen: np.ndarray, appeared: np.ndarray, prev_by_signal: np.ndarray | None = None) -> Duties:
    """Duties of the pairs ``rows`` of ``sit`` that became dangerous now; ``prev_rules``: RULE_* bits,
    ``prev_priority`` (as ``PairSituations.priority``) and ``prev_by_signal`` (the signals decided it; None: they
    did) at the step before (valid where ``seen``); ``appeared``: a car of the pair entered the data this step."""
    if prev_by_signal is None:
        prev_by_signal = np.ones(len(rows), dtype=bool)
    kind = sit.kind[rows]
    crossing = kind >= FIRST_INTERSECTION_CODE
    if not crossing.any():
        return _road_duties(sit, rows, prev_rules, seen, appeared)
    if crossing.all():
        return _intersection_duties(sit, rows, prev_rules, prev_priority, prev_by_signal, seen, appeared)
    road = _road_duties(sit, rows, prev_rules, seen, appeared)
    junction = _intersection_duties(sit, rows, prev_rules, prev_priority, prev_by_signal, seen, appeared)
    pick = crossing[:, None]
    return Duties(*(np.where(pick if getattr(road, f).ndim == 2 else crossing, getattr(junction, f), getattr(road, f))
                    for f in ("must_brake", "front_limited", "brake_correct", "owed_lat", "trigger", "roles",
                              "owed")))


def _road_duties(sit: PairSituations, rows: np.ndarray, prev_rules: np.ndarray, seen: np.ndarray,
                 appeared: np.ndarray) -> Duties:
    # A pair that was no road situation at the previous step (a car new in the data; cars far apart, on unrelated
    # edges, or in a crossing situation then) appears dangerous: what was safe before is unknown, so the overlap
    # decides (rss.md §5). Cars that were far apart do not overlap: the longitudinal response, as it was safe.
    prev_lon = (prev_rules & RULE_LON) > 0
    prev_lat = (prev_rules & RULE_LAT) > 0
    overlap = sit.lon_gap[rows] < 0.0
    owed_lon = np.where(seen, prev_lon, ~overlap)
    owed_lat = np.where(seen, prev_lat, overlap)
    same = np.isin(sit.kind[rows], SAME_DIRECTION_CODES)
    a_rear = sit.a_is_rear[rows]
    rear = np.column_stack([a_rear, ~a_rear])
    must_brake = owed_lon[:, None] & np.where(same[:, None], rear, True)
    front_limited = owed_lon[:, None] & same[:, None] & ~rear
    lon_role = np.where(same[:, None], np.where(rear, "rear", "front"), "oncoming")
    # Opposite directions: b_corr for a car in its correct lane, b_min for one in the oncoming lane (rss.md §5).
    wrong_way = np.column_stack([sit.wrong_way_a[rows], sit.wrong_way_b[rows]]) if sit.wrong_way_a is not None \
        else np.zeros((len(rows), 2), dtype=bool)
    brake_correct = (sit.kind[rows] == 1)[:, None] & ~wrong_way
    lon_owed = np.where(same[:, None], np.where(rear, "lon:brake-min", "lon:brake-at-most-max"),
                        np.where(brake_correct, "lon:brake-correct", "lon:brake-min"))
    a_left = sit.a_is_left[rows]
    lat_role = np.column_stack([np.where(a_left, "left", "right"), np.where(a_left, "right", "left")])
    roles = _join(np.where(owed_lon[:, None], lon_role, ""), np.where(owed_lat[:, None], lat_role, ""))
    owed = _join(np.where(owed_lon[:, None], lon_owed, ""), np.where(owed_lat[:, None], "lat:brake", ""))
    trigger = np.where(appeared, "appeared", np.where(~seen, "first-seen", np.where(
        owed_lon & owed_lat, "both", np.where(owed_lon, "lon", "lat"))))
    return Duties(must_brake, front_limited, brake_correct, owed_lat, trigger.astype(object), roles, owed)


def _intersection_duties(sit: PairSituations, rows: np.ndarray, prev_rules: np.ndarray, prev_priority: np.ndarray,
                         prev_by_signal: np.ndarray, seen: np.ndarray, appeared: np.ndarray) -> Duties:
    n = len(rows)
    rules = np.where(seen, prev_rules, 0)
    able = (rules & RULE_ABLE_TO_STOP) > 0
    in_front = ~able & ((rules & RULE_IN_FRONT) > 0)
    # Who yields is decided by the priority under which 'able to stop' held (the step before t_b), unless the
    # signals give it now and did not then: after an all-red step, where both lights were red and the junction's
    # static right of way stood in, the light that turned green decides (the car approaching its red yields).
    now = sit.priority[rows] if sit.priority is not None else np.zeros(n, dtype=np.int8)
    by_signal_now = sit.kind[rows] == KIND_SIGNAL
    priority = np.where(seen & (prev_by_signal | ~by_signal_now), prev_priority, now)
    yielding = np.column_stack([priority != 1, priority != 2])  # equal priority: both yield
    # Safe by 'in front' before t_b: the rear car brakes; if neither car is in front at t_b (they overlap on the
    # virtual line), there is no rear car and both do, as ad_rss's BrakeMin for both.
    ahead = sit.in_front[rows] if sit.in_front is not None else np.zeros(n, dtype=np.int8)
    ordered = in_front & (ahead > 0)
    rear = np.column_stack([ahead == 2, ahead == 1])
    must_brake = np.where(able[:, None], yielding, np.where(ordered[:, None], rear, True))
    roles = np.where(able[:, None], np.where(yielding, "yielding", "priority"),
                     np.where(ordered[:, None], np.where(rear, "rear", "front"), "crossing")).astype(object)
    owed = np.where(must_brake, "int:brake-min", "").astype(object)
    trigger = np.where(able, "able-to-stop", np.where(in_front, "in-front", np.where(
        (rules > 0), "no-time-overlap", np.where(appeared, "appeared", "first-seen"))))
    return Duties(must_brake, np.zeros((n, 2), dtype=bool), np.zeros((n, 2), dtype=bool), np.zeros(n, dtype=bool),
                  trigger.astype(object), roles, owed)
