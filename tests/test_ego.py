"""The ego hook: a planner's trajectory is executed exactly by libsumo (moveToXY + setPreviousSpeed)."""
from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import SCENARIOS, write_scenario
from sumo_rss import SessionError, Trajectory, load_scenario
from sumo_rss.batch.runner import param_resolver
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info
from sumo_rss.sim.session import Session
from sumo_rss.trajectory import TrajectoryState

LANE_Y = -5.25  # centre of highway lane 1 (lanes 3.5 m wide, the edge's left border at y = 0) [m]
SPEED = 25.0  # [m/s]


def _lane_keeping_plan(session: Session, duration: float) -> tuple[Trajectory, float, float]:
    """Steps until the ego departs; then a plan at SPEED along lane 1 for ``duration`` s, its start time and x."""
    while not session.ego_on_road:
        session.step()
    t0 = session.time
    x0 = float(session.snapshot.x[session.snapshot.index_of("ego")])
    times = t0 + np.arange(0.0, duration, session.spec.step_s)
    plan = Trajectory(times, x0 + SPEED * (times - t0), np.full_like(times, LANE_Y), np.zeros_like(times),
                      np.full_like(times, SPEED), np.zeros_like(times))
    return plan, t0, x0


def test_constant_speed_lane_keeping_trajectory_is_followed(valid_scenario, tmp_path):
    valid_scenario["demand"]["flows"][0]["veh_per_hour"] = 600
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with Session(spec) as session:
        plan, t0, x0 = _lane_keeping_plan(session, 12.0)
        rows = []
        for _ in range(100):  # 10 s: 250 m along hw0 (900 m long)
            session.drive_ego(plan)
            snap = session.step()
            rows.append((snap.time, snap.x[snap.index_of("ego")], snap.y[snap.index_of("ego")],
                         snap.speed[snap.index_of("ego")], snap.heading[snap.index_of("ego")],
                         snap.lane_id[snap.index_of("ego")], snap.lat_pos[snap.index_of("ego")]))
    t, x, y, v, heading, lane, lat = map(np.array, zip(*rows))
    np.testing.assert_allclose(x, x0 + SPEED * (t - t0), atol=1e-6)
    np.testing.assert_allclose(y, LANE_Y, atol=1e-6)
    np.testing.assert_allclose(v, SPEED, atol=1e-9)
    np.testing.assert_allclose(heading, 0.0, atol=1e-9)
    np.testing.assert_allclose(lat, 0.0, atol=1e-6)
    assert set(lane) == {"hw0_1"}


def test_a_placed_ego_just_past_a_lane_end_has_no_lateral_speed(valid_scenario, tmp_path):
    """SUMO keeps a bumper placed a few mm past a lane's end on that lane and reports the overshoot as its
    lateral offset: 8.6 mm gave a phantom 0.086 m/s (twice: carried onto the next edge) that the audit judged."""
    valid_scenario["demand"]["flows"][0]["veh_per_hour"] = 600
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    lane_end = 899.87  # [m] x of the end of hw0_1
    with Session(spec) as session:
        while not session.ego_on_road:
            session.step()
        t_hit = session.time + 2.0
        times = session.time + np.arange(0.0, 4.0, session.spec.step_s)
        plan = Trajectory(times, lane_end + 0.0086 + SPEED * (times - t_hit), np.full_like(times, LANE_Y),
                          np.zeros_like(times), np.full_like(times, SPEED), np.zeros_like(times))
        rows = []
        for _ in range(30):
            session.drive_ego(plan)
            snap = session.step()
            k = snap.index_of("ego")
            rows.append((snap.time, snap.lane_id[k], snap.lane_pos[k], snap.lat_speed[k]))
    at_end = [r for r in rows if abs(r[0] - t_hit) < 1e-6]
    assert at_end and at_end[0][1] == "hw0_1" and at_end[0][2] == pytest.approx(lane_end, abs=2e-3)  # the SUMO case
    # Up to the step onto hw1, which carries the last speed over; from then on hw1 bends away from the straight
    # plan (its lateral speed there is real).
    straight = [r for r in rows if r[0] <= t_hit + 0.1 + 1e-6]
    assert straight[-1][1] == "hw1_1"
    np.testing.assert_allclose([r[3] for r in straight], 0.0, atol=1e-6)


def test_drive_ego_before_the_ego_departs_is_refused(valid_scenario, tmp_path):
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))  # the ego departs at t = 1 s
    plan = Trajectory(np.array([0.0, 1.0]), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2))
    with Session(spec) as session:
        session.step()
        with pytest.raises(SessionError, match="'ego' is not on the road at t = 0.00 s"):
            session.drive_ego(plan)


def test_trajectory_interpolates_and_rejects_bad_input():
    plan = Trajectory(np.array([0.0, 2.0]), np.array([0.0, 10.0]), np.zeros(2), np.array([3.0, -3.0]),
                      np.array([5.0, 5.0]), np.zeros(2))
    state = plan.state_at(1.0)
    assert state.x == pytest.approx(5.0)
    assert abs(state.heading) == pytest.approx(np.pi, abs=0.15)  # through ±π, not through 0 (unwrapped)
    with pytest.raises(ValueError, match="outside the trajectory"):
        plan.state_at(2.5)
    with pytest.raises(ValueError, match="strictly increasing"):
        Trajectory(np.array([0.0, 0.0]), *(np.zeros(2) for _ in range(5)))


def test_the_ego_arrives_at_the_end_of_its_route(valid_scenario, tmp_path):
    """A vehicle placed by moveToXY never arrives on its own: at the end of its route's last edge the session hands
    the ego back to SUMO, which lets it arrive there (hw0 ends at x = 900 m; hw1 goes on, off the ego's route)."""
    valid_scenario["demand"]["flows"][0]["veh_per_hour"] = 600
    valid_scenario["ego"]["route"] = ["hw0"]
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with Session(spec) as session:
        plan, t0, x0 = _lane_keeping_plan(session, 60.0)
        edges, last_x = set(), x0
        while session.ego_on_road and session.time < t0 + 50.0:
            session.drive_ego(plan)
            snap = session.step()
            if session.ego_on_road:
                edges.add(str(snap.edge_id[snap.index_of("ego")]))
                last_x = float(snap.x[snap.index_of("ego")])
    assert not session.ego_on_road  # it arrived, ~ (900 - 50) / 25 = 34 s after departing
    assert session.time < t0 + 36.0
    assert edges == {"hw0"} and last_x > 870.0


def test_the_fcd_of_a_placed_ego_gives_the_online_audit_offline(valid_scenario, tmp_path):
    """SUMO writes acceleration and speedLat 0 for a vehicle placed by moveToXY; the session writes the values its
    snapshots derived, so the offline audit of the run's FCD equals the online one (a lane change while
    speeding up, in traffic)."""
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    network = RoadNetwork.from_file(spec.net_file)
    online = Auditor(network, param_resolver(spec), "placed")
    with Session(spec, tmp_path / "run", fcd=True) as session:
        while not session.ego_on_road:
            online.observe(session.step())
        t0, x0 = session.time, float(session.snapshot.x[session.snapshot.index_of("ego")])
        times = t0 + np.arange(0.0, 12.0, spec.step_s)
        tau = times - t0
        speed = 20.0 + 0.5 * tau  # speeding up at 0.5 m/s², to the left lane (3.5 m) between 2 s and 6 s
        lateral = 3.5 * np.clip((tau - 2.0) / 4.0, 0.0, 1.0)
        plan = Trajectory(times, x0 + 20.0 * tau + 0.25 * tau ** 2, LANE_Y + lateral, np.zeros_like(times), speed,
                          np.full_like(times, 0.5))
        for _ in range(110):
            session.drive_ego(plan)
            online.observe(session.step())
    changing = [row for row in ET.parse(tmp_path / "run" / "fcd.xml").getroot().iter("vehicle")
                      if row.get("id") == "ego" and float(row.get("speedLat")) > 0.8]
    assert len(changing) >= 30 and all(float(r.get("acceleration")) == pytest.approx(0.5, abs=1e-6)
                                             for r in changing)  # SUMO wrote 0 for both
    on = online.finish()
    off = audit_fcd(tmp_path / "run" / "fcd.xml", network, param_resolver(spec),
                    vehicles=read_vehicle_info(tmp_path / "run" / "routes.rou.xml", spec.net_file), run_id="placed")
    assert (on.episodes.class_a == "ego").any() or (on.episodes.class_b == "ego").any()
    for name in ("episodes", "violations"):
        assert getattr(off, name).to_csv(index=False) == getattr(on, name).to_csv(index=False), name
    on.to_csv(tmp_path / "written")  # the CSVs and the parameters they were judged with
    assert json.loads((tmp_path / "written" / "rss_params.json").read_text()) == on.params


def test_a_placed_ego_that_stands_longer_than_the_teleport_time_is_not_teleported(valid_scenario, tmp_path):
    """time_to_teleport_s = 3 s; the ego departs standing and is placed where it stands for 10 s. SUMO counts its
    waiting time like anyone's and took it off the road after 3 s, putting it back at 33 m/s."""
    valid_scenario["sumo"] = {"time_to_teleport_s": 3.0}
    valid_scenario["duration_s"] = 12.0
    valid_scenario["ego"].update(depart_s=0.0, depart_speed=0.0, depart_pos_m=300.0)
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with Session(spec) as session:
        while not session.ego_on_road:
            session.step()
        k = session.snapshot.index_of("ego")
        x, y, heading = (float(a[k]) for a in (session.snapshot.x, session.snapshot.y, session.snapshot.heading))
        speeds = []
        for _ in range(100):
            session.place_ego(TrajectoryState(x, y, heading, 0.0, 0.0))
            snapshot = session.step()
            speeds.append(float(snapshot.speed[snapshot.index_of("ego")]))
        assert session.teleports == 0
    assert max(speeds) == 0.0


@pytest.mark.parametrize("command, says", [
    ((0.0, -5.25, 0.0, 20.0, 0.0), "expected a sumo_rss.trajectory.TrajectoryState, got tuple"),
    (TrajectoryState(float("nan"), -5.25, 0.0, 20.0, 0.0), "expected finite x, y, heading, accel and a speed"),
    (TrajectoryState(50.0, -5.25, 0.0, -1.0, 0.0), "a speed >= 0 m/s"),  # -1 would hand the speed back to SUMO
])
def test_a_malformed_ego_command_is_refused_naming_the_time(valid_scenario, tmp_path, command, says):
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with Session(spec) as session:
        while not session.ego_on_road:
            session.step()
        with pytest.raises(SessionError, match=f"the ego command at t = {session.time:.2f} s: .*{re.escape(says)}"):
            session.place_ego(command)


def test_a_controller_without_a_command_method_is_refused_before_the_run(valid_scenario, tmp_path):
    from sumo_rss.batch.runner import run_one

    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with pytest.raises(TypeError, match=r"controller: expected an object with a method command\(snapshot, auditor\)"):
        run_one(spec, tmp_path / "out", controller=object())
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("summary.json"))


def test_an_own_loop_passes_the_sessions_new_collisions_to_the_audit():
    """docs/extending.md's own loop on highway_dense: the ego driven at 40 m/s into the car ahead in its lane;
    each contact reaches the audit once (SUMO reports it every step it lasts) and closes the pair's episode."""
    spec = load_scenario(SCENARIOS / "highway_dense.toml").with_overrides(duration_s=40.0)
    auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec), signal_rule=spec.rss.signal_rule)
    with Session(spec) as session:
        while not session.finished:
            if session.ego_on_road:
                snap = session.snapshot
                k = snap.index_of("ego")
                heading, step = float(snap.heading[k]), 40.0 * spec.step_s
                session.place_ego(TrajectoryState(float(snap.x[k]) + step * np.cos(heading),
                                                  float(snap.y[k]) + step * np.sin(heading), heading, 40.0, 0.0))
            auditor.observe(session.step(), session.new_collisions)
    result = auditor.finish()
    ego_hits = [c for c in session.collisions if "ego" in (c.collider, c.victim)]
    assert ego_hits and len(result.collisions) == len(session.collisions)
    closed = result.episodes[result.episodes.collision]
    assert {(c.collider, c.victim) for c in ego_hits} <= set(zip(closed.collider, closed.victim))


def test_an_ego_placed_off_every_lane_leaving_the_road_is_named(valid_scenario, tmp_path):
    """A controller that placed the ego away from the road (an example that did not steer, in a curve) lost it
    silently: it left the snapshots, was neither driven nor audited any more, and the run still said ok."""
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with Session(spec) as session:
        while not session.ego_on_road:
            session.step()
        snap = session.snapshot
        k = snap.index_of(spec.ego.id)
        session.place_ego(TrajectoryState(float(snap.x[k]), float(snap.y[k]) + 200.0, float(snap.heading[k]),
                                          float(snap.speed[k]), 0.0))
        with pytest.warns(UserWarning, match=rf"the ego '{spec.ego.id}' left the road at t = "
                                             rf"{session.time + spec.step_s:.2f} s without arriving"):
            session.step()
    assert not session.ego_on_road
