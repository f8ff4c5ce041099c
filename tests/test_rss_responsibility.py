"""The responsibility tracker over hand-built steps of one pair (rss.md §5): which steps are judged, the bound of
the step in which ρ ends, the lateral response that has come to rest, and a collision that closes two episodes.
Accelerations are SUMO's: the mean over the step before the time stamp [m/s²]; steps of 0.1 s; ad_rss parameters
(ρ 1 s, a_acc 3.5, b_min 4, b_max 8, a_lat 0.2, b_lat 0.8 m/s²) unless stated."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.rss.auditor import INTERSECTION_KEY, collision_blame
from sumo_rss.rss.params import RssParamArrays, RssParams
from sumo_rss.rss.responsibility import ResponsibilityTracker
from sumo_rss.rss.step_input import StepInput
from sumo_rss.rss.situations import FIRST_INTERSECTION_CODE, RULE_ABLE_TO_STOP, RULE_LON, PairSituations

PAIR = np.int64(1)  # uids 0 ('a') and 1 ('b'): (0 << 32) | 1
DT = 0.1


def _pair(lon_safe: bool, lat_safe: bool, v_lat_a: float = 0.0, a_left: bool = False,
          lat_offset: float = 2.3) -> PairSituations:
    """Car a 10 m/s behind car b on a road (a on the right unless ``a_left``, centres ``lat_offset`` m apart
    across it); d_min and gaps only matter for the margins."""
    one = np.ones(1)
    return PairSituations(a=np.array([0]), b=np.array([1]), kind=np.zeros(1, dtype=int), a_is_rear=np.ones(1, bool),
                          a_is_left=np.array([a_left]), lon_gap=5.0 * one, lat_gap=0.5 * one, v_lon_a=10.0 * one,
                          v_lon_b=10.0 * one, v_lat_a=v_lat_a * one, v_lat_b=0.0 * one, lon_d_min=10.0 * one,
                          lat_d_min=one, lon_safe=np.array([lon_safe]), lat_safe=np.array([lat_safe]),
                          lat_offset=lat_offset * one)


def _step(tracker: ResponsibilityTracker, t: float, situations: PairSituations, accel=(0.0, 0.0),
          params: RssParams = RssParams(), keys=(PAIR,), speed=(10.0, 10.0), **extra) -> None:
    tracker.step(StepInput(time=t, keys=np.array(keys, dtype=np.int64), situations=situations,
                           ids=np.array(["a", "b"], dtype=object), uids=np.array([0, 1], dtype=np.int64),
                           vclass=np.array(["background"] * 2, dtype=object), accel=np.array(accel, dtype=float),
                           speed=np.array(speed, dtype=float), params=RssParamArrays.stack([params, params]),
                           new_vehicle=np.zeros(2, dtype=bool), **extra))


def _rear_car_run(accels: list[float], rho: float) -> ResponsibilityTracker:
    """Safe at 0 s, longitudinally dangerous from t_b = 0.1 s on; the rear car a's acceleration per step after."""
    tracker = ResponsibilityTracker()
    p = RssParams(response_time=rho)
    _step(tracker, 0.0, _pair(True, False), params=p)
    _step(tracker, DT, _pair(False, False), params=p)
    for k, accel in enumerate(accels, start=2):
        _step(tracker, round(k * DT, 10), _pair(False, False), accel=(accel, 0.0), params=p)
    tracker.finish()
    return tracker


def test_the_step_in_which_the_response_time_ends_is_bounded_by_the_time_weighted_mix():
    """ρ = 0.25 s: ρ ends half-way through the step 0.3-0.4 s. The exact proper response (+3.5 until 0.35 s, −4
    after) has the mean 0.5·3.5 − 0.5·4 = −0.25 m/s² there: compliant. Its bound is no longer −b_min = −4 (which
    blamed it, excess 3.75); braking less, e.g. a mean of +0.5 m/s², still violates it by 0.75."""
    exact = _rear_car_run([3.5, 3.5, -0.25, -4.0, -4.0], rho=0.25)
    (episode,) = exact.episodes().to_dict("records")
    assert episode["owed_a"] == "lon:brake-min" and episode["responsible"] == "none"
    assert exact.violations().empty
    late = _rear_car_run([3.5, 3.5, 0.5, -4.0, -4.0], rho=0.25)
    (violation,) = late.violations().to_dict("records")
    assert violation["constraint"] == "lon-brake-after-response-time" and violation["t_start_s"] == pytest.approx(0.4)
    assert violation["bound"] == pytest.approx(-0.25) and violation["excess"] == pytest.approx(0.75)
    on_the_grid = _rear_car_run([3.5] * 9 + [0.0, -3.0], rho=1.0)  # ρ = 1 s ends with a step: −b_min after it
    late_brake = on_the_grid.violations()
    assert list(zip(late_brake["bound"], late_brake["t_start_s"])) == [(-4.0, pytest.approx(1.2))]


def test_the_step_that_ends_an_episode_is_judged_also_where_the_pair_is_no_longer_evaluated():
    """An FCD written every 1 s: a step after its t_b the pair is no longer a candidate (one car has left the
    junction), yet the rear car's acceleration over that step (+2.6 m/s² after its 1 s response time) was driven
    while the pair was in danger. It was not judged, and the collision between the two steps was blamed on
    nobody. Its lateral duty cannot be judged there (no lateral speeds without the pair's frame)."""
    tracker = ResponsibilityTracker()
    _step(tracker, 0.0, _pair(True, False))
    _step(tracker, 1.0, _pair(False, False, v_lat_a=0.3))
    _step(tracker, 2.0, _pair(False, False, v_lat_a=0.3), accel=(2.6, 0.0))  # within ρ: allowed
    _step(tracker, 3.0, _pair(False, False), accel=(2.6, 0.0), keys=())  # gone from the candidates
    tracker.finish()
    (episode,) = tracker.episodes().to_dict("records")
    assert (episode["t_b_s"], episode["t_end_s"], episode["ended_by"]) == (1.0, 3.0, "safe")
    (violation,) = tracker.violations().to_dict("records")
    assert violation["constraint"] == "lon-brake-after-response-time" and violation["vehicle_id"] == "a"
    assert violation["worst_actual"] == pytest.approx(2.6) and episode["responsible"] == "a"


def test_the_step_that_ends_an_episode_is_judged_the_one_that_starts_it_is_not():
    """Lateral unsafe throughout; longitudinally safe at 0 s, dangerous at 0.1 s, laterally safe at 0.2 s. The
    acceleration reported at 0.1 s was driven while the pair was safe (not judged); the one reported at 0.2 s was
    driven from 0.1 s, in danger: the front car b brake-checking at −12 m/s² (b_max 8) there is responsible."""
    tracker = ResponsibilityTracker()
    _step(tracker, 0.0, _pair(True, False))
    _step(tracker, 0.1, _pair(False, False), accel=(0.0, -12.0))
    _step(tracker, 0.2, _pair(False, True), accel=(0.0, -12.0))
    tracker.finish()
    (episode,) = tracker.episodes().to_dict("records")
    assert (episode["t_b_s"], episode["t_end_s"], episode["ended_by"]) == (0.1, 0.2, "safe")
    assert episode["owed_b"] == "lon:brake-at-most-max" and episode["responsible"] == "b"
    (violation,) = tracker.violations().to_dict("records")
    assert (violation["vehicle_id"], violation["constraint"], violation["t_start_s"], violation["excess"]) == \
        ("b", "lon-brake-beyond-max", 0.2, pytest.approx(4.0))


def test_a_lateral_response_that_has_come_to_rest_must_stay_at_rest():
    """Cut-in (lateral safe before t_b = 0.1 s): the lateral response is owed by both. Car a (on the right, + =
    towards b) was moving towards b at u0 = 0.5 m/s, stops its lateral motion at once and holds 0 past ρ; at 1.2 s
    (τ = 1.1 s) it moves towards b again at 0.3 m/s. The envelope alone would allow 0.5 + 0.2·1 − 0.8·0.1 = 0.62
    m/s; but its speed has been ≤ 0 from ρ on and must stay there (rss.md §5): a violation by 0.3 m/s."""
    tracker = ResponsibilityTracker()
    _step(tracker, 0.0, _pair(False, True))
    _step(tracker, 0.1, _pair(False, False, v_lat_a=0.5))
    for k in range(2, 12):
        _step(tracker, round(k * DT, 10), _pair(False, False))
    _step(tracker, 1.2, _pair(False, False, v_lat_a=0.3))
    tracker.finish()
    (episode,) = tracker.episodes().to_dict("records")
    assert episode["owed_a"] == "lat:brake" and episode["responsible"] == "a"
    (violation,) = tracker.violations().to_dict("records")
    assert (violation["constraint"], violation["bound"], violation["worst_actual"]) == \
        ("lat-speed-envelope", 0.0, pytest.approx(0.3))


def test_a_car_in_line_with_the_one_that_cut_in_may_move_out_to_either_side():
    """Car b cut in (lateral safe before t_b = 0.1 s) and from 0.5 s drives straight ahead of a in a's lane
    (centres 0.0 m apart, within μ/2): no side of a is towards b. From 1.5 s a moves left at 0.5 m/s to pass b
    (+ = left); from 1.7 s its centre is 0.3 m left of b's (beyond μ/2 = 0.05 m), so b is on its right and moving
    left is moving away: a owes nothing and is not responsible. The lateral duty keeps the side the cars are on
    now (highway_sparse seed 0: the EPSILON ego was held behind a car that cut in ahead of it for 37 s)."""
    tracker = ResponsibilityTracker()
    _step(tracker, 0.0, _pair(False, True))
    for k in range(1, 15):
        _step(tracker, round(k * DT, 10), _pair(False, False, lat_offset=1.0 if k < 5 else 0.0))
    for k in range(15, 25):
        offset = 0.5 * (k - 14) * DT
        _step(tracker, round(k * DT, 10), _pair(False, False, v_lat_a=0.5, a_left=offset > 0.0, lat_offset=offset))
    tracker.finish()
    (episode,) = tracker.episodes().to_dict("records")
    assert episode["owed_a"] == "lat:brake" and episode["responsible"] == "none"
    assert tracker.violations().empty


def test_a_car_beside_the_one_that_cut_in_may_not_move_towards_it():
    """The same move left by a while b is still 1.0 m to its left, beside it (not in line): towards b after its
    lateral speed had come to rest, a violation by 0.5 m/s."""
    tracker = ResponsibilityTracker()
    _step(tracker, 0.0, _pair(False, True))
    for k in range(1, 15):
        _step(tracker, round(k * DT, 10), _pair(False, False, lat_offset=1.0))
    for k in range(15, 25):
        _step(tracker, round(k * DT, 10), _pair(False, False, v_lat_a=0.5, lat_offset=1.0 - 0.05 * (k - 14)))
    tracker.finish()
    (episode,) = tracker.episodes().to_dict("records")
    assert episode["responsible"] == "a"
    (violation,) = tracker.violations().to_dict("records")
    assert (violation["constraint"], violation["worst_actual"]) == ("lat-speed-envelope", pytest.approx(0.5))


def test_the_lateral_tolerance_stops_growing_once_the_envelope_has_reached_zero():
    """Same cut-in, a holding still sideways; it then moves towards b at 1 m/s (a SUMO lane change's ~1.17 m/s) at
    τ = 2 s or τ = 22 s. The envelope from u0 = 0.5 reaches 0 at ρ + (0.5 + 0.2·1)/0.8 = 1.875 s, so the
    tolerance is 0.05 m/s²·min(τ, 1.875 s) ≤ 0.094 m/s either way: a violation by 1 m/s both times (the tolerance
    used to be 0.05·τ, 1.1 m/s at τ = 22 s, and let the later move pass)."""
    for start in (2.0, 22.0):
        tracker = ResponsibilityTracker()
        _step(tracker, 0.0, _pair(False, True))
        _step(tracker, 0.1, _pair(False, False, v_lat_a=0.5))
        moving = round(0.1 + start, 10)
        k = 2
        while (t := round(k * DT, 10)) <= moving + 0.15:
            _step(tracker, t, _pair(False, False, v_lat_a=1.0 if t >= moving - 1e-9 else 0.0))
            k += 1
        tracker.finish()
        (episode,) = tracker.episodes().to_dict("records")
        assert episode["responsible"] == "a", start
        (violation,) = tracker.violations().to_dict("records")
        assert (violation["constraint"], violation["bound"], violation["worst_actual"], violation["t_start_s"]) == \
            ("lat-speed-envelope", 0.0, pytest.approx(1.0), pytest.approx(moving)), start


def _road_and_junction(road_rules: int, junction_rules: int) -> PairSituations:
    """One pair in two situations: a behind b on a road, and a yielding to b (b has priority) at a conflict area."""
    z, no = np.zeros(2), np.zeros(2, dtype=bool)
    return PairSituations(
        a=np.zeros(2, dtype=int), b=np.ones(2, dtype=int), kind=np.array([0, FIRST_INTERSECTION_CODE]),
        a_is_rear=np.ones(2, dtype=bool), a_is_left=no, lon_gap=np.full(2, 5.0), lat_gap=np.array([0.0, np.nan]),
        v_lon_a=np.full(2, 10.0), v_lon_b=np.full(2, 10.0), v_lat_a=z, v_lat_b=z, lon_d_min=np.full(2, 10.0),
        lat_d_min=np.array([1.0, np.nan]), lon_safe=np.array([road_rules > 0, False]), lat_safe=no,
        rules=np.array([road_rules, junction_rules], dtype=np.int8), priority=np.array([0, 2], dtype=np.int8),
        in_front=np.array([0, 2], dtype=np.int8), area=np.array(["", "J:0x1"], dtype=object))


def test_a_collision_that_closes_a_road_and_a_junction_episode_blames_whoever_either_found_responsible():
    """The road episode finds the front car b responsible (it brakes at −10 m/s², b_max 8); in the junction episode
    only a owed braking (b has priority) and a complied. The collision closes both: blamed b, both keys."""
    tracker = ResponsibilityTracker()
    keys = (PAIR, PAIR | INTERSECTION_KEY)
    _step(tracker, 0.0, _road_and_junction(RULE_LON, RULE_ABLE_TO_STOP), keys=keys)
    _step(tracker, 0.1, _road_and_junction(0, 0), keys=keys)
    _step(tracker, 0.2, _road_and_junction(0, 0), accel=(0.0, -10.0), keys=keys)
    records = tracker.collide([int(PAIR), int(PAIR | INTERSECTION_KEY)], 0.2, "a", "b")
    assert [(r["episode_key"], r["responsible"], r["ended_by"]) for r in records] == \
        [("a|b|1", "b", "collision"), ("a|b|x1", "none", "collision")]
    assert collision_blame(records) == ("b", "a|b|1;a|b|x1")
    assert collision_blame([]) == ("none", "")
    assert tracker.collide([int(PAIR)], 0.3, "a", "b") == []  # nothing open any more


def test_after_a_contact_the_model_did_not_see_coming_no_episode_opens_while_the_cars_stay_in_contact():
    """The pair was safe when SUMO reported the contact (no episode: blamed none). The cars stay overlapped and the
    pair dangerous for a while (SUMO's collision action 'warn'); a new episode then would judge what follows the
    contact, here blaming a that keeps its speed. None opens until the pair is safe once; then episodes count
    again."""
    tracker = ResponsibilityTracker()
    _step(tracker, 0.0, _pair(True, False))
    _step(tracker, 0.1, _pair(True, False))
    assert tracker.collide([int(PAIR)], 0.1, "a", "b") == []
    for k in range(2, 20):
        _step(tracker, round(k * DT, 10), _pair(False, False))
    _step(tracker, 2.0, _pair(True, False))
    _step(tracker, 2.1, _pair(False, False))
    tracker.finish()
    assert [(e["t_b_s"], e["episode_index"]) for e in tracker.episodes().to_dict("records")] == [(2.1, 1)]


@pytest.mark.parametrize("tolerance, blamed", [(0.05, True), (0.15, False)])
def test_accelerations_measured_coarsely_are_judged_within_their_resolution(tolerance, blamed):
    """An FCD without accelerations, speeds written with 2 decimals at a 0.1 s step: a derived acceleration may be
    off by 0.1 m/s², twice the 0.05 tolerance. A rear car read at −3.9 m/s² where b_min = 4 is owed (excess 0.1) is
    within that resolution: not a violation there; with exact accelerations it is."""
    tracker = ResponsibilityTracker()
    p = RssParams(response_time=0.1)
    _step(tracker, 0.0, _pair(True, False), params=p)
    _step(tracker, 0.1, _pair(False, False), params=p)
    for k in range(2, 5):
        _step(tracker, round(k * 0.1, 10), _pair(False, False), accel=(-3.9, 0.0), params=p,
              accel_tolerance=tolerance)
    tracker.finish()
    assert (tracker.episodes().to_dict("records")[0]["responsible"] == "a") == blamed
