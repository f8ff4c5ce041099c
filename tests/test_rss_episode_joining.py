"""Episodes that flicker around the safe distance are one episode; the raw form stays available.

tests/data/a10kw_motorway.net.xml: a 1.2 km stretch of the A10 motorway (eclipse-sumo's A10KW net, OSM), three
lanes. The rear car drives at 25 m/s; the car 89.14 m ahead of it at 25 m/s ± 0.2 m/s (a 1.6 s sine), so the gap
hovers around d_min = 25 + 1.75 + 28.5²/8 − 25²/16 = 89.19 m: dangerous for ~0.8 s of every 1.6 s, then safe for
~0.8 s (both less than ρ = 1 s), as Monaco's car210|car72 (101 episodes in 140 s at 46-47 m, d_min ± 0.5 m).
"""
from __future__ import annotations

import math

import libsumo
import numpy as np
import pytest

from sumo_rss.rss.episode_log import EpisodeParts
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


def _part(parts: EpisodeParts, *, responsible, excusable, entered, stays_out, rows=()) -> None:
    parts.add(list(rows), np.array(responsible), np.array(excusable), np.array(entered), np.array(stays_out))


def test_a_yielding_car_that_stands_short_at_the_end_of_a_joined_episode_complied_in_every_part():
    """MoST 249|343 at 223.9-230.5 s: car a (yielding, column 0) brakes 0.6 s late in the first part, which ends
    safe while it is still fast; the pair is dangerous again within ρ twice, and a stands 4.7 m short of the
    conflict area at the end. Over the joined episode it never entered: the first part's blame and violation go,
    car b's blame of the second part stays."""
    late = {"constraint": "lon-brake-after-response-time", "vehicle_id": "a"}
    rear = {"constraint": "lon-brake-after-response-time", "vehicle_id": "b"}
    parts = EpisodeParts()
    _part(parts, responsible=[True, False], excusable=[True, False], entered=[False, False],
          stays_out=[False, False], rows=[(0, late)])
    assert parts.responsible.tolist() == [True, False] and parts.violations() == [late]
    _part(parts, responsible=[False, True], excusable=[False, False], entered=[False, False],
          stays_out=[True, False], rows=[(1, rear)])  # a is the front car here: nothing is excusable
    _part(parts, responsible=[False, False], excusable=[True, False], entered=[False, False],
          stays_out=[True, False])
    assert parts.responsible.tolist() == [False, True] and parts.violations() == [rear]


def test_a_yielding_car_that_enters_in_a_later_part_keeps_the_blame_of_every_part():
    """The same car a enters the conflict area in the last part: it did not stay out, so the first part's
    violation and blame stand even though it was braking hard enough to stop at the end of the first part."""
    late = {"constraint": "lon-brake-after-response-time", "vehicle_id": "a"}
    parts = EpisodeParts()
    _part(parts, responsible=[True, False], excusable=[True, False], entered=[False, False],
          stays_out=[True, False], rows=[(0, late)])
    assert parts.responsible.tolist() == [False, False] and parts.violations() == []  # as a single episode
    _part(parts, responsible=[False, False], excusable=[True, False], entered=[True, False],
          stays_out=[False, False])
    assert parts.responsible.tolist() == [True, False] and parts.violations() == [late]


def test_blame_from_a_part_where_the_car_did_not_owe_the_junction_response_is_never_cleared():
    """A lateral or road-part violation is not what the stay-out rule excuses: it stays with the car."""
    lateral = {"constraint": "lat-speed-envelope", "vehicle_id": "a"}
    parts = EpisodeParts()
    _part(parts, responsible=[True, False], excusable=[False, False], entered=[False, False],
          stays_out=[False, False], rows=[(0, lateral)])
    _part(parts, responsible=[False, False], excusable=[True, False], entered=[False, False],
          stays_out=[True, False])
    assert parts.responsible.tolist() == [True, False] and parts.violations() == [lateral]
