"""Rule 5 — evasive effort (docs/rss.md "Rule 5"): hand-made scenes on the highway net's straight edge hw0 (lanes 0,
1, 2 at y = −8.75, −5.25, −1.75, 3.5 m wide, 33.33 m/s), cars 4.5 x 1.8 m, ad_rss parameters (ρ 1 s, a_acc 3.5,
b_min 4, b_max 8, a_lat 0.2, b_lat 0.8, μ 0.1), steps of 0.1 s, the numbers worked by hand in each docstring."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, CollisionInput, ParamResolver
from sumo_rss.rss.evasive import lateral_manoeuvre, naive
from sumo_rss.rss.params import EvasiveParams, evasive_params
from sumo_rss.sim.snapshot import WorldSnapshot

RULE5 = EvasiveParams(enabled=True)  # rule 5 is off by default (docs/rss.md)
LANE_Y = {0: -8.75, 1: -5.25, 2: -1.75}
LENGTH, WIDTH = 4.5, 1.8


@pytest.fixture(scope="module")
def net() -> RoadNetwork:
    return RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")


def _snapshot(t: float, cars: list[tuple]) -> WorldSnapshot:
    """Cars (id, lane index, front bumper x [m], speed [m/s], accel [m/s²], offset left of the lane's centre [m],
    lateral speed [m/s], vType) on hw0, bodies along the lane."""
    n = len(cars)
    col = list(zip(*cars))
    lane = np.array(col[1])
    offset = np.array(col[5], dtype=float)
    return WorldSnapshot(
        time=round(t, 6), ids=np.array(col[0]), x=np.array(col[2], dtype=float),
        y=np.array([LANE_Y[k] for k in lane]) + offset, heading=np.zeros(n), speed=np.array(col[3], dtype=float),
        accel=np.array(col[4], dtype=float), lat_speed=np.array(col[6], dtype=float), length=np.full(n, LENGTH),
        width=np.full(n, WIDTH), lane_id=np.array([f"hw0_{k}" for k in lane]), edge_id=np.array(["hw0"] * n),
        lane_index=lane, lane_pos=np.array(col[2], dtype=float), lat_pos=offset, vclass=np.array(["background"] * n),
        vtype=np.array(col[7]), signals=np.zeros(n, int), route_index=np.zeros(n, int),
        route_edges=(("hw0", "hw1", "hw2"),) * n)


def test_naive_prediction_keeps_the_acceleration_until_the_speed_reaches_zero():
    """Def. 11: v0 = 10 m/s, a0 = −4 m/s² stops after τ = 2.5 s at 12.5 m and stays; a0 = +1 keeps accelerating
    (3 s: 30 + 4.5 = 34.5 m); a lateral v0 = −0.5 m/s with a0 = +0.25 stops after 2 s at −0.5 m."""
    x, v = naive(0.0, np.array([10.0, 10.0, -0.5]), np.array([-4.0, 1.0, 0.25]), np.array([[1.0], [3.0]]))
    assert x.ravel().tolist() == pytest.approx([8.0, 10.5, -0.375, 12.5, 34.5, -0.5])
    assert v.ravel().tolist() == pytest.approx([6.0, 11.0, -0.25, 0.0, 13.0, 0.0])


def test_a_lateral_candidate_comes_to_rest_one_lane_over():
    """a = 1 m/s² from rest, half a lane 1.75 m: reached after √3.5 = 1.871 s at 1.871 m/s, then braked at 1 m/s²:
    at 3 s the car is 1.75 + 1.871·1.129 − 1.129²/2 = 3.225 m over at 0.742 m/s, and at rest 3.5 m over from
    3.742 s on."""
    y, u = lateral_manoeuvre(0.0, -1.0, 1.75, 1.0, np.array([1.0, 3.0, 5.0]))
    assert y.tolist() == pytest.approx([-0.5, -3.2249, -3.5], abs=1e-4)
    assert u.tolist() == pytest.approx([-1.0, -0.7417, 0.0], abs=1e-4)


def test_rule5_settings_are_checked():
    assert evasive_params("ad_rss") == EvasiveParams(3.0, 5.0, enabled=False)
    assert evasive_params("ad_rss", enabled=True).enabled
    assert evasive_params("krauss", horizon_s=2.0).horizon_s == 2.0
    with pytest.raises(ValueError, match="evasive_horizon_s must be in"):
        evasive_params("ad_rss", horizon_s=0.0)
    with pytest.raises(ValueError, match="evasive_lookback_s must be in"):
        evasive_params("ad_rss", lookback_s=0.0)


def _empty(t: float) -> WorldSnapshot:
    """A step without any vehicle (SUMO writes them before the first vehicle departs)."""
    none = np.zeros(0)
    return WorldSnapshot(
        time=t, ids=np.zeros(0, dtype=str), x=none, y=none, heading=none, speed=none, accel=none, lat_speed=none,
        length=none, width=none, lane_id=np.zeros(0, dtype=str), edge_id=np.zeros(0, dtype=str),
        lane_index=np.zeros(0, int), lane_pos=none, lat_pos=none, vclass=np.zeros(0, dtype=str),
        vtype=np.zeros(0, dtype=str), signals=np.zeros(0, int), route_index=np.zeros(0, int), route_edges=())


@pytest.mark.parametrize("empty_steps", [0, 1, 2])
def test_a_leader_hit_from_behind_could_not_have_evaded(net, empty_steps):
    """The leader stands in lane 1 (front bumper at 500 m); the follower comes at 20 m/s 30 m behind its back
    (d_min 20 + 1.75 + 23.5²/8 = 90.8 m: dangerous from the first step, the follower owes braking after ρ), keeps its
    speed to 1.2 s and brakes at 8 m/s² only from then on: it breaks its response from 1.1 s (a = 0 > −4) and runs
    into the leader at 1.6 s. At 1.1 s the gap is 8 m: in 3 s the follower on its naive prediction (20 m/s) covers
    60 m, the leader at most 1.75·3² = 15.75 m, and 0.2 m/s² moves it 0.9 m sideways, short of the 1.9 m it would
    need: no candidate avoids the contact, at 1.1 s nor later (rules 1-3: the follower; rule 5: none).
    ``empty_steps``: the data begins with that many steps of 0.1 s without any vehicle (a merge_onramp FCD's do:
    rule 5's lateral accelerations looked the cars up among those of the step before, an empty array: IndexError),
    and every time is that much later."""
    auditor = Auditor(net, ParamResolver("ad_rss"), signal_rule=False, evasive=RULE5)
    for k in range(empty_steps):
        auditor.observe(_empty(round(0.1 * k, 6)))
    x, v, t = 465.5, 20.0, 0.0
    while True:
        step_t = t + 0.1 * empty_steps
        a = -8.0 if t > 1.25 else 0.0
        step = _snapshot(step_t, [("follower", 1, x, v, a, 0.0, 0.0, "car"),
                                  ("leader", 1, 500.0, 0.0, 0.0, 0.0, 0.0, "car")])
        contact = x > 500.0 - LENGTH
        auditor.observe(step, [CollisionInput(step.time, "follower", "leader", "collision")] if contact else [])
        if contact:
            break
        v_next = max(v - 0.8, 0.0) if t + 0.1 > 1.25 else v
        x, v, t = x + 0.05 * (v + v_next), v_next, t + 0.1
    result = auditor.finish()
    (episode,) = result.episodes.itertuples()
    assert (episode.responsible, episode.collision, episode.t_end_s) == ("a", True,
                                                                         pytest.approx(1.6 + 0.1 * empty_steps))
    assert episode.evasive_checked and np.isnan(episode.evasive_last_s) and episode.rule5_responsible == ""
    assert "evasive-effort" not in set(result.violations.constraint)
    assert result.collisions.could_have_avoided.tolist() == [""]


def _cut_in(net, occupied: bool, rule5: EvasiveParams = RULE5):
    """The keeper drives at 20 m/s in the centre of lane 1 (its vType 'evader' has a_lat = 1 m/s²); the cutter, its
    front bumper 1.76 m behind the keeper's, drifts in from lane 2 at 0.3 m/s, 2.0 m away side to side at 0 s.
    Across, d_min = 0.556 (the cutter: 0.4 + 0.5²/1.6) + 1.125 (the keeper: 0.5 + 1²/1.6) + 0.1 = 1.781 m: the pair
    turns dangerous at 0.8 s (1.76 m; lateral response by both) and at 0.9 s the cutter jumps to 1.5 m/s sideways,
    beyond its envelope 0.3 + 0.2·0.1 (rules 1-3: the cutter). 1.61 m apart then, the two touch at 2.0 s.
    ``occupied``: lane 0 holds a car beside the keeper (front bumper 3.5 m ahead of the keeper's) and one behind it
    (15 m behind), both at 20 m/s in their lane's centre, 1.7 m from the keeper."""
    cars0 = [("lane0_ahead", 0, 503.5), ("lane0_behind", 0, 485.0)] if occupied else []
    auditor = Auditor(net, ParamResolver("ad_rss", vtype_overrides={"evader": {"lat_accel_max": 1.0}}),
                      signal_rule=False, evasive=rule5)
    offset, t = 0.3, 0.0
    for k in range(21):
        t = round(0.1 * k, 6)
        u = -0.3 if t <= 0.8 + 1e-9 else -1.5
        if k:
            offset += 0.1 * u
        cars = [("cutter", 2, 498.24 + 2.0 * t, 20.0, 0.0, offset, u, "car"),
                ("keeper", 1, 500.0 + 2.0 * t, 20.0, 0.0, 0.0, 0.0, "evader")]
        cars += [(vid, lane, x + 2.0 * t, 20.0, 0.0, 0.0, 0.0, "car") for vid, lane, x in cars0]
        contact = 1.7 + offset <= 0.0
        auditor.observe(_snapshot(t, cars), [CollisionInput(t, "cutter", "keeper", "collision")] if contact else [])
        if contact:
            break
    assert t == pytest.approx(2.0)
    result = auditor.finish()
    episodes = result.episodes.set_index(["vehicle_a", "vehicle_b"])
    return episodes.loc[("cutter", "keeper")], result


def test_a_car_cut_into_that_kept_its_speed_could_have_evaded_into_the_free_lane(net):
    """At 0.9 s, 1.61 m apart, the cutter on its naive prediction (1.5 m/s sideways, 20 m/s) touches a keeper that
    holds its lane when the gap falls below μ = 0.1 m, after 1.0 s; getting out of its way along the road takes
    longer: behind it, 4.5 + 1.76 m at 4 m/s² relative (b_max), 1.25 s; ahead of it, 4.5 − 1.76 m at 1.75 m/s²,
    1.25 s. Swerving right at 1 m/s² keeps the gap 1.61 − 1.5τ + 0.5τ² ≥ 0.485 m (at 1.5 s) and ≥ 0.33 m at 3 s; braked
    at 8 or 4 m/s² the keeper is 28.7 / 11.7 m behind the cutter then (d_min 0 / 1.28 m: not dangerous), at 0
    or 3.5 m/s² still beside it or 13 m ahead (d_min 32.6 m): the legal manoeuvres are −b_max and −b_min with
    −a_lat. The same holds at 1.0 and 1.1 s (1.46, 1.31 m apart: the swerve keeps ≥ 0.335, 0.185 m) and no longer
    at 1.2 s (1.16 m: the gap falls below 0.1 m at 1.14 s, before braking gets clear at 1.25 s). The keeper kept
    its speed and lane: it did not follow the −b_min/−a_lat swerve (4 m/s² short of it) and is rule-5 responsible."""
    episode, result = _cut_in(net, occupied=False)
    assert (episode.responsible, episode.collision) == ("a", True)
    assert episode.evasive_checked and episode.evasive_last_s == pytest.approx(1.1)
    assert episode.rule5_responsible == "keeper"
    (row,) = result.violations[result.violations.constraint == "evasive-effort"].itertuples()
    assert (row.vehicle_id, row.episode_key) == ("keeper", "cutter|keeper|1")
    assert (row.t_start_s, row.t_end_s) == (pytest.approx(0.9), pytest.approx(1.1))
    assert (row.bound, row.worst_actual, row.excess) == (-4.0, 0.0, pytest.approx(3.95))
    assert result.collisions.could_have_avoided.tolist() == ["keeper"]
    assert set(result.violations[result.violations.constraint != "evasive-effort"].vehicle_id) == {"cutter"}


def test_a_car_cut_into_could_not_have_evaded_into_an_occupied_lane(net):
    """As before, with lane 0 occupied: swerving right 1.6 m (to 0.1 m of the car beside) takes √3.2 = 1.79 s, and
    then the keeper is beside one of them whatever it does along the road: at 0 or +3.5 m/s² beside the one ahead
    (front bumper 0 / 5.6 m ahead of its own, which spans 3.5 m ahead to 1 m behind), braked at 8 m/s² 12.8 m
    back, beside the one behind (15 to 19.5 m back), at 4 m/s² 6.5 m back at 1.79 s and 12.5 m back at 2.5 s,
    beside the one behind again. Evading would have caused another collision: no rule-5 car. (The car behind in
    lane 0 follows the one ahead 14 m back at 20 m/s and breaks its braking response; the one ahead could not
    get safe from it in 3 s: 14 + 15.75 m < d_min 32.6 m.)"""
    episode, result = _cut_in(net, occupied=True)
    assert (episode.responsible, episode.collision) == ("a", True)
    assert episode.evasive_checked and np.isnan(episode.evasive_last_s) and episode.rule5_responsible == ""
    assert set(result.episodes.rule5_responsible) == {""}
    assert "evasive-effort" not in set(result.violations.constraint)
    assert result.collisions.could_have_avoided.tolist() == [""]


@pytest.mark.parametrize("lookback_s, last_s, first_s", [(1.05, 1.1, 1.0), (0.85, np.nan, np.nan)])
def test_a_collision_is_asked_over_the_steps_of_its_look_back_window(net, lookback_s, last_s, first_s):
    """The free-lane cut-in (contact at 2.0 s; legal swerves at 0.9, 1.0 and 1.1 s) asked over the last 1.05 s only
    (steps 0.95-2.0 s kept): the swerves of 1.0 and 1.1 s are found, the keeper followed neither and is rule-5
    responsible from 1.0 s. Over the last 0.85 s (steps from 1.15 s on): none is found (at 1.2 s no swerve is legal any
    more), no rule-5 car."""
    episode, result = _cut_in(net, occupied=False, rule5=EvasiveParams(lookback_s=lookback_s, enabled=True))
    assert episode.evasive_checked
    rows = result.violations[result.violations.constraint == "evasive-effort"]
    if np.isnan(last_s):
        assert np.isnan(episode.evasive_last_s) and episode.rule5_responsible == "" and rows.empty
        return
    assert episode.evasive_last_s == pytest.approx(last_s) and episode.rule5_responsible == "keeper"
    (row,) = rows.itertuples()
    assert (row.t_start_s, row.t_end_s, row.bound) == (pytest.approx(first_s), pytest.approx(last_s), -4.0)
