"""Responsibility in real libsumo traffic on the highway, vehicles commanded step by step (ad_rss preset:
ρ = 1 s, a_acc = 3.5, b_min = 4, b_max = 8 m/s²; vType 'car': 4.5 m x 1.8 m; lanes 3.5 m wide)."""
from __future__ import annotations

from collections.abc import Callable

import libsumo
import pandas as pd
import pytest

from conftest import audit_commanded, write_scenario
from sumo_rss import load_scenario
from sumo_rss.rss.auditor import AuditResult

DT = 0.1  # [s]


def _empty_highway(tmp_path, valid_scenario):
    valid_scenario["demand"]["flows"] = []
    del valid_scenario["ego"]
    valid_scenario["duration_s"] = 60.0
    valid_scenario.setdefault("rss", {})["evasive_effort"] = True  # rule 5 is opt-in (docs/rss.md)
    return load_scenario(write_scenario(tmp_path, valid_scenario))


def _add(vid: str, lane: int, pos: float, speed: float) -> None:
    libsumo.vehicle.add(vid, "hw", typeID="car", depart="now", departLane=str(lane), departPos=str(pos),
                        departSpeed=str(speed))
    libsumo.vehicle.setSpeedMode(vid, 0)  # exactly the commanded speed, no safety checks of its own
    libsumo.vehicle.setLaneChangeMode(vid, 0)


def _audit(spec, setup: Callable[[], None], control: Callable[[float], None], seconds: float) -> AuditResult:
    def setup_route() -> None:
        libsumo.route.add("hw", ["hw0", "hw1", "hw2"])
        setup()

    return audit_commanded(spec, setup_route, control, seconds)


def _accelerate(vid: str, accel: float) -> None:
    """Command ``accel`` [m/s²] over the coming step (never below standstill)."""
    v = libsumo.vehicle.getSpeed(vid)
    libsumo.vehicle.setSpeed(vid, max(0.0, v + accel * DT))


def _only_episode(result: AuditResult) -> pd.Series:
    assert len(result.episodes) == 1, result.episodes
    return result.episodes.iloc[0]


def test_a_follower_accelerating_into_a_braking_leader_is_responsible(tmp_path, valid_scenario):
    spec = _empty_highway(tmp_path, valid_scenario)

    def setup():  # same lane, 20 m/s each, 95.5 m bumper gap (> d_min 65.8 m: safe at the start)
        _add("leader", 1, 300.0, 20.0)
        _add("follower", 1, 200.0, 20.0)

    def control(t):
        if libsumo.vehicle.getIDCount() == 2:
            _accelerate("leader", -4.0 if t >= 1.0 else 0.0)  # a proper, moderate stop
            _accelerate("follower", 1.0)  # keeps accelerating

    result = _audit(spec, setup, control, 14.0)
    episode = _only_episode(result)
    # In one lane lateral safety never held, so the longitudinal response is owed (rss.md §5).
    assert episode.situation == "same-direction" and episode.trigger == "lon"
    assert (episode.vehicle_a, episode.vehicle_b) == ("follower", "leader")
    assert (episode.owed_a, episode.owed_b) == ("lon:brake-min", "lon:brake-at-most-max")
    assert episode.responsible == "a"
    broken = result.violations
    assert set(broken.vehicle_id) == {"follower"}
    assert set(broken.constraint) == {"lon-brake-after-response-time"}
    row = broken.iloc[0]
    assert row.bound == -4.0 and row.worst_actual == pytest.approx(1.0, abs=1e-6) and row.excess == pytest.approx(5.0)
    # The first violating step is the first one after t_b + ρ.
    assert row.t_start_s == pytest.approx(episode.t_b_s + 1.1, abs=1e-6)
    # The follower hits the standing leader; the collision joins the episode and blames the follower.
    assert episode.collision and episode.ended_by == "collision"
    (collision,) = result.collisions.itertuples()
    assert collision.blamed == "follower" and collision.episode_key == episode.episode_key


def test_b_leader_braking_harder_than_b_max_is_responsible(tmp_path, valid_scenario):
    spec = _empty_highway(tmp_path, valid_scenario)

    def setup():  # 20 m/s each, bumper gap 70.5 m: just above d_min = 65.78 m
        _add("leader", 1, 275.0, 20.0)
        _add("follower", 1, 200.0, 20.0)

    braking = {"t_b": None}

    def control(t):
        if libsumo.vehicle.getIDCount() < 2:
            return
        _accelerate("leader", -9.5 if t >= 1.0 else 0.0)  # a brake check beyond b_max = 8
        if t >= 1.0 and braking["t_b"] is None:
            braking["t_b"] = t
        # The follower answers properly: no acceleration during ρ, then brakes at 4.5 ≥ b_min.
        _accelerate("follower", -4.5 if braking["t_b"] is not None and t >= braking["t_b"] + 1.0 else 0.0)

    result = _audit(spec, setup, control, 10.0)
    episode = _only_episode(result)
    assert (episode.vehicle_a, episode.vehicle_b) == ("follower", "leader")
    assert episode.responsible == "b" and not episode.collision
    # Rule 5 is asked of collisions only (docs/rss.md): this near miss is not asked.
    assert not episode.evasive_checked and episode.rule5_responsible == ""
    assert set(result.violations.vehicle_id) == {"leader"}
    assert set(result.violations.constraint) == {"lon-brake-beyond-max"}
    assert result.violations.worst_actual.min() == pytest.approx(-9.5, abs=1e-6)


def test_c_cut_in_at_unsafe_distance_makes_the_cutting_car_responsible(tmp_path, valid_scenario):
    spec = _empty_highway(tmp_path, valid_scenario)

    def setup():  # the cutter in lane 2, 15 m ahead of the follower's front bumper, both at 20 m/s
        _add("cutter", 2, 219.5, 20.0)
        _add("follower", 1, 200.0, 20.0)

    state = {"t_b": None}

    def control(t):
        if libsumo.vehicle.getIDCount() < 2:
            return
        if t >= 0.95 and state["t_b"] is None:
            libsumo.vehicle.changeLane("cutter", 1, 3.0)  # into the follower's lane, 3 s manoeuvre
            state["t_b"] = t
        _accelerate("cutter", 0.0)
        # The follower brakes properly once the cut-in has begun (after ρ, at 4.5 m/s² ≥ b_min).
        _accelerate("follower", -4.5 if state["t_b"] is not None and t >= state["t_b"] + 1.0 else 0.0)

    result = _audit(spec, setup, control, 8.0)
    episode = _only_episode(result)
    assert (episode.vehicle_a, episode.vehicle_b) == ("cutter", "follower")
    assert episode.trigger == "lat"  # lateral safety was lost: the cut-in
    assert episode.owed_a == "lat:brake" and episode.owed_b == "lat:brake"
    assert episode.responsible == "a"
    assert set(result.violations.vehicle_id) == {"cutter"}
    assert set(result.violations.constraint) == {"lat-speed-envelope"}


def test_d_cars_keeping_safe_distances_produce_no_episode(tmp_path, valid_scenario):
    spec = _empty_highway(tmp_path, valid_scenario)

    def setup():
        _add("ahead", 1, 400.0, 30.0)  # 195.5 m ahead of "behind" (d_min 72 m), and faster
        _add("behind", 1, 200.0, 25.0)
        _add("beside", 0, 200.0, 25.0)  # the next lane: 1.7 m lateral gap (d_min 0.35 m), no lateral motion

    def control(t):
        for vid in ("ahead", "behind", "beside"):
            if vid in libsumo.vehicle.getIDList():
                _accelerate(vid, 0.0)

    result = _audit(spec, setup, control, 20.0)
    assert result.episodes.empty and result.violations.empty and result.collisions.empty
