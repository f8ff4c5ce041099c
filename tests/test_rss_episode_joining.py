"""Episodes that flicker around the safe distance are one episode; the raw form stays available.

tests/data/a10kw_motorway.net.xml: a 1.2 km stretch of the A10 motorway (eclipse-sumo's A10KW net, OSM), three
lanes. The rear car drives at 25 m/s; the car 89.14 m ahead of it at 25 m/s ± 0.2 m/s (a 1.6 s sine), so the gap
hovers around d_min = 25 + 1.75 + 28.5²/8 − 25²/16 = 89.19 m: dangerous for ~0.8 s of every 1.6 s, then safe for
~0.8 s (both less than ρ = 1 s), as Monaco's car210|car72 (101 episodes in 140 s at 46-47 m, d_min ± 0.5 m).
"""
from __future__ import annotations

import math

import libsumo
import pytest

from sumo_runs import CAR, DATA, STEP_S, hold_speed, run_sumo

SPEED, SWING, PERIOD = 25.0, 0.2, 1.6  # [m/s], [m/s], [s]


@pytest.fixture(scope="module")
def hovering(tmp_path_factory):
    folder = tmp_path_factory.mktemp("hovering")

    def control(time: float) -> None:
        for vid in ("rear", "front"):
            if vid in libsumo.vehicle.getIDList():
                swing = SWING * math.sin(2.0 * math.pi * (time + STEP_S) / PERIOD) if vid == "front" else 0.0
                hold_speed(vid, SPEED + swing)

    routes = CAR + '<route id="r" edges="264306385"/>' \
        '<vehicle id="rear" type="car" route="r" depart="0" departLane="1" departPos="20" departSpeed="25"/>' \
        '<vehicle id="front" type="car" route="r" depart="0" departLane="1" departPos="113.64" departSpeed="25"/>'
    return run_sumo(DATA / "a10kw_motorway.net.xml", folder, routes, 30.0, lambda: None, control)


def test_an_episode_that_reopens_within_rho_continues_and_the_raw_form_counts_each(hovering):
    """Verdict: one episode of a car following at about its safe distance for the whole run, nobody responsible
    (each dangerous spell is shorter than ρ: the rear car never owed braking). Raw, it is one episode per spell."""
    joined, raw = hovering.audit(), hovering.audit(raw_episodes=True)
    assert len(raw.episodes) >= 15  # ~30 s / 1.6 s
    assert set(raw.episodes.responsible) == {"none"}
    assert len(joined.episodes) == 1
    episode = joined.episodes.iloc[0]
    assert episode.responsible == "none" and episode.episode_key == "front|rear|1"
    assert episode.t_b_s == raw.episodes.t_b_s.min() and episode.t_end_s == raw.episodes.t_end_s.max()
    assert episode.min_lon_margin_m == pytest.approx(raw.episodes.min_lon_margin_m.min())
    assert (episode.trigger, episode.owed_a, episode.owed_b) == tuple(raw.episodes.iloc[0][["trigger", "owed_a",
                                                                                              "owed_b"]])


def test_joining_never_changes_who_is_responsible(hovering, tmp_path):
    """A spell that outlasts ρ: from 20 s the front car brakes at 1 m/s² for 2 s (the rear car keeps its speed):
    the rear car is responsible in the raw episode of that spell and so in the joined one."""
    def control(time: float) -> None:
        for vid in ("rear", "front"):
            if vid in libsumo.vehicle.getIDList():
                if vid == "front" and 20.0 <= time < 22.0:
                    hold_speed(vid, SPEED - (time + STEP_S - 20.0))
                elif vid == "front" and time >= 22.0:
                    hold_speed(vid, SPEED - 2.0)
                else:
                    swing = SWING * math.sin(2.0 * math.pi * (time + STEP_S) / PERIOD) if vid == "front" else 0.0
                    hold_speed(vid, SPEED + swing)

    run = run_sumo(hovering.net, tmp_path, hovering.routes.read_text()[len("<routes>"):-len("</routes>")], 26.0,
                   lambda: None, control)
    joined, raw = run.audit(), run.audit(raw_episodes=True)
    assert set(raw.episodes.responsible) == {"none", "b"}  # b = rear
    assert len(joined.episodes) == 1 and joined.episodes.iloc[0].responsible == "b"
    keys = set(joined.violations.episode_key)
    assert keys == {"front|rear|1"} and len(joined.violations) == len(raw.violations)
