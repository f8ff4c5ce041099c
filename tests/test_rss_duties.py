"""The response owed at the danger threshold (rss.md §5), from what held at the step before: at intersections,
and on roads for pairs first seen dangerous."""
from __future__ import annotations

import numpy as np

from sumo_rss.rss.duties import duties_at_threshold
from sumo_rss.rss.situations import (FIRST_INTERSECTION_CODE, RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_LON,
                                     RULE_NO_OVERLAP, PairSituations)


def _dangerous_crossings(priority: list[int], in_front: list[int]) -> PairSituations:
    """Pairs of cars (rows 2k, 2k+1) at a conflict area, all dangerous now."""
    n = len(priority)
    zeros, false = np.zeros(n), np.zeros(n, dtype=bool)
    return PairSituations(
        a=np.arange(0, 2 * n, 2), b=np.arange(1, 2 * n, 2), kind=np.full(n, FIRST_INTERSECTION_CODE),
        a_is_rear=false, a_is_left=false, lon_gap=zeros, lat_gap=zeros, v_lon_a=zeros, v_lon_b=zeros,
        v_lat_a=zeros, v_lat_b=zeros, lon_d_min=zeros, lat_d_min=zeros, lon_safe=false, lat_safe=false,
        rules=np.zeros(n, dtype=np.int8), priority=np.array(priority, dtype=np.int8),
        in_front=np.array(in_front, dtype=np.int8))


def test_who_must_brake_at_an_intersection_follows_the_condition_that_held_before():
    # (rule before t_b, priority, car in front at t_b) → (a brakes, b brakes), as ad_rss's proper response
    cases = [
        (RULE_ABLE_TO_STOP, 2, 0, (True, False), ("yielding", "priority")),  # b has priority: a yields
        (RULE_ABLE_TO_STOP, 0, 0, (True, True), ("yielding", "yielding")),  # same priority: both yield
        (RULE_IN_FRONT, 1, 2, (True, False), ("rear", "front")),  # b in front: the rear car a brakes
        (RULE_IN_FRONT, 1, 1, (False, True), ("front", "rear")),
        (RULE_IN_FRONT, 1, 0, (True, True), ("crossing", "crossing")),  # overlap on the virtual line: no rear car
        (RULE_NO_OVERLAP, 1, 0, (True, True), ("crossing", "crossing")),
        (RULE_ABLE_TO_STOP | RULE_IN_FRONT, 1, 2, (False, True), ("priority", "yielding")),  # able-to-stop first
    ]
    rules, priority, ahead, braking, roles = zip(*cases)
    sit = _dangerous_crossings(list(priority), list(ahead))
    rows = np.arange(len(cases))
    duties = duties_at_threshold(sit, rows, np.array(rules, dtype=np.int8), np.array(priority, dtype=np.int8),
                                 np.ones(len(cases), dtype=bool), np.zeros(len(cases), dtype=bool))
    assert [tuple(map(bool, row)) for row in duties.must_brake] == list(braking)
    assert [tuple(row) for row in duties.roles] == list(roles)
    assert duties.trigger.tolist() == ["able-to-stop", "able-to-stop", "in-front", "in-front", "in-front",
                                       "no-time-overlap", "able-to-stop"]


def test_who_yields_follows_the_priority_under_which_able_to_stop_held():
    """A signal that changes at t_b (yellow onset: SUMO falls back to the junction's static right of way) does not
    make the car that was let through the one that yields: b had priority while a could stop; at t_b a has it and
    b, at the area, cannot stop. a (without priority before) brakes, b may drive on (rss.md §5)."""
    sit = _dangerous_crossings([1, 1], [0, 0])  # a has priority now in both pairs
    duties = duties_at_threshold(sit, np.arange(2), np.full(2, RULE_ABLE_TO_STOP, dtype=np.int8),
                                 np.array([2, 1], dtype=np.int8), np.ones(2, dtype=bool), np.zeros(2, dtype=bool))
    assert [tuple(map(bool, row)) for row in duties.must_brake] == [(True, False), (False, True)]
    assert [tuple(row) for row in duties.roles] == [("yielding", "priority"), ("priority", "yielding")]
    first_seen = duties_at_threshold(sit, np.arange(1), np.zeros(1, dtype=np.int8), np.array([2], dtype=np.int8),
                                     np.zeros(1, dtype=bool), np.ones(1, dtype=bool))
    assert first_seen.trigger.tolist() == ["appeared"]  # no step before: nothing to take a priority from


def test_a_road_pair_first_seen_dangerous_owes_by_its_overlap():
    """rss.md §5: a pair that appears already dangerous owes the longitudinal response unless the cars overlap
    longitudinally, then the lateral one; also when neither car is new but the two were no road situation at the
    step before (a ramp car reaching the motorway's edge beside a car: on unrelated edges until then). It was
    taken as longitudinally safe before, and the car a few metres behind, side by side, was blamed for not
    braking."""
    n = 3
    zeros, false = np.zeros(n), np.zeros(n, dtype=bool)
    sit = PairSituations(
        a=np.arange(0, 2 * n, 2), b=np.arange(1, 2 * n, 2), kind=np.zeros(n, dtype=int), a_is_rear=np.ones(n, bool),
        a_is_left=false, lon_gap=np.array([-2.5, 8.0, -2.5]), lat_gap=np.full(n, 0.1), v_lon_a=zeros,
        v_lon_b=zeros, v_lat_a=zeros, v_lat_b=zeros, lon_d_min=np.full(n, 65.0), lat_d_min=np.full(n, 0.35),
        lon_safe=false, lat_safe=false, rules=np.zeros(n, dtype=np.int8))
    seen, appeared = np.array([False, False, True]), np.zeros(n, dtype=bool)
    duties = duties_at_threshold(sit, np.arange(n), np.array([0, 0, RULE_LON], dtype=np.int8),
                                 np.zeros(n, dtype=np.int8), seen, appeared)
    assert duties.trigger.tolist() == ["first-seen", "first-seen", "lon"]
    assert [tuple(row) for row in duties.owed] == [("lat:brake", "lat:brake"),
                                                   ("lon:brake-min", "lon:brake-at-most-max"),
                                                   ("lon:brake-min", "lon:brake-at-most-max")]
    assert duties.owed_lat.tolist() == [True, False, False]
