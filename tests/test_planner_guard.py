"""The RSS proper-response guard on the executed ego command (rss.md §5 restrictions)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.guard import ProperResponseGuard, avoiding_decel
from sumo_rss.planner.lanes import lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.compliance import in_line
from sumo_rss.rss.owed_responses import OwedResponses
from sumo_rss.sim.snapshot import WorldSnapshot
from sumo_rss.trajectory import TrajectoryState

DT = 0.1


@pytest.fixture(scope="module")
def frame():
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    return RoadFrame.build(lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1"])))


def _ego_alone(speed: float) -> WorldSnapshot:
    one = np.zeros(1)
    return WorldSnapshot(time=20.0, ids=np.array(["ego"]), x=np.array([300.0]), y=np.array([-5.25]), heading=one,
                         speed=np.array([speed]), accel=one, lat_speed=one, length=np.array([4.5]),
                         width=np.array([1.8]), lane_id=np.array(["hw0_1"]), edge_id=np.array(["hw0"]),
                         lane_index=np.ones(1, int), lane_pos=np.array([300.0]), lat_pos=one,
                         vclass=np.array(["ego"]), vtype=np.array(["car"]), signals=np.zeros(1, int),
                         route_index=np.zeros(1, int))


def _owing_brake(t_b: float) -> OwedResponses:
    no = np.zeros(1, dtype=bool)
    return OwedResponses(np.array([t_b]), np.ones(1, dtype=bool), no, no, no, no, np.zeros(1), np.array(["x"], object),
                         np.ones(1, dtype=bool), no)


def test_after_the_response_time_the_owed_braking_is_enforced_and_a_stopped_ego_stays_stopped(frame):
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)  # ad_rss: ρ = 1 s, b_min = 4 m/s²
    owed = _owing_brake(t_b=15.0)  # 5 s ago: braking is owed now
    moving = guard.apply(_ego_alone(5.0), 0, frame, TrajectoryState(300.6, -5.25, 0.0, 5.5, 5.0), owed)
    assert moving.accel <= -4.0 and moving.speed == pytest.approx(5.0 - 4.1 * DT)
    stopped = guard.apply(_ego_alone(0.0), 0, frame, TrajectoryState(300.01, -5.25, 0.0, 0.3, 3.0), owed)
    assert stopped.speed == 0.0  # moving off would owe b_min braking again at once
    free = guard.apply(_ego_alone(0.0), 0, frame, TrajectoryState(300.01, -5.25, 0.0, 0.3, 3.0),
                       OwedResponses(*(np.zeros(0, dtype=a.dtype) for a in vars(owed).values())))
    assert free.speed == pytest.approx(0.3)  # nothing owed: it may go
    assert guard.counts.lon_owed == 2


def test_braking_owed_without_a_response_time_is_enforced_at_once(frame):
    """A car that moved off from standing into a junction danger owes its braking from t_b (rss/moving_off.py): 0.1 s
    after t_b, within what would be its ρ (1 s), the plan's 5 m/s² becomes the owed −4 m/s² (−4.1 with the guard's
    margin); with the response time it may still accelerate up to a_acc 3.5 (3.4)."""
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    planned = TrajectoryState(300.6, -5.25, 0.0, 3.5, 5.0)
    for at_once, accel in ((True, -4.1), (False, 3.4)):
        owed = replace(_owing_brake(t_b=20.0), no_response_time=np.array([at_once]))
        done = guard.apply(_ego_alone(3.0), 0, frame, planned, owed)
        assert done.speed == pytest.approx(3.0 + accel * DT)


def _owing_lateral(t_b: float, u0: float, other_is_left: bool, settled: bool = False) -> OwedResponses:
    no = np.zeros(1, dtype=bool)
    return OwedResponses(np.array([t_b]), no, no, no, np.ones(1, dtype=bool), np.array([other_is_left]),
                         np.array([u0]), np.array(["x"], object), np.ones(1, dtype=bool), np.array([settled]))


@pytest.mark.parametrize("t_b, other_is_left, lateral_speed", [
    (19.6, True, 0.55),  # τ = 0.5 s ≤ ρ: u0 + (a_lat − 0.1)·τ = 0.5 + 0.1·0.5
    (18.1, True, 0.0),  # τ = 2 s: 0.5 + 0.1·1 − 0.9·1 < 0, so no speed towards the other at all
    (18.1, False, 1.0),  # the other car is on the right: moving left is moving away, as planned
])
def test_an_owed_lateral_response_bounds_the_speed_towards_the_other_car(frame, t_b, other_is_left, lateral_speed):
    """ad_rss: a_lat 0.2, b_lat 0.8 m/s², ρ 1 s; the guard keeps 0.1 m/s² inside both. Trigger at t_b with the
    ego moving towards the other car at u0 = 0.5 m/s; the plan moves it left at 1 m/s."""
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    planned = TrajectoryState(300.0 + 2.0 * DT, -5.25 + 1.0 * DT, 0.0, 2.0, 0.0)
    done = guard.apply(_ego_alone(2.0), 0, frame, planned, _owing_lateral(t_b, 0.5, other_is_left))
    assert (done.y + 5.25) / DT == pytest.approx(lateral_speed, abs=1e-6)
    assert guard.counts.lat_owed == int(lateral_speed < 1.0)


def test_a_lateral_response_that_has_come_to_rest_keeps_the_ego_from_moving_towards_the_other_car(frame):
    """τ = 1.05 s: the envelope would still allow 0.5 + 0.1·1 − 0.9·0.05 = 0.555 m/s towards the car on the left,
    but the ego's speed towards it has been ≤ 0 since ρ (the auditor's 'and stay ≤ 0'): the plan's 1 m/s to the left
    becomes 0."""
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    planned = TrajectoryState(300.0 + 2.0 * DT, -5.25 + 1.0 * DT, 0.0, 2.0, 0.0)
    done = guard.apply(_ego_alone(2.0), 0, frame, planned, _owing_lateral(18.95, 0.5, True, settled=True))
    assert (done.y + 5.25) / DT == pytest.approx(0.0, abs=1e-6)
    assert guard.counts.lat_owed == 1


@pytest.mark.parametrize("side, towards_ego, blocked", [
    (-1.0, 0.3, False), (1.0, 0.3, False),  # lateral gap after the step 1.37 m > d_min 1.156 m
    (-1.0, 0.6, True), (1.0, 0.6, True),  # 1.07 m < 1.156 m
])
def test_a_move_towards_a_car_beside_is_judged_with_each_cars_own_lateral_parameters(frame, side, towards_ego,
                                                                                   blocked):
    """mobileye_human: ρ 1 s for the ego, 2 s for the other car (a_lat 0.2, b_lat 0.8 m/s², μ 0.1 m). A car
    right beside the ego (so longitudinally unsafe), 3.5 m − ``towards_ego`` to its ``side`` (−1 right, +1 left);
    the plan moves the ego towards it at 0.3 m/s. d_min = the ego's reach (0.3 + 0.5)/2·1 + 0.5²/1.6 = 0.55625 +
    the other's 0.2·2 + 0.4²/1.6 = 0.5 + μ 0.1 = 1.15625 m, on either side (with the two cars' parameters swapped
    it read 1.531 m and blocked the 0.3 m case on the right)."""
    z = np.zeros(2)
    lane = 1 + int(side)
    snapshot = WorldSnapshot(
        time=20.0, ids=np.array(["ego", "car"]), x=np.array([300.0, 300.0]),
        y=np.array([-5.25, -5.25 + side * (3.5 - towards_ego)]), heading=z, speed=np.array([20.0, 20.0]), accel=z,
        lat_speed=z, length=np.array([4.5, 4.5]), width=np.array([1.8, 1.8]), lane_id=np.array(["hw0_1", f"hw0_{lane}"]),
        edge_id=np.array(["hw0", "hw0"]), lane_index=np.array([1, lane]), lane_pos=np.array([300.0, 300.0]),
        lat_pos=np.array([0.0, -side * towards_ego]), vclass=np.array(["ego", "background"]),
        vtype=np.array(["car", "car"]), signals=np.zeros(2, int), route_index=np.zeros(2, int))
    guard = ProperResponseGuard(ParamResolver("mobileye_human"), DT)
    planned = TrajectoryState(300.0 + 20.0 * DT, -5.25 + side * 0.3 * DT, 0.0, 20.0, 0.0)
    nothing_owed = OwedResponses(*(np.zeros(0, dtype=t) for t in (float, bool, bool, bool, bool, bool, float, object,
                                                                   bool, bool)))
    done = guard.apply(snapshot, 0, frame, planned, nothing_owed)
    assert (done.y + 5.25) / DT == pytest.approx(0.0 if blocked else side * 0.3, abs=1e-6)
    assert guard.counts.lat_predictive == int(blocked)


@pytest.mark.parametrize("gap, v_lead, b_lead, expected", [
    (50.0, 0.0, 0.0, 25.0 ** 2 / 100.0),  # a car standing 50 m ahead: stop within the gap
    (10.0, 20.0, 0.0, 5.0 ** 2 / 20.0),  # 5 m/s faster, the leader going on: match its speed within the gap
    (30.1, 25.0, 8.0, 25.0 ** 2 / (2.0 * (30.1 + 25.0 ** 2 / 16.0))),  # equal speeds, the leader stops first
    (20.0, 30.0, 0.0, 0.0),  # a faster leader: nothing
    (5.0, 15.0, 2.0, 2.0 + 10.0 ** 2 / 10.0),  # the speeds meet while both move: (a - b)·gap·2 = Δv²
])
def test_the_deceleration_that_avoids_a_car_ahead_by_hand(gap, v_lead, b_lead, expected):
    assert avoiding_decel(np.array([gap]), 25.0, np.array([v_lead]), np.array([b_lead]))[0] == \
        pytest.approx(expected, rel=1e-6)


def _least_gap_braking(gap: float, v: float, v_lead: float, b_lead: float, a: float) -> float:
    """[m] The least gap over time, both cars braking to a stand (the follower at ``a``), from the motion
    equations sampled finely up to when the follower stands (the gap grows after that)."""
    t = np.linspace(0.0, v / a, 200001)
    own = v * t - 0.5 * a * t * t
    lead_t = np.minimum(t, v_lead / b_lead) if b_lead > 0.0 else t  # the leader stands from v_lead / b_lead on
    lead = v_lead * lead_t - 0.5 * b_lead * lead_t * lead_t
    return float(np.min(gap + lead - own))


def test_the_deceleration_that_avoids_a_car_ahead_is_the_least_that_does():
    """Random cases against the motion itself: braking at the answer the gap stays open (to the sampling's
    precision), braking 1 % less it closes; an answer of 0 means coasting never reaches the car."""
    rng = np.random.default_rng(7)
    cases = np.column_stack([rng.uniform(0.0, 80.0, 60), rng.uniform(0.5, 35.0, 60),
                             rng.uniform(0.0, 35.0, 60) * rng.integers(0, 2, 60),
                             rng.uniform(0.0, 9.0, 60) * rng.integers(0, 2, 60)])
    checked = 0
    for gap, v, v_lead, b_lead in cases:
        a = float(avoiding_decel(np.array([gap]), v, np.array([v_lead]), np.array([b_lead]))[0])
        if a == 0.0:
            assert v <= v_lead and b_lead == 0.0 or _least_gap_braking(gap, v, v_lead, b_lead, 1e-3) >= -1e-6
            continue
        assert _least_gap_braking(gap, v, v_lead, b_lead, a) >= -1e-3 * v
        assert _least_gap_braking(gap, v, v_lead, b_lead, 0.99 * a) < 0.0
        checked += 1
    assert checked > 20


def test_emergency_braking_up_to_b_max_where_b_min_would_hit_the_car_ahead(frame):
    """A car that cut in 30 m ahead of the ego and brakes at 8 m/s² from 25 m/s: the ego owes it no braking
    (rss.md §5: the lateral response), but braking at b_min would hit it; it brakes as hard as avoiding it needs
    (4.59 m/s² to stop 1 m behind it), up to b_max. The planner had ramped its braking up to its 5 m/s² limit and
    hit the car at 15 m/s."""
    ego = _ego_alone(25.0)
    lead_x = 300.0 + 30.0 + 4.5  # front bumpers: a 30 m gap
    both = WorldSnapshot(**{**vars(ego), **{k: np.concatenate([getattr(ego, k), np.array([v])]) for k, v in {
        "ids": "cut", "x": lead_x, "y": -5.25, "heading": 0.0, "speed": 25.0, "accel": -8.0, "lat_speed": 0.0,
        "length": 4.5, "width": 1.8, "lane_id": "hw0_1", "edge_id": "hw0", "lane_index": 1, "lane_pos": lead_x,
        "lat_pos": 0.0, "vclass": "background", "vtype": "car", "signals": 0, "route_index": 0}.items()}})
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    nothing = OwedResponses(*(np.zeros(0, dtype=a.dtype) for a in vars(_owing_brake(0.0)).values()))
    braking = guard.apply(both, 0, frame, TrajectoryState(302.5, -5.25, 0.0, 25.0, 0.0), nothing)
    needed = float(avoiding_decel(np.array([30.0 - 1.0]), 25.0, np.array([25.0]), np.array([8.0]))[0])
    assert needed == pytest.approx(25.0 ** 2 / (2.0 * (29.0 + 25.0 ** 2 / 16.0))) and braking.accel == pytest.approx(-(needed + 0.1))
    assert guard.counts.emergency == 1
    # A leader braking at 2 m/s²: b_min is enough, the plan stands.
    mild = WorldSnapshot(**{**vars(both), "accel": np.array([0.0, -2.0])})
    assert guard.apply(mild, 0, frame, TrajectoryState(302.5, -5.25, 0.0, 25.0, 0.0), nothing).accel == 0.0


def _with_car(ego: WorldSnapshot, **car) -> WorldSnapshot:
    """``ego`` and one more car (given fields; the rest as a car in lane hw0_1 driving along +x)."""
    row = {"ids": "car", "x": 350.0, "y": -5.25, "heading": 0.0, "speed": 20.0, "accel": 0.0, "lat_speed": 0.0,
           "length": 4.5, "width": 1.8, "lane_id": "hw0_1", "edge_id": "hw0", "lane_index": 1, "lane_pos": 350.0,
           "lat_pos": 0.0, "vclass": "background", "vtype": "car", "signals": 0, "route_index": 0, **car}
    return WorldSnapshot(**{**vars(ego), **{k: np.concatenate([getattr(ego, k), np.array([v])])
                                            for k, v in row.items()}})


def _nothing_owed() -> OwedResponses:
    return OwedResponses(*(np.zeros(0, dtype=a.dtype) for a in vars(_owing_brake(0.0)).values()))


def test_braking_owed_as_the_rear_car_and_limited_as_the_front_car_meets_both_duties(frame):
    """krauss: b_min = b_max = 4.5 m/s² (the vType's decel). Owing braking to one car and no harder than b_max to
    another, the guard kept 0.1 inside b_max (−4.4 m/s²) and so broke the braking duty by 0.1, twice the auditor's
    tolerance; −4.5 meets both. With ad_rss (4 and 8 m/s²) both margins fit: −4.1."""
    owed = OwedResponses(np.array([15.0, 15.0]), np.array([True, False]), np.zeros(2, bool), np.array([False, True]),
                         np.zeros(2, bool), np.zeros(2, bool), np.zeros(2), np.array(["a", "b"], object),
                         np.ones(2, bool), np.zeros(2, bool))
    planned = TrajectoryState(300.0 + 2.0 * DT, -5.25, 0.0, 20.0, 0.0)
    for preset, accel in (("krauss", -4.5), ("ad_rss", -4.1)):
        guard = ProperResponseGuard(ParamResolver(preset), DT)
        assert guard.apply(_ego_alone(20.0), 0, frame, planned, owed).accel == pytest.approx(accel)
        assert guard.counts.lon_owed == 1


def test_a_plan_braking_exactly_as_owed_is_not_counted_as_an_intervention(frame):
    """The guard keeps 0.1 m/s² inside b_min; a plan braking at b_min itself (the planner's backup) complies with
    the auditor (tolerance 0.05) and was counted as corrected at every step."""
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    done = guard.apply(_ego_alone(20.0), 0, frame, TrajectoryState(301.98, -5.25, 0.0, 19.6, -4.0), _owing_brake(15.0))
    assert done.accel == pytest.approx(-4.1) and guard.counts.lon_owed == 0


def test_the_speed_cap_behind_a_car_is_safe_at_the_next_step_not_only_now(frame):
    """ad_rss, a car 60 m ahead at 15 m/s, the ego at 17 m/s planning to speed up. The cap was the RSS-safe speed
    for the gap at t; the gap shrinks over the step, so at t + dt the ego stood just inside the RSS distance and
    owed braking (49 of 63 such episodes of an MPDM run began right after a capped step)."""
    from sumo_rss.rss import formulas

    ego = _ego_alone(17.0)
    both = _with_car(ego, x=300.0 + 60.0 + 4.5, speed=15.0)
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    done = guard.apply(both, 0, frame, TrajectoryState(301.8, -5.25, 0.0, 18.0, 10.0), _nothing_owed())
    p = ParamResolver("ad_rss").arrays(both)
    gap_next = 60.0 - (0.5 * (17.0 + done.speed) - 15.0) * DT
    d_min = formulas.lon_safe_distance_same_dir(np.array([done.speed]), np.array([15.0]), p.take(np.array([0])),
                                                p.take(np.array([1])))
    assert guard.counts.lon_predictive == 1 and 17.0 < done.speed < 18.0
    assert gap_next == pytest.approx(float(d_min[0]), abs=2e-3)  # on the RSS distance at t + dt, not inside it
    assert formulas.is_safe_distance(np.array([gap_next + 1.1e-3]), d_min)[0]


@pytest.mark.parametrize("other_lateral_speed, blocked", [(-1.0, False), (0.0, True)])
def test_a_move_towards_a_car_that_moves_away_faster_is_not_blocked(frame, other_lateral_speed, blocked):
    """ad_rss, a car right beside the ego on its left (longitudinally unsafe), 1.0 m between their sides; the plan
    moves the ego towards it at 0.5 m/s. The guard took the other car's lateral speed as 0 for the next step, so a
    car moving away at 1 m/s (``other_lateral_speed`` −1, towards the ego +) looked still: the move was set to 0.
    With its speed kept, d_min next = ego 0.906 + other −0.9 + μ 0.1 = 0.106 m against a gap of 1.05 m: safe.
    Towards a car that keeps its lateral position: d_min 1.131 m against 0.95 m, blocked."""
    # The car's centre 1.0 + 1.8 m to the left of the ego's; its lateral speed + = left, i.e. away from the ego.
    both = _with_car(_ego_alone(20.0), x=300.0, y=-5.25 + 2.8, lane_id="hw0_2", lane_index=2, lat_pos=-0.7,
                     lat_speed=-other_lateral_speed)
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    done = guard.apply(both, 0, frame, TrajectoryState(302.0, -5.25 + 0.5 * DT, 0.0, 20.0, 0.0), _nothing_owed())
    assert (done.y + 5.25) / DT == pytest.approx(0.0 if blocked else 0.5, abs=1e-6)
    assert guard.counts.lat_predictive == int(blocked)


@pytest.mark.parametrize("other_lateral_speed, plan_speed, guarded_speed", [
    (-1.0, -0.4, 0.0),  # it turns off to the right as the ego moves right: towards it at t + dt, so held
    (0.0, -0.4, -0.4),  # it keeps in its place: still in line at t + dt (the ego may leave to either side)
    (-1.0, 0.4, 0.4),  # the ego leaves to the left, away from it
])
def test_an_owed_lateral_response_is_judged_with_the_cars_as_they_will_be_at_the_next_step(
        frame, other_lateral_speed, plan_speed, guarded_speed):
    """highway_exit seed 7 (epsilon), 46.5 s: the ego and a car that cut in on it 32.6 m behind were in line (centres
    ≈ 11 mm apart, μ/2 = 50 mm), so the guard was owed nothing; the car turned right at 1.17 m/s and the ego's move
    right at 0.43 m/s was towards it at 46.6 s (centres ≈ 68 mm apart): responsible. Here, ad_rss (μ 0.1 m): the car
    30 m behind, its centre 20 mm right of the ego's; the lateral response is owed and settled (bound 0), in line
    now. Moving right at 0.4 m/s the ego's centre is at −40 mm at t + dt; the car turning right at 1 m/s is then
    at −20 − 100 = −120 mm, 80 mm to the right of the ego (apart: the auditor judges the 0.4 m/s towards it),
    standing still at −20 mm, 20 mm to the left (in line: not judged). Moving left the car is to the right either way."""
    both = _with_car(_ego_alone(20.0), x=270.0, y=-5.25 - 0.02, lane_pos=270.0, lat_pos=-0.02,
                     speed=20.0, lat_speed=other_lateral_speed)
    no = np.zeros(1, dtype=bool)
    in_line_now = OwedResponses(np.array([10.0]), no, no, no, no, no, np.zeros(1), np.array(["car"], object),
                                np.ones(1, dtype=bool), np.ones(1, dtype=bool), lat_duty=np.ones(1, dtype=bool))
    guard = ProperResponseGuard(ParamResolver("ad_rss"), DT)
    done = guard.apply(both, 0, frame, TrajectoryState(302.0, -5.25 + plan_speed * DT, 0.0, 20.0, 0.0), in_line_now)
    assert (done.y + 5.25) / DT == pytest.approx(guarded_speed, abs=1e-6)
    assert guard.counts.lat_owed == int(guarded_speed != plan_speed)
    # The auditor's verdict at t + dt on the guarded move: in line, or no speed towards the car's side.
    offset = (-0.02 + other_lateral_speed * DT) - (done.y + 5.25)
    towards = np.sign(offset) * (done.y + 5.25) / DT
    assert bool(in_line(abs(offset), 0.1, 0.1)) or towards <= 1e-9

