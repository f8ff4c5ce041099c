"""The response owed at an intersection's danger threshold (rss.md §5), from what held at the step before."""
from __future__ import annotations

import numpy as np

from sumo_rss.rss.duties import duties_at_threshold
from sumo_rss.rss.situations import (FIRST_INTERSECTION_CODE, RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_NO_OVERLAP,
                                     PairSituations)


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
    duties = duties_at_threshold(sit, rows, np.array(rules, dtype=np.int8), np.ones(len(cases), dtype=bool),
                                 np.zeros(len(cases), dtype=bool))
    assert [tuple(map(bool, row)) for row in duties.must_brake] == list(braking)
    assert [tuple(row) for row in duties.roles] == list(roles)
    assert duties.trigger.tolist() == ["able-to-stop", "able-to-stop", "in-front", "in-front", "in-front",
                                       "no-time-overlap", "able-to-stop"]
