"""DCP-tree of the EUDM behaviour planner (epsilon.md §2.3)."""
from __future__ import annotations

import pytest

from sumo_rss.planner.behavior.dcp_tree import Action, Lat, Lon, build_tree, ongoing_action, valid_policies


def test_27_policies_with_an_ongoing_keep():
    policies = valid_policies(Action(Lon.MAINTAIN, Lat.KEEP, 1.0))
    assert len(build_tree(Action(Lon.MAINTAIN, Lat.KEEP, 1.0))) == 27 and len(policies) == 27
    lateral = sorted({"".join(l.value for l in p.lats) for p in policies})
    assert lateral == sorted(["KKKKK", "KLLLL", "KRRRR", "KKLLL", "KKRRR", "KKKLL", "KKKRR", "KKKKL", "KKKKR"])
    assert {p.lon for p in policies} == set(Lon)


@pytest.mark.parametrize("ongoing", [Lat.LEFT, Lat.RIGHT])
def test_15_policies_during_a_lane_change(ongoing):
    tree = build_tree(Action(Lon.MAINTAIN, ongoing, 0.4))
    valid = [p for p in tree if p.is_valid]
    assert len(tree) == 27 and len(valid) == 15
    other = Lat.RIGHT if ongoing is Lat.LEFT else Lat.LEFT
    # Sequences that switch directly to the opposite lane change are pre-deleted; cancels remain.
    assert all(other not in p.lats for p in valid)
    names = {"".join(l.value for l in p.lats) for p in valid}
    assert ongoing.value + "KKKK" in names and any(p.is_cancel for p in valid)


def test_first_layer_keeps_decisions_on_the_one_second_grid():
    policies = valid_policies(Action(Lon.MAINTAIN, Lat.KEEP, 0.3))
    assert {p.durations for p in policies} == {(0.3, 1.0, 1.0, 1.0, 1.0)}
    assert policies[0].horizon == pytest.approx(4.3)


def test_ongoing_action_from_the_previous_plan():
    previous = valid_policies(Action(Lon.ACCELERATE, Lat.KEEP, 1.0))
    plan = next(p for p in previous if p.name == "A:KLLLL")
    # 1.3 s into the plan: the second layer (L) is active with 0.7 s left, if a lane change is under way.
    now = ongoing_action(plan, 1.3, lane_change_active=True)
    assert (now.lon, now.lat) == (Lon.ACCELERATE, Lat.LEFT) and now.duration == pytest.approx(0.7)
    # Without an active lane-change context the lateral action is forced to keep.
    assert ongoing_action(plan, 1.3).lat is Lat.KEEP
    # No previous plan: maintain/keep until the next whole second.
    first = ongoing_action(None, 12.35)
    assert (first.lon, first.lat) == (Lon.MAINTAIN, Lat.KEEP) and first.duration == pytest.approx(0.65)
