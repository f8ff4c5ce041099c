"""EUDM manager (epsilon.md §2.7): lane-change proposals, context timing and expiry."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.dcp_tree import Lat, Lon, Policy
from sumo_rss.planner.behavior.manager import Manager, ManagerSettings
from sumo_rss.planner.lanes import CURRENT, lane_chains, lanes_consistent_with
from sumo_rss.road.network import RoadNetwork

LEFT_NOW = Policy(Lon.MAINTAIN, (Lat.LEFT,) * 5, (1.0,) * 5)
LANE, START_LANES = 3, frozenset({3})


def _trigger(manager: Manager, mandatory: Lat | None, speed: float = 15.0) -> float:
    """Propose the same left change every 0.1 s until a context exists; returns the time it was created."""
    now = 10.0
    while manager.context is None:
        manager.propose(LEFT_NOW, now, speed, LANE, START_LANES, mandatory)
        now = round(now + 0.1, 1)
        assert now < 12.0, "no context after 2 s of consistent proposals"
    return now - 0.1


def test_a_context_needs_consistent_proposals_and_operates_on_the_grid_after_the_minimum_delay():
    manager = Manager(ManagerSettings(), layer_duration=1.0)
    created = _trigger(manager, None)
    assert created == pytest.approx(10.3)  # the 4th consistent cycle
    assert manager.context.operation_time == pytest.approx(13.0)  # >= 2 s later, on the 1 s grid
    assert manager.lane_changes_started == 1


@pytest.mark.parametrize("mandatory", [None, Lat.LEFT])
def test_only_a_discretionary_context_expires_while_the_ego_is_still_in_its_lane(mandatory):
    """A mandatory change (the lane ends) keeps its context while the ego waits for a gap: dropping it would shut
    lane changes out for >= 2 s (new proposals, then the operation delay), just when a gap may come."""
    settings = ManagerSettings()
    manager = Manager(settings, layer_duration=1.0)
    _trigger(manager, mandatory)
    operation = manager.context.operation_time
    manager.update_context(operation + settings.outdated_after + 0.1, LANE)
    assert (manager.context is not None) == (mandatory is not None)
    manager.update_context(operation + settings.outdated_after + 0.2, LANE + 1)  # it left its lanes: done
    assert manager.context is None
    assert manager.lane_changes_completed == (1 if mandatory is not None else 0)


def test_a_discretionary_change_respects_the_speed_window_and_a_mandatory_one_does_not():
    slow = Manager(ManagerSettings(), layer_duration=1.0)
    for k in range(10):
        slow.propose(LEFT_NOW, 10.0 + 0.1 * k, 1.0, LANE, START_LANES, None)
    assert slow.context is None
    forced = Manager(ManagerSettings(), layer_duration=1.0)
    _trigger(forced, Lat.LEFT, speed=0.0)
    assert forced.context.mandatory


@pytest.mark.parametrize("desired, speed, proposed", [(20.0, 24.0, True), (20.0, 25.0, False), (30.0, 30.0, True),
                                                     (30.0, 35.9, True), (30.0, 36.1, False)])
def test_the_speed_window_tops_out_at_1_2_times_the_desired_speed(desired, speed, proposed):
    """The release's 4-24 m/s window, with its 20 m/s demo ego, scaled: an ego wanting 30 m/s may start a
    discretionary change up to 36 m/s (with a fixed 24 m/s it could never overtake at highway speeds)."""
    manager = Manager(ManagerSettings(), layer_duration=1.0, desired_speed=desired)
    for k in range(10):
        manager.propose(LEFT_NOW, 10.0 + 0.1 * k, speed, LANE, START_LANES, None)
    assert (manager.context is not None) == proposed


@pytest.mark.parametrize("case", ["cool-down", "speed window"])
def test_only_eligible_cycles_count_towards_the_consistent_proposals(case):
    """epsilon.md §2.7 step 7: the 4 consistent cycles must each meet every condition (the release clears its
    queued proposals on "cold down" and "illegal speed"). Cycles 10.1-10.3 are ineligible (3 s after the last
    trigger, or at 3 m/s), 10.4 on are eligible: the context comes at the 4th eligible cycle, 10.7, not at 10.4."""
    manager = Manager(ManagerSettings(), layer_duration=1.0)
    if case == "cool-down":
        manager.last_trigger = 5.4
    created = None
    for k in range(1, 10):
        now = round(10.0 + 0.1 * k, 1)
        speed = 3.0 if case == "speed window" and now < 10.35 else 15.0
        manager.propose(LEFT_NOW, now, speed, LANE, START_LANES, None)
        if manager.context is not None:
            created = now
            break
    assert created == pytest.approx(10.7)


def test_a_context_completes_on_a_lane_change_not_on_driving_on_past_the_planning_chain():
    """merge net: the planning chain from mw_in_1 reaches only mw_merge_2 (250 m past mw_in_1). Driving straight
    on into :m2_0_1 and mw_out_1 is no lane change (epsilon.md §2.7: the lanes "consistent" with the start are
    found along its successors, up to 20); moving over to mw_merge_1 is."""
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    ids = list(net.lane_ids)
    chain = lane_chains(net, ids.index("mw_in_1"), net.edge_indices(["mw_in", "mw_merge", "mw_out"]))
    current = chain.lanes[chain.chain_of[CURRENT]]
    assert [ids[k] for k in current] == ["mw_in_1", ":m1_1_1", "mw_merge_2"]
    consistent = lanes_consistent_with(net, current)
    assert {ids[k] for k in consistent} == {"mw_in_1", ":m1_1_1", "mw_merge_2", ":m2_0_1", "mw_out_1"}
    manager = Manager(ManagerSettings(), layer_duration=1.0)
    _trigger(manager, None)
    manager.context = replace(manager.context, start_lanes=consistent)
    for lane in ("mw_merge_2", ":m2_0_1", "mw_out_1"):
        manager.update_context(14.0, ids.index(lane))
    assert manager.context is not None and manager.lane_changes_completed == 0
    manager.update_context(14.0, ids.index("mw_merge_1"))
    assert manager.context is None and manager.lane_changes_completed == 1


def test_before_its_operation_time_a_context_allows_only_its_own_direction():
    """MPDM's policies change lanes from their first layer: with a left context not yet due, its right-change
    policy was allowed too (any policy not keeping in its first layer), and the ego changed right."""
    manager = Manager(ManagerSettings(), layer_duration=1.0)
    _trigger(manager, None)
    right_now = Policy(Lon.MAINTAIN, (Lat.RIGHT,) * 5, (1.0,) * 5)
    keep = Policy(Lon.MAINTAIN, (Lat.KEEP,) * 5, (1.0,) * 5)
    policies = [keep, LEFT_NOW, right_now]
    early = manager.context.operation_time - 0.5
    assert manager.select(policies, np.array([1.0, 0.8, 0.5]), np.ones(3, bool), early) == 1  # not the right one
    assert manager.select([keep, right_now], np.array([1.0, 0.5]), np.ones(2, bool), early) == 0
