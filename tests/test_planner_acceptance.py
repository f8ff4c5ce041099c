"""Issue 48's acceptance: the EPSILON ego is safe *and* not timid, judged on seeds 0-19 of every scenario family
against the SUMO-driven ego (and, at junctions, against SUMO's ego held to RSS: sumo_restricted) on the same seeds,
with the per-run measures of sumo_rss.report.ego_metrics. Every EPSILON run: no collision involving the ego, never
responsible (as issue 5 asked, and still).

- Free flow (every highway run): with no car within 150 m ahead in its lane and no lane end or lower limit within
  its stopping distance, the ego holds >= 99 % of min(desired speed, speed limit).
- highway_overtake: the ego passes the slow truck in >= 18 of 20 seeds; its settled mean speed is >= 1.15x that
  of the same planner without lateral actions, and >= the SUMO ego's.
- highway_exit: the ego leaves by the ramp in 20 of 20 seeds.
- highway_sparse: settled mean speed >= 0.97x the SUMO ego's.
- intersection_tls, intersection_priority: median route travel time <= 1.15x the SUMO ego's and <= the
  sumo_restricted ego's.
- merge_onramp: merged before the acceleration lane ends in 20 of 20; median time from entering the acceleration
  lane to the completed merge <= 30 s, maximum <= 90 s; where a seed misses it (over 30 s if the median misses,
  over 90 s if the maximum does), no RSS-legal merge was reachable earlier than its merge minus the slack
  (sumo_rss.report.merge_gaps_run: the change time + 1 s).
Only with SUMO_RSS_ACCEPTANCE=1 (make acceptance): ~160 runs of the planner, each batch once per module.
"""
from __future__ import annotations

import numpy as np
import pytest

from closed_loop import ACCEPTANCE_SEEDS, acceptance, assert_on_acceleration_lane_not_past_its_end, assert_safe, batch, \
    trace
from sumo_rss.report.ego_metrics import ego_run_metrics, free_flow_shortfalls, passed
from sumo_rss.report.merge_gaps import GapSearch
from sumo_rss.report.merge_gaps_run import merge_gap_report

pytestmark = [acceptance, pytest.mark.slow]
HIGHWAY_DENSE_S = 90.0  # highway_dense is cut short (60 s of planner driving); the others run their own duration
SLOW_TRUCK = "slow.0"  # highway_overtake's truck the ego starts behind


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """runs(name, controller="epsilon", **planner): the 20-seed batch of one scenario and controller, made once."""
    made: dict = {}

    def get(name: str, controller: str = "epsilon", **planner):
        key = (name, controller, tuple(sorted(planner.items())))
        if key not in made:
            made[key] = batch(name, tmp_path_factory.mktemp(name), ACCEPTANCE_SEEDS, controller=controller,
                              duration=HIGHWAY_DENSE_S if name == "highway_dense" else None,
                              fcd=name.startswith("highway") or name == "merge_onramp", **planner)
            if controller == "epsilon":
                assert_safe(made[key])
        return made[key]
    return get


def _metrics(runs_of_one) -> list:
    return [ego_run_metrics(folder) for _, folder in runs_of_one]


def _settled(runs_of_one) -> float:
    return float(np.mean([m.settled_mean_speed_ms for m in _metrics(runs_of_one)]))


def _median_travel(runs_of_one) -> float:
    return float(np.median([m.travel_time_s if m.travel_time_s is not None else np.inf
                            for m in _metrics(runs_of_one)]))


@pytest.mark.parametrize("name", ["highway_dense", "highway_sparse", "highway_overtake"])
def test_in_free_flow_the_ego_holds_its_speed(runs, name):
    shortfalls = {task.spec.seed: free_flow_shortfalls(folder) for task, folder in runs(name)}
    assert not any(shortfalls.values()), {seed: s[:3] for seed, s in shortfalls.items() if s}


def test_the_ego_overtakes_the_slow_truck_and_gains_by_it(runs):
    planner = runs("highway_overtake")
    overtaken = [task.spec.seed for task, folder in planner if passed(folder, SLOW_TRUCK)]
    assert len(overtaken) >= 18, overtaken
    keeping = runs("highway_overtake", lane_changes=False)
    sumo = runs("highway_overtake", "sumo")
    assert _settled(planner) >= 1.15 * _settled(keeping)
    assert _settled(planner) >= _settled(sumo)


def test_the_ego_takes_the_exit(runs):
    missed = [task.spec.seed for task, folder in runs("highway_exit")
              if not any(r["lane_id"].startswith("ex_ramp_") for r in trace(folder))]
    assert not missed


def test_on_the_sparse_highway_the_ego_keeps_up_with_the_sumo_ego(runs):
    assert _settled(runs("highway_sparse")) >= 0.97 * _settled(runs("highway_sparse", "sumo"))


@pytest.mark.parametrize("name", ["intersection_tls", "intersection_priority"])
def test_at_junctions_the_ego_is_about_as_quick_as_the_sumo_ego(runs, name):
    planner = _median_travel(runs(name))
    assert planner <= 1.15 * _median_travel(runs(name, "sumo"))
    assert planner <= _median_travel(runs(name, "sumo_restricted"))


def test_on_the_dense_highway_the_ego_is_safe(runs):
    assert len(runs("highway_dense")) == len(ACCEPTANCE_SEEDS)  # never responsible, no collision: runs() asserts it


def test_the_ego_merges_promptly_from_the_ramp(runs):
    merge = runs("merge_onramp")
    assert_on_acceleration_lane_not_past_its_end(merge)
    for task, folder in merge:
        lanes = [r["lane_id"] for r in trace(folder)]
        assert lanes[-1] not in ("ramp_0", "mw_merge_0"), f"{task.run_id}: never merged"
        assert any(lane.startswith("mw_out_") for lane in lanes), f"{task.run_id}: never reached mw_out"
    delays = [m.merge_delay_s for m in _metrics(merge)]
    if np.median(delays) <= 30.0 and max(delays) <= 90.0:
        return
    line = 30.0 if np.median(delays) > 30.0 else 90.0
    reports = [merge_gap_report(folder) for (_, folder), delay in zip(merge, delays) if delay > line]
    missed = {r.run: round(r.missed_s(), 1) for r in reports if not r.explained(GapSearch().change_s)}
    assert not missed, (delays, missed)  # run: its merge minus the earliest legal start [s]
