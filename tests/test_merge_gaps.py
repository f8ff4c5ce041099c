"""The earliest RSS-legal merge (sumo_rss.report.merge_gaps): hand-made target lanes whose answer is known, and one
real merge_onramp run (EPSILON ego, libsumo, the shipped network) checked against the auditor's formulas."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from closed_loop import batch
from sumo_rss.cli import main
from sumo_rss.report.ego_metrics import ego_run_metrics
from sumo_rss.report.merge_gaps import EgoLimits, GapSearch, TargetLane, earliest_merge, reachable_interval
from sumo_rss.report.merge_gaps_run import merge_gap_report
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss import formulas
from sumo_rss.rss.params import RssParamArrays, RssParams

DT = 0.1
EGO_LENGTH = 4.7
AD_RSS = RssParams()
STEADY = EgoLimits(accel=1e-6, brake=1e-6, max_speed=33.33)  # the ego can only hold its speed
PLANNER = EgoLimits.planner(33.33)


def _lane(front: np.ndarray, speed: np.ndarray, end: float = 270.0, length: float = 4.5) -> TargetLane:
    """A target lane of slots ``front`` / ``speed`` [T, N] (nan: empty), every car ``length`` m, ad_rss."""
    times = np.arange(front.shape[0]) * DT
    params = RssParamArrays.stack([AD_RSS] * front.size)
    params = RssParamArrays(*(getattr(params, name).reshape(front.shape) for name in params.__dataclass_fields__))
    return TargetLane(times, front, speed, np.full(front.shape, length), params, end)


def _constant(t: np.ndarray, start: float, speed: float) -> np.ndarray:
    return start + speed * t


def test_the_reachable_interval_is_exact_for_bang_bang_profiles():
    lo, hi, ok = reachable_interval(np.array([0.0, 10.0, 14.0]), np.array(2.0), 10.0, EgoLimits(2.0, 5.0, 33.0))
    # 10 m/s after 2 s: at most +2 for 1 s, -2 (of 5) ... w = (2 + 5 + 2)/(0.5 + 0.2) = 12.857; at least brake then
    # accelerate: u = (2 + 5 - 2)/0.7 = 7.143.
    w, u = (2 + 10 / 2 + 10 / 5) / 0.7, (10 / 5 + 10 / 2 - 2) / 0.7
    assert hi[1] == pytest.approx((w * w - 100) / 4 + (w * w - 100) / 10)
    assert lo[1] == pytest.approx((100 - u * u) / 10 + (100 - u * u) / 4)
    assert hi[2] == pytest.approx(lo[2]) == pytest.approx(24.0)  # 14 m/s only by accelerating all the time
    assert ok.tolist() == [True, True, True]
    assert lo[0] == pytest.approx(10.0) and not reachable_interval(0.0, 1.0, 10.0, EgoLimits(2.0, 5.0, 33.0))[2]


def test_a_gap_that_opens_behind_the_ego_is_found_when_the_slower_follower_is_at_the_safe_distance():
    t = np.arange(300) * DT
    leader = _constant(t, 200.0, 25.0)  # far ahead, as fast as the ego
    follower = _constant(t, -EGO_LENGTH - 2.0, 20.0)  # starts 2 m behind the ego's rear, falls back at 5 m/s
    lane = _lane(np.stack([leader, follower], axis=1), np.stack([np.full_like(t, 25.0), np.full_like(t, 20.0)], 1),
                 end=1e6)
    got = earliest_merge(lane, 0.0, 0.0, 25.0, EGO_LENGTH, AD_RSS, STEADY)
    d_min = float(formulas.lon_safe_distance_same_dir(20.0, 25.0, AD_RSS, AD_RSS))
    opens = (d_min + formulas.SAFE_DISTANCE_PRECISION - 2.0) / 5.0  # the follower's gap 2 + 5 t passes d_min
    assert opens < got.start_s <= opens + DT + 1e-9
    assert got.speed_ms == pytest.approx(25.0) and got.completion_s == pytest.approx(got.start_s + 1.0)
    # With the planner's acceleration the ego pulls ahead of the follower sooner.
    assert earliest_merge(lane, 0.0, 0.0, 25.0, EGO_LENGTH, AD_RSS, PLANNER).start_s < got.start_s


def _platoon(t: np.ndarray, hole: tuple[float, float]) -> TargetLane:
    """Cars every 15 m at 25 m/s from -300 m to +300 m, all gone from the lane during ``hole`` [s)."""
    starts = np.arange(-300.0, 300.0, 15.0)
    front = starts[None, :] + 25.0 * t[:, None]
    front[(t >= hole[0]) & (t < hole[1])] = np.nan
    return _lane(front, np.full_like(front, 25.0), end=1e6)


def test_a_hole_shorter_than_the_lane_change_is_rejected_and_a_long_enough_one_is_found():
    t = np.arange(80) * DT
    short = _platoon(t, (5.0, 5.5))
    assert earliest_merge(short, 0.0, 0.0, 25.0, EGO_LENGTH, AD_RSS, PLANNER).start_s is None
    shorter_change = earliest_merge(short, 0.0, 0.0, 25.0, EGO_LENGTH, AD_RSS, PLANNER, GapSearch(change_s=0.4))
    assert shorter_change.start_s == pytest.approx(5.0)
    long = earliest_merge(_platoon(t, (5.0, 6.5)), 0.0, 0.0, 25.0, EGO_LENGTH, AD_RSS, PLANNER)
    assert long.start_s == pytest.approx(5.0) and long.completion_s == pytest.approx(6.0)


def test_a_gap_beyond_the_egos_acceleration_or_the_lanes_end_is_rejected():
    t = np.arange(160) * DT  # 16 s
    standing = np.arange(-100.0, 151.0, 10.0)  # a standing queue up to 150 m
    front = np.repeat(standing[None, :], t.size, axis=0)
    lane = _lane(front, np.zeros_like(front))
    # From standstill at 2 m/s² the ego passes the queue's head (+ the ego's length, the queue's d_min) after
    # about sqrt(2 * 155 / 2) = 12.4 s; within 10 s it cannot.
    first_10_s = _lane(front[:100], np.zeros((100, standing.size)))
    assert earliest_merge(first_10_s, 0.0, 0.0, 0.0, EGO_LENGTH, AD_RSS, PLANNER).start_s is None
    got = earliest_merge(lane, 0.0, 0.0, 0.0, EGO_LENGTH, AD_RSS, PLANNER)
    need = 150.0 + EGO_LENGTH + float(formulas.lon_safe_distance_same_dir(0.0, got.speed_ms, AD_RSS, AD_RSS))
    assert got.front_m >= need - 1e-6 and got.start_s >= math.sqrt(2.0 * need / 2.0) - DT
    ended = TargetLane(lane.times, lane.front, lane.speed, lane.length, lane.params, end=140.0)
    assert earliest_merge(ended, 0.0, 0.0, 0.0, EGO_LENGTH, AD_RSS, PLANNER).start_s is None


def test_bad_settings_and_folders_are_refused_in_one_line(tmp_path, capsys):
    with pytest.raises(ValueError, match="change time"):
        GapSearch(change_s=-1.0)
    with pytest.raises(ValueError, match="speed step"):
        GapSearch(speed_step=0.0)
    assert main(["merge-gaps", str(tmp_path), "--change-time", "-1"]) == 2
    assert "change time must be in [0, 20] s" in capsys.readouterr().err
    assert main(["merge-gaps", str(tmp_path)]) == 2
    assert f"{tmp_path}: no ego_trace.csv" in capsys.readouterr().err


@pytest.mark.slow
def test_a_real_merge_starts_no_earlier_than_its_earliest_legal_merge(tmp_path, capsys):
    (task, folder), = batch("merge_onramp", tmp_path, range(17, 18), duration=75.0, fcd=True)
    report = merge_gap_report(folder)
    delay = ego_run_metrics(folder).merge_delay_s
    assert report.completed_s - report.entered_s == pytest.approx(delay)
    e = report.earliest
    assert report.entered_s <= e.start_s <= report.completed_s
    # The state found is safe by the auditor's formulas to every target-lane car at every step of the change.
    fcd = _target_lane_cars(folder / "fcd.xml", RoadNetwork.from_file(task.spec.net_file))
    for k in range(11):
        at = fcd[np.isclose(fcd.time, e.start_s + k * DT)]
        ego = e.front_m + e.speed_ms * k * DT
        for car in at.itertuples():
            if car.front > ego:
                gap, d_min = car.front - car.length - ego, formulas.lon_safe_distance_same_dir(
                    e.speed_ms, car.speed, AD_RSS, AD_RSS)
            else:
                gap, d_min = ego - EGO_LENGTH - car.front, formulas.lon_safe_distance_same_dir(
                    car.speed, e.speed_ms, AD_RSS, AD_RSS)
            assert formulas.is_safe_distance(gap, d_min), (k, car)
    assert main(["merge-gaps", str(folder)]) == 0
    assert f"| {report.entered_s:.1f} | {e.start_s:.1f} ({e.speed_ms:.1f}) |" in capsys.readouterr().out


def _target_lane_cars(path: Path, net: RoadNetwork) -> pd.DataFrame:
    """Every car on mw_in_0, :m1_1_0, mw_merge_1, :m2_0_0, mw_out_0 per step, its front along mw_merge_1 [m]."""
    length = dict(zip(net.lane_ids, net.lane_length))
    starts = {"mw_in_0": -length["mw_in_0"] - length[":m1_1_0"], ":m1_1_0": -length[":m1_1_0"], "mw_merge_1": 0.0,
              ":m2_0_0": length["mw_merge_1"], "mw_out_0": length["mw_merge_1"] + length[":m2_0_0"]}
    rows = []
    for step in ET.parse(path).getroot():
        for v in step:
            if v.get("lane") in starts and v.get("id") != "ego":
                rows.append((round(float(step.get("time")), 3), starts[v.get("lane")] + float(v.get("pos")),
                             float(v.get("speed")), 12.0 if v.get("type") == "truck" else 4.5))
    return pd.DataFrame(rows, columns=["time", "front", "speed", "length"])
