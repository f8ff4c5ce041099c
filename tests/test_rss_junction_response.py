"""Who owes the junction response after an all-red phase, and when a yielding car has given it.

tests/data/drt_fragment.net.xml: the signalised junction cluster_1560224191_... of eclipse-sumo's DRT net (OSM).
A waits at its stop line on 71028777#2 (lane 1, straight on: link 1); B comes along 142575692#0 -> #2 straight on
(link 5); their paths cross 7.0 m (A) and 9.0 m (B) past the stop lines, and the junction's static right of way
gives B priority. The signal shows B green, yellow from 3 s, all red from 6 s, A green from 8 s (the real program's
phases 1, 2, 4 and 5, set on time). At 8 s B is 43 m before its line at 14.7 m/s and cannot stop before the area
under ad_rss's assumptions (57.8 m: a_acc during ρ, then b_min); it brakes at 2.5 m/s² and stops at its line, and
A moves off at 2 m/s².
"""
from __future__ import annotations

import libsumo
import pytest

from sumo_runs import CAR, DATA, hold_speed, run_sumo

NET = DATA / "drt_fragment.net.xml"
SIGNAL = "cluster_1560224191_1560224195_2697454310_443598395"
PHASES = ((0.0, "rrrrgGggrrrrgGggrrrr"), (3.0, "rrrryyyyrrrryyyyrrrr"), (6.0, "r" * 20), (8.0, "gGggrrrrgGggrrrrrGrG"))
GREEN_A = 8.0  # [s]


@pytest.fixture(scope="module")
def all_red(tmp_path_factory):
    folder = tmp_path_factory.mktemp("all_red")
    speeds = {"a": 0.0, "b": 14.7}

    def control(time: float) -> None:
        for start, state in PHASES:
            if abs(time - start) < 1e-6:
                libsumo.trafficlight.setRedYellowGreenState(SIGNAL, state)
        if time >= GREEN_A - 1e-6:
            speeds["a"] += 2.0 * 0.1
            speeds["b"] = max(0.0, speeds["b"] - 2.5 * 0.1)
        for vid, speed in speeds.items():
            if vid in libsumo.vehicle.getIDList():
                hold_speed(vid, speed)

    # B departs 3 s (at 14.7 m/s) + 43 m before its stop line; the route file gives the audit both routes.
    routes = CAR + '<route id="ra" edges="71028777#2 71028774#0"/><route id="rb" edges="142575692#0 142575692#2 ' \
        '142575692#3"/><vehicle id="a" type="car" route="ra" depart="0" departLane="1" departPos="95.8" ' \
        'departSpeed="0"/><vehicle id="b" type="car" route="rb" depart="5" departLane="1" departPos="8.7" ' \
        'departSpeed="14.7"/>'
    return run_sumo(NET, folder, routes, 16.0, lambda: None, control)


def _episodes(result):
    e = result.episodes
    return e[(e.vehicle_a == "a") & (e.vehicle_b == "b") & (e.situation == "intersection-priority")]


def test_after_the_all_red_step_the_car_approaching_its_red_owes_the_response(all_red):
    """Verdict: B, approaching its red, must yield; A, moving off on green, may go. At the all-red step the
    junction's static right of way made A the car that yields (and B the one with priority), and the duties came
    from there: A, accelerating away on its green, was blamed, and B owed nothing."""
    episodes = _episodes(all_red.audit())
    assert len(episodes) == 1
    first = episodes.iloc[0]
    assert first.t_b_s == pytest.approx(GREEN_A, abs=0.15) and first.trigger == "able-to-stop"
    assert (first.owed_a, first.owed_b) == ("", "int:brake-min")
    assert first.responsible == "none"  # A owes nothing; B stops before the area (next test)


def test_a_yielding_car_that_stops_at_its_line_has_complied(all_red):
    """B brakes at 2.5 m/s² (not at b_min = 4) and stands at its stop line, 9 m before the conflict area: it gave
    the response the intersection rule asks for, not entering the area. ad_rss's reading (brake at b_min until
    stopped) is kept as an option: under it B is responsible."""
    assert _episodes(all_red.audit()).iloc[0].responsible == "none"
    strict = all_red.audit(junction_brake_min=True)
    assert _episodes(strict).iloc[0].responsible == "b"
    broken = strict.violations[strict.violations.vehicle_id == "b"]
    assert set(broken.constraint) == {"lon-brake-after-response-time"}
    assert broken.worst_actual.max() == pytest.approx(-2.5, abs=0.01)
