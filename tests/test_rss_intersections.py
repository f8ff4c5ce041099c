"""Responsibility at junctions with real libsumo vehicles commanded step by step (ad_rss preset).

intersection_tls: fixed program, phase 1 (0-30 s) gives N-S through traffic G, N-S left turns g (permissive) and
W-E red. intersection_priority: W-E major road, S-N minor road with stop signs.
"""
from __future__ import annotations

import subprocess
from collections.abc import Callable

import libsumo
import numpy as np
import pandas as pd
import pytest

from conftest import NETWORKS, audit_commanded, write_scenario
from sumo_rss import load_scenario
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import AuditResult, Auditor, ParamResolver
from sumo_rss.rss.formulas import lon_reach
from sumo_rss.rss.params import RssParams
from sumo_rss.sim.snapshot import WorldSnapshot
from sumo_rss.sumo_home import sumo_tool

DT = 0.1  # [s]


def _spec(tmp_path, network: str, seconds: float):
    data = {"network": network, "duration_s": seconds, "demand": {"vtypes": {"car": {"length": 4.5, "width": 1.8}}}}
    return load_scenario(write_scenario(tmp_path, data))


def _add(vid: str, edges: list[str], lane: int, pos: float, speed: float) -> None:
    libsumo.route.add(f"r_{vid}", edges)
    libsumo.vehicle.add(vid, f"r_{vid}", typeID="car", depart="now", departLane=str(lane), departPos=str(pos),
                        departSpeed=str(speed))
    libsumo.vehicle.setSpeedMode(vid, 0)  # exactly the commanded speed: no lights, no right of way of its own
    libsumo.vehicle.setLaneChangeMode(vid, 0)


def _drive(vid: str, accel: float) -> None:
    if vid in libsumo.vehicle.getIDList():
        libsumo.vehicle.setSpeed(vid, max(0.0, libsumo.vehicle.getSpeed(vid) + accel * DT))


def _audit(spec, setup: Callable[[], None], control: Callable[[float], None]) -> AuditResult:
    return audit_commanded(spec, setup, control, spec.duration_s, "junction")


def _junction_episodes(result: AuditResult, a: str, b: str) -> pd.DataFrame:
    e = result.episodes
    return e[(e.vehicle_a == a) & (e.vehicle_b == b) & e.situation.str.startswith("intersection")]


def test_a_red_light_runner_is_responsible_and_the_green_car_is_not(tmp_path):
    spec = _spec(tmp_path, "intersection_tls", 14.0)

    def setup():  # both ~85 m before the stop line at 13 m/s; W-E is red, N-S green
        _add("green", ["N_in", "S_out"], 0, 205.0, 13.0)
        _add("red", ["W_in", "E_out"], 0, 205.0, 13.0)

    def control(t):
        _drive("red", 0.0)  # runs the red light
        _drive("green", -5.0 if t >= 4.0 else 0.0)  # brakes for the intruder

    result = _audit(spec, setup, control)
    episodes = _junction_episodes(result, "green", "red")
    assert not episodes.empty
    first = episodes.iloc[0]
    assert first.situation == "intersection-priority" and first.conflict_area == "C:1x10"
    assert first.owed_a == "" and first.owed_b == "int:brake-min"  # the red car must yield; the green may go
    assert set(episodes.responsible) == {"b"}
    assert set(result.violations[result.violations.episode_key.isin(episodes.episode_key)].vehicle_id) == {"red"}


def test_b_minor_road_car_that_could_not_stop_is_responsible(tmp_path):
    spec = _spec(tmp_path, "intersection_priority", 12.0)

    def setup():
        _add("major", ["W_in", "J_E"], 0, 215.0, 13.0)  # ~75 m before the junction
        _add("minor", ["S_in", "J_N"], 0, 230.0, 11.0)  # ~60 m before its stop line, does not stop

    def control(t):
        _drive("major", -4.5 if t >= 3.0 else 0.0)
        _drive("minor", 0.0)

    result = _audit(spec, setup, control)
    episodes = _junction_episodes(result, "major", "minor")
    assert not episodes.empty and set(episodes.situation) == {"intersection-yield"}
    assert episodes.iloc[0].owed_b == "int:brake-min" and episodes.iloc[0].owed_a == ""
    assert set(episodes.responsible) == {"b"}


def test_d_crossing_with_disjoint_time_windows_gives_no_episode(tmp_path):
    spec = _spec(tmp_path, "intersection_priority", 12.0)

    def setup():
        _add("major", ["W_in", "J_E"], 0, 20.0, 10.0)  # ~270 m away: arrives after 25 s
        _add("minor", ["S_in", "J_N"], 0, 270.0, 10.0)  # 20 m before the junction: through in 4 s

    def control(t):
        _drive("major", 0.0)
        _drive("minor", 0.0)

    result = _audit(spec, setup, control)
    assert _junction_episodes(result, "major", "minor").empty


def test_e_permissive_left_turn_owes_the_yield_to_oncoming_traffic(tmp_path):
    spec = _spec(tmp_path, "intersection_tls", 12.0)

    def setup():  # phase 1: N straight G, S left g (permissive)
        _add("oncoming", ["N_in", "S_out"], 0, 215.0, 12.0)
        _add("turner", ["S_in", "W_out"], 1, 230.0, 10.0)

    def control(t):
        _drive("oncoming", -4.5 if t >= 3.0 else 0.0)
        _drive("turner", 0.0)  # turns without yielding

    result = _audit(spec, setup, control)
    episodes = _junction_episodes(result, "oncoming", "turner")
    assert not episodes.empty
    first = episodes.iloc[0]
    assert first.situation == "intersection-priority" and first.conflict_area == "C:1x8"
    assert first.owed_a == "" and first.owed_b == "int:brake-min"
    assert set(episodes.responsible) == {"b"}


@pytest.mark.slow
def test_every_collision_in_ten_minutes_of_careless_junction_traffic_joins_an_episode(tmp_path):
    """10 simulated minutes of the shipped intersection_tls demand with drivers who sometimes ignore foes and
    red lights (SUMO's junction-model parameters), so that SUMO reports real junction collisions."""
    import tomllib

    from sumo_rss.batch.runner import run_one

    data = tomllib.loads((NETWORKS.parent / "scenarios" / "intersection_tls.toml").read_text())
    data["duration_s"] = 600.0
    for vtype in data["demand"]["vtypes"].values():
        vtype["car_follow_params"] = {"jmIgnoreFoeProb": 0.3, "jmIgnoreFoeSpeed": 20.0,
                                      "jmIgnoreJunctionFoeProb": 0.3, "jmDriveAfterRedTime": 3.0}
    spec = load_scenario(write_scenario(tmp_path, data, "careless.toml"))
    summary = run_one(spec, tmp_path / "out")
    collisions = pd.read_csv(tmp_path / "out" / "careless" / "0" / "collisions.csv", keep_default_na=False)
    assert summary.collisions == len(collisions) >= 3
    assert (collisions.episode_key != "").all()  # no collision without an episode
    episodes = pd.read_csv(tmp_path / "out" / "careless" / "0" / "episodes.csv", keep_default_na=False)
    joined = episodes.set_index("episode_key").loc[collisions.episode_key]
    assert joined.collision.astype(str).eq("True").all()
    assert (collisions.blamed != "none").mean() >= 0.8  # most contacts have a car that broke its duty


def test_c_ramp_car_forcing_into_the_motorway_lane_is_responsible(tmp_path):
    spec = _spec(tmp_path, "merge", 8.0)

    def setup():  # acceleration lane (lane 0 of mw_merge, 270 m, ends) beside motorway lane 1
        _add("ramp", ["mw_merge", "mw_out"], 0, 50.0, 20.0)
        _add("motorway", ["mw_merge", "mw_out"], 1, 35.0, 22.0)  # its front bumper 10.5 m behind the ramp car

    state = {"forced": None}

    def control(t):
        if t >= 0.95 and state["forced"] is None and "ramp" in libsumo.vehicle.getIDList():
            libsumo.vehicle.changeLane("ramp", 1, 3.0)  # forces in, 3 s manoeuvre
            state["forced"] = t
        _drive("ramp", 0.0)
        forced = state["forced"]
        _drive("motorway", -4.5 if forced is not None and t >= forced + 1.0 else 0.0)  # keeps its lane, brakes

    result = _audit(spec, setup, control)
    episodes = result.episodes[(result.episodes.vehicle_a == "motorway") & (result.episodes.vehicle_b == "ramp")]
    assert not episodes.empty
    first = episodes.iloc[0]
    assert first.situation == "merge" and first.trigger == "lat"
    assert first.responsible == "b"
    assert set(result.violations.vehicle_id) == {"ramp"}


@pytest.mark.parametrize("routes", [True, False])
def test_signal_rule_red_light_and_avoidable_yellow_light_entries(tmp_path, routes):
    """N-S through traffic turns yellow at 30 s (red at 33 s). At 8 m/s a car needs 8 m to stop at b_min = 4:
    'early' is 20 m before the line at 30 s (could stop, crosses on yellow: violation), 'late' 5 m (could not:
    no violation); 'runner' crosses W-E, red all along (violation). Without the routes (an FCD file audited
    without its route file) the link a car takes is the one whose stop line it crosses: the same verdicts."""
    network = RoadNetwork.from_file(NETWORKS / "intersection_tls" / "intersection_tls.net.xml")
    to_line = float(network.lane_length[network.lane_indices(["N_in_0"])[0]])
    spec = _spec(tmp_path, "intersection_tls", 36.0)

    def setup():
        _add("late", ["N_in", "S_out"], 0, to_line - 5.0 - 8.0 * 30.0, 8.0)
        _add("early", ["N_in", "S_out"], 0, to_line - 20.0 - 8.0 * 30.0, 8.0)

    def control(t):
        if abs(t - 27.0) < 1e-6:
            _add("runner", ["W_in", "E_out"], 0, to_line - 40.0, 10.0)  # crosses at ~31 s, W-E red until 46 s
        for vid in ("late", "early", "runner"):
            _drive(vid, 0.0)

    result = audit_commanded(spec, setup, control, spec.duration_s, "junction", routes=routes)
    signal = result.violations[result.violations.role == "signal"]
    assert dict(zip(signal.vehicle_id, signal.constraint)) == {"early": "signal-yellow-light",
                                                               "runner": "signal-red-light"}
    assert signal.set_index("vehicle_id").worst_actual.to_dict() == pytest.approx({"early": 8.0, "runner": 10.0})
    assert (signal.episode_key == "").all()


@pytest.mark.parametrize("case, expected", [
    ("green onset", []),
    ("red onset", [("signal-red-light", 33.0)]),
    ("red onset, too fast to stop at yellow", [("signal-red-light", 33.0)]),
    ("could stop when it turned yellow", [("signal-yellow-light", pytest.approx(31.2))]),
    ("could not stop when it turned yellow", []),
    ("red-yellow", [("signal-red-light", pytest.approx(3.2))]),
])
def test_a_crossing_is_judged_by_the_signal_state_it_was_made_under(tmp_path, case, expected):
    """A snapshot's signal states are those SUMO moved its cars under to get there (stamped, as SUMO's outputs are,
    with the step's start time): the light W-E turns G at 46.0 and N-S y at 30.0, r at 33.0 (intersection_tls).
    A car at a constant speed that is 0.5 m before its line at 45.9 crosses under G: no violation (it was judged
    by the state before, red). One 0.5 m before its line at 32.9 crosses under r: red light (it was yellow). At
    26 m/s it needs 84.5 m to stop at b_min and was 78.5 m away when the light turned yellow: red light all the
    same. At 10 m/s (12.5 m to stop) a car 12.9 m before its line when the light turned yellow (snapshot 29.9)
    could stop: yellow light (the decision was taken at 30.0, 11.9 m before: none); 11.9 m before: none. A car
    crossing under 'u' (red-yellow, closed in SUMO): red light."""
    net = RoadNetwork.from_file(NETWORKS / "intersection_tls" / "intersection_tls.net.xml")
    to_n, to_w = (float(net.lane_length[net.lane_indices([lane])[0]]) for lane in ("N_in_0", "W_in_0"))
    # A car added at control time t0 (before the step from t0) at constant speed v is at pos + v·(t − t0 − 0.1)
    # in the snapshot stamped t.
    cars = {"green onset": (40.0, ["W_in", "E_out"], to_w - 0.5 - 10.0 * 5.8, 10.0),
            "red onset": (25.0, ["N_in", "S_out"], to_n - 0.5 - 10.0 * 7.8, 10.0),
            "red onset, too fast to stop at yellow": (25.0, ["N_in", "S_out"], to_n - 0.5 - 26.0 * 7.8, 26.0),
            "could stop when it turned yellow": (20.0, ["N_in", "S_out"], to_n - 12.9 - 10.0 * 9.8, 10.0),
            "could not stop when it turned yellow": (20.0, ["N_in", "S_out"], to_n - 11.9 - 10.0 * 9.8, 10.0),
            "red-yellow": (0.0, ["W_in", "E_out"], to_w - 30.0, 10.0)}
    t0, route, pos, speed = cars[case]
    spec = _spec(tmp_path, "intersection_tls", 47.0 if case == "green onset" else 35.0)

    def control(t):
        if abs(t - t0) < 1e-6:
            _add("car", route, 0, pos, speed)
        _drive("car", 0.0)
        if case == "red-yellow":
            state = list(libsumo.trafficlight.getRedYellowGreenState("C"))
            state[10] = "u"  # W_in straight
            libsumo.trafficlight.setRedYellowGreenState("C", "".join(state))

    result = audit_commanded(spec, lambda: None, control, spec.duration_s, "signal")
    signal = result.violations[result.violations.role == "signal"]
    assert list(zip(signal.constraint, signal.t_start_s)) == expected


def test_a_crossing_within_one_step_past_the_junction_lane_is_judged(tmp_path):
    """With 1 s steps a car turning right on red (W_in -> S_out, a 9 m junction lane) at 12 m/s goes from its
    approach lane (0.5 m before the line at 5 s) to the exit edge in one step: a red light (it was never seen
    on the junction lane, and went unjudged)."""
    net = RoadNetwork.from_file(NETWORKS / "intersection_tls" / "intersection_tls.net.xml")
    to_w = float(net.lane_length[net.lane_indices(["W_in_0"])[0]])
    spec = load_scenario(write_scenario(tmp_path, {"network": "intersection_tls", "duration_s": 8.0, "step_s": 1.0,
                                                   "demand": {"vtypes": {"car": {"length": 4.5, "width": 1.8}}}}))

    def control(t):
        if "turner" in libsumo.vehicle.getIDList():
            libsumo.vehicle.setSpeed("turner", 12.0)

    result = audit_commanded(spec, lambda: _add("turner", ["W_in", "S_out"], 0, to_w - 60.5, 12.0), control,
                             spec.duration_s, "skip")
    signal = result.violations[result.violations.role == "signal"]
    assert list(zip(signal.vehicle_id, signal.constraint, signal.t_start_s)) == [("turner", "signal-red-light", 6.0)]


def test_the_area_a_pair_becomes_dangerous_in_decides_who_yields(tmp_path):
    """An offline audit without routes: every link of a car's lane is a possible path, and e (E_in, westbound,
    13.89 m/s) and w (W_in, creeping at 0.01 m/s before its line: a standing car would be held, able to stop
    anywhere short of the areas) meet in five conflict areas. At 0 s every area is safe by
    'able to stop'; the kept (most critical) one is J:4x11 (e straight x w left: w yields, margin 0.2 m), while in
    J:5x10 (e left x w straight: e yields) e's margin is 0.5 m (D = 13.89 + 1.75 + 17.39²/8 = 53.44 m, +λ 0.2 m).
    At 0.1 s e is 1.39 m nearer: J:5x10 is dangerous (margin -0.89 m), and e, which had to yield there, owes
    braking; it keeps 13.89 m/s and is responsible from t_b + ρ + 0.1 s. The duties used to come from J:4x11
    (w yields: w owed braking, nobody responsible). With w's route known (J:5x10 alone) the audit is the same."""
    network = RoadNetwork.from_file(NETWORKS / "intersection_priority" / "intersection_priority.net.xml")
    p, v, creep = RssParams(), 13.89, 0.01
    # Bumpers placed so that w's margin in J:4x11 is 0.2 m and e's in J:5x10 0.5 m (each area begins 0.2 m into
    # the car's link, the links begin 7.2 m from the junction's centre).
    d_w = float(lon_reach(creep, p, p.lon_brake_min))
    d_e = float(lon_reach(v, p, p.lon_brake_min)) + 0.3

    def snapshot(t: float, routes) -> WorldSnapshot:
        ahead, behind = d_e - v * t, d_w - creep * t
        return WorldSnapshot(
            time=t, ids=np.array(["e", "w"]), x=np.array([7.2 + ahead, -7.2 - behind]), y=np.array([1.6, -1.6]),
            heading=np.array([np.pi, 0.0]), speed=np.array([v, creep]), accel=np.zeros(2), lat_speed=np.zeros(2),
            length=np.full(2, 5.0), width=np.full(2, 1.8), lane_id=np.array(["E_in_0", "W_in_0"]),
            edge_id=np.array(["E_in", "W_in"]), lane_index=np.zeros(2, int),
            lane_pos=np.array([292.8 - ahead, 292.8 - behind]), lat_pos=np.zeros(2),
            vclass=np.array(["background"] * 2), vtype=np.array(["car"] * 2), signals=np.zeros(2, int),
            route_index=np.zeros(2, int), route_edges=routes)

    for routes in (None, ((), ("W_in", "J_E"))):
        auditor = Auditor(network, ParamResolver("ad_rss"), signal_rule=False)
        kept = [auditor.observe(snapshot(round(0.1 * k, 2), routes)).area[-1] for k in range(17)]
        result = auditor.finish()
        assert kept[:2] == (["J:4x11", "J:5x10"] if routes is None else ["J:5x10", "J:5x10"])
        (episode,) = result.episodes.itertuples()
        assert (episode.conflict_area, episode.t_b_s, episode.trigger, episode.owed_a, episode.owed_b,
                episode.responsible) == ("J:5x10", 0.1, "able-to-stop", "int:brake-min", "", "a")
        (violation,) = result.violations.itertuples()
        assert (violation.vehicle_id, violation.constraint, violation.bound, violation.t_start_s) == \
            ("e", "lon-brake-after-response-time", -4.0, 1.2)


ROUNDABOUT_NODES = """<nodes>
 <node id="r0" x="20" y="0" type="priority"/><node id="r1" x="0" y="20" type="priority"/>
 <node id="r2" x="-20" y="0" type="priority"/><node id="r3" x="0" y="-20" type="priority"/>
 <node id="E" x="200" y="0"/><node id="N" x="0" y="200"/><node id="W" x="-200" y="0"/><node id="S" x="0" y="-200"/>
</nodes>"""
ROUNDABOUT_EDGES = "<edges>" + "".join(
    f'<edge id="R{a}{b}" from="r{a}" to="r{b}" numLanes="1" speed="8" shape="{shape}"/>'
    for a, b, shape in ((0, 1, "20,0 14.1,14.1 0,20"), (1, 2, "0,20 -14.1,14.1 -20,0"),
                        (2, 3, "-20,0 -14.1,-14.1 0,-20"), (3, 0, "0,-20 14.1,-14.1 20,0"))) + "".join(
    f'<edge id="{arm}in" from="{arm}" to="r{k}" numLanes="1"/><edge id="{arm}out" from="r{k}" to="{arm}" numLanes="1"/>'
    for k, arm in enumerate("ENWS")) + "</edges>"


def test_a_car_two_junctions_away_on_a_roundabout_is_in_its_conflict_before_the_edge_leading_there(tmp_path):
    """A roundabout's edges are ~22 m: a circulating car took part in the conflict at the next junction only once
    on the edge leading there. An entering car that had long been unable to stop was then first seen already in
    danger, and the circulating car (which has priority) was made to brake and blamed. Its route now carries it
    into the conflicts at the junctions after the next within the horizon: the entering car, which must yield,
    owes the braking from when it could no longer stop."""
    (tmp_path / "r.nod.xml").write_text(ROUNDABOUT_NODES)
    (tmp_path / "r.edg.xml").write_text(ROUNDABOUT_EDGES)
    subprocess.run([str(sumo_tool("netconvert")), "-n", str(tmp_path / "r.nod.xml"), "-e", str(tmp_path / "r.edg.xml"),
                    "--roundabouts.guess", "--no-turnarounds", "-o", str(tmp_path / "rb.net.xml")],
                   check=True, capture_output=True)
    data = {"network": str(tmp_path / "rb.net.xml"), "duration_s": 16.0,
            "demand": {"vtypes": {"car": {"length": 4.5, "width": 1.8}}}}
    spec = load_scenario(write_scenario(tmp_path, data))
    speeds = {"circ": 5.5, "ent": 16.5}  # the entering car does not slow down

    def control(t):
        if abs(t - 3.5) < 1e-6:
            _add("ent", ["Ein", "R01", "Nout"], 0, 5.0, speeds["ent"])
        for vid, speed in speeds.items():
            if vid in libsumo.vehicle.getIDList():
                libsumo.vehicle.setSpeed(vid, speed)

    result = _audit(spec, lambda: _add("circ", ["R12", "R23", "R30", "R01", "Nout"], 0, 0.0, speeds["circ"]), control)
    episodes = _junction_episodes(result, "circ", "ent")
    assert episodes[["conflict_area", "trigger", "owed_a", "owed_b", "responsible"]].values.tolist() == \
        [["r0:0x2", "able-to-stop", "", "int:brake-min", "b"]]
    assert episodes.t_b_s.iloc[0] == pytest.approx(10.0)  # first seen (already dangerous) at 11.9 s before
