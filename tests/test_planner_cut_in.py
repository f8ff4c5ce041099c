"""A car that cut in ahead of the ego, which owes it no longitudinal braking (rss.md §5: the episode started
laterally, so the gap is that car's duty): the ego keeps the gap it was left instead of braking to restore the
RSS distance, is not charged the RSS cost for it, and the guard lets it keep up with that car but not close in.

Hand numbers (ad_rss: ρ 1 s, a_acc 3.5, b_min 4, b_max 8 m/s²): at 25 m/s behind a car at 25 m/s the RSS distance
is 25 + 1.75 + 28.5²/8 − 25²/16 = 89.21875 m; a car that cut in leaves the ego 30 m."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sumo_rss.planner.behavior.cost_weights import CostWeights
from sumo_rss.planner.behavior.evaluation import rss_penalty
from sumo_rss.planner.behavior.forward_sim import Rollouts, SimSettings, Vehicles, simulate
from sumo_rss.planner.guard import ProperResponseGuard
from sumo_rss.planner.lanes import CURRENT
from sumo_rss.rss import formulas
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.params import RssParamArrays, RssParams
from sumo_rss.rss.owed_responses import OwedResponses
from sumo_rss.sim.snapshot import WorldSnapshot
from sumo_rss.trajectory import TrajectoryState

GAP = 30.0  # [m] bumper gap the cut-in left
DT = 0.1


def _follow(frame, cut_in_gap, owed_brake_due=None):
    """The ego (column 0) and the car ahead, both 4.5 m long at 25 m/s; the car keeps 25 m/s; 5 s of keep-lane
    with the ego wanting 30 m/s."""
    n = 2
    z = np.zeros(n)
    vehicles = Vehicles(np.array([100.0, 100.0 + 4.5 + GAP]), z.copy(), z.copy(), np.full(n, 25.0), z.copy(),
                        z.copy(), np.full(n, 4.5), np.full(n, 1.8), np.full(n, CURRENT))
    rollouts = Rollouts(np.full((1, 5), CURRENT), np.array([30.0]), np.ones(1), np.zeros(1, dtype=bool), 4.2,
                        np.full((1, n), CURRENT), np.array([0.0, 25.0]))
    p = RssParams()
    return simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * n),
                    cut_in_gap=cut_in_gap, owed_brake_due=owed_brake_due)


def test_the_ego_keeps_the_gap_a_cut_in_left_instead_of_braking_for_the_rss_distance(highway):
    _, frame = highway
    assert formulas.lon_safe_distance_same_dir(25.0, 25.0, RssParams(), RssParams()) == pytest.approx(89.21875)
    braking = _follow(frame, None)
    kept = _follow(frame, np.array([np.inf, GAP]))
    gap = kept.s[0, :, 1] - kept.s[0, :, 0] - 4.5
    assert kept.valid[0] and gap.min() >= GAP - 0.5  # it does not close in
    assert kept.speed[0, :, 0].min() > 24.5  # nor drop back at once (24.83 m/s at the lowest)
    assert braking.speed[0, :, 0].min() < 22.0  # RSS following: it brakes to restore ~89 m (to 21.6 m/s)
    # The leader cost reads what the simulation followed: the held gap, not the RSS distance.
    assert np.all(kept.ego_lead_held_gap[0] == GAP) and np.all(np.isinf(braking.ego_lead_held_gap[0]))


def test_a_car_that_cut_in_is_not_charged_the_rss_cost(highway):
    _, frame = highway
    sim = _follow(frame, np.array([np.inf, GAP]))
    p = RssParams()
    args = (sim, frame, p, RssParamArrays.stack([p]), np.full(2, 4.5), np.full(2, 1.8), CostWeights())
    assert np.all(rss_penalty(*args) > 0.0)  # 30 m behind a car at 25 m/s: far faster than its RSS-safe speed
    assert np.all(rss_penalty(*args, np.array([True])) == 0.0)


def _owed(other: str, must_brake: bool, same_direction: bool = True) -> OwedResponses:
    no = np.zeros(1, dtype=bool)
    return OwedResponses(np.array([19.0]), np.array([must_brake]), no, no, np.array([not must_brake]), no,
                         np.zeros(1), np.array([other], dtype=object), np.array([same_direction]), no)


def test_the_cars_owed_no_longitudinal_braking_are_those_of_same_direction_episodes_that_started_laterally():
    assert _owed("a", must_brake=False).without_lon_duty() == {"a"}
    assert _owed("a", must_brake=True).without_lon_duty() == frozenset()
    # An oncoming car or one crossing at an intersection: no following, so no leave to keep up with it.
    assert _owed("a", must_brake=False, same_direction=False).without_lon_duty() == frozenset()


def _ego_behind(v_ego: float, v_other: float) -> WorldSnapshot:
    """The ego on hw0_1 at x = 300 m and a car 30 m ahead (bumper gap), both 4.5 m long."""
    two = np.zeros(2)
    x = np.array([300.0, 300.0 + 4.5 + GAP])
    return WorldSnapshot(time=20.0, ids=np.array(["ego", "other"]), x=x, y=np.full(2, -5.25), heading=two,
                         speed=np.array([v_ego, v_other]), accel=two, lat_speed=two, length=np.full(2, 4.5),
                         width=np.full(2, 1.8), lane_id=np.full(2, "hw0_1"), edge_id=np.full(2, "hw0"),
                         lane_index=np.ones(2, int), lane_pos=x, lat_pos=two, vclass=np.array(["ego", "background"]),
                         vtype=np.full(2, "car"), signals=np.zeros(2, int), route_index=np.zeros(2, int))


@pytest.mark.parametrize("v_ego, allowed", [(20.0, 1.0), (24.95, 0.5), (26.0, 0.0)])
def test_the_guard_lets_the_ego_keep_up_with_a_car_that_cut_in_but_not_close_in(highway, v_ego, allowed):
    """The car ahead drives at 25 m/s, 30 m ahead: RSS-unsafe for the ego at any of these speeds. Planned:
    +1 m/s². Owing it nothing longitudinally, the ego may speed up to the car's 25 m/s, not beyond; owing it
    the RSS distance, it may not speed up at all."""
    _, frame = highway
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    snapshot = _ego_behind(v_ego, 25.0)
    planned = TrajectoryState(300.0 + 4.5 + v_ego * DT, -5.25, 0.0, v_ego + 1.0 * DT, 1.0)
    cut_in = guard.apply(snapshot, 0, frame, planned, _owed("other", must_brake=False))
    assert (cut_in.speed - v_ego) / DT == pytest.approx(allowed, abs=1e-9)
    owing = guard.apply(snapshot, 0, frame, planned, _owed("other", must_brake=False, same_direction=False))
    assert owing.speed == pytest.approx(v_ego)


def test_the_guard_does_not_let_the_ego_speed_up_towards_an_oncoming_car(highway):
    _, frame = highway
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    snapshot = _ego_behind(20.0, 25.0)
    snapshot = replace(snapshot, heading=np.array([0.0, np.pi]))
    planned = TrajectoryState(300.0 + 4.5 + 20.0 * DT, -5.25, 0.0, 20.0 + 1.0 * DT, 1.0)
    oncoming = _owed("other", must_brake=False, same_direction=False)  # the auditor's opposite-direction episode
    assert guard.apply(snapshot, 0, frame, planned, oncoming).speed == pytest.approx(20.0)


def test_owed_braking_is_planned_from_the_end_of_the_response_time_until_the_pair_is_safe(highway):
    """The ego 30 m behind a car at 25 m/s (RSS distance 89.2 m) owes it braking from 0.5 s on (t_b 0.5 s ago,
    ρ = 1 s): the rollout brakes from then on as the guard would make it, instead of IDM's mild braking (21.6
    m/s at the lowest), and stops braking once the pair is safe again (at 2.4 s, 16.7 m/s; 15.2 m/s at the
    lowest as the jerk limit releases the brake), not down to a standstill."""
    _, frame = highway
    p = RssParams()
    mild, owed = _follow(frame, None), _follow(frame, None, np.array([np.inf, 0.5]))
    before = owed.t <= 0.5 + 1e-9
    np.testing.assert_array_equal(owed.speed[0, before, 0], mild.speed[0, before, 0])
    assert owed.speed[0, :, 0].min() < mild.speed[0, :, 0].min() - 3.0
    v_e, v_f = owed.speed[0, -1, 0], owed.speed[0, -1, 1]
    gap = owed.s[0, -1, 1] - owed.s[0, -1, 0] - 4.5
    assert gap >= formulas.lon_safe_distance_same_dir(v_e, v_f, p, p) - 1.0  # safe (to a step's braking) at the end
    assert owed.speed[0, :, 0].min() > 14.0  # braking ended with the danger
