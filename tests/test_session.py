"""Real libsumo co-simulations of the shipped scenarios: traffic flows, determinism, continuous lateral
motion, collision bookkeeping and the session's lifecycle rules."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import asdict, replace

import numpy as np
import pytest
import sumolib

from conftest import NETWORKS, SCENARIOS, SHIPPED_SCENARIOS, write_scenario
from sumo_rss import SessionError, load_scenario
from sumo_rss.sim.demand import write_route_file
from sumo_rss.sim.session import Session, as_written, sumo_arguments


def _spec(name: str, **overrides):
    return load_scenario(SCENARIOS / f"{name}.toml").with_overrides(**overrides)


def _run(spec, seconds: float) -> tuple[Session, list]:
    snapshots = []
    with Session(spec) as session:
        while session.steps < round(seconds / spec.step_s):
            snapshots.append(session.step())
    return session, snapshots


def test_every_shipped_scenario_is_tested():
    assert SHIPPED_SCENARIOS == ["highway_dense", "highway_exit", "highway_overtake", "highway_sparse",
                                 "highway_truck_cut_in", "intersection_occluded", "intersection_priority",
                                 "intersection_tls", "intersection_tls_peds", "merge_onramp"]


# Staged cases of a few vehicles and no ego, each tested in its own file (test_rss_occlusion_highway.py).
STAGED = ("highway_truck_cut_in",)


@pytest.mark.parametrize("name", [n for n in SHIPPED_SCENARIOS if n not in STAGED])
def test_scenario_runs_60_s_with_traffic_flowing(name):
    spec = _spec(name)
    session, snaps = _run(spec, 60.0)
    assert session.steps == 600 and snaps[0].time == 0.0 and snaps[-1].time == pytest.approx(59.9)
    # Evenly spaced flows give their count within SUMO's insertion delays; random ones (a probability per second)
    # a binomial count, allowed three standard deviations below its mean.
    def active_s(flow) -> float:  # [s] of the first 60 s in which the flow inserts
        return max(0.0, min(60.0, flow.end_s if flow.end_s is not None else 60.0) - flow.begin_s)

    even = sum(f.veh_per_hour * active_s(f) for f in spec.demand.flows if f.veh_per_hour) / 3600.0
    arrivals = sum(f.probability * active_s(f) for f in spec.demand.flows if f.probability)  # expected random ones
    expected = 0.8 * even + arrivals - 3.0 * np.sqrt(arrivals)
    background = session.vehicles_inserted - 1  # the ego departs within the first 30 s
    assert background >= expected, (background, expected)
    assert any(spec.ego.id in s.ids for s in snaps)
    last = snaps[-1]
    assert len(last) >= 10 and np.mean(last.speed) > 3.0  # moving traffic, not a jam
    assert len(set(last.ids)) == len(last)
    assert all(lane.rsplit("_", 1)[0] == edge for lane, edge in zip(last.lane_id, last.edge_id))
    lengths = {vt.id: vt.length for vt in spec.demand.vtypes}
    background_rows = last.vclass == "background"
    assert np.array_equal(last.length[background_rows], [lengths[t] for t in last.vtype[background_rows]])
    assert session.collisions == [] and session.teleports == 0


def test_highway_dense_background_traffic_never_collides():
    spec = _spec("highway_dense")
    session, snaps = _run(spec, spec.duration_s)
    assert max(len(s) for s in snaps) >= 150
    assert session.collisions == [] and session.teleports == 0


def _summary(session: Session) -> dict:
    return {k: v for k, v in vars(session).items()
            if k in ("steps", "vehicles_inserted", "peak_vehicles", "teleports")} | \
        {"collisions": [asdict(c) for c in session.collisions]}


def test_same_seed_gives_identical_snapshots_and_another_seed_differs():
    first, a = _run(_spec("merge_onramp", seed=4), 40.0)
    second, b = _run(_spec("merge_onramp", seed=4), 40.0)
    third, c = _run(_spec("merge_onramp", seed=5), 40.0)
    assert len(a) == len(b) == 400
    assert all(x.equals(y) for x, y in zip(a, b))
    assert _summary(first) == _summary(second)
    assert not all(x.equals(y) for x, y in zip(a, c))


def _lane_centre_offsets(network: str) -> dict[str, float]:
    """Lateral offset [m] of each lane's centre from its edge's right border."""
    net = sumolib.net.readNet(str(NETWORKS / network / f"{network}.net.xml"))
    offsets = {}
    for edge in net.getEdges():
        right = 0.0
        for lane in edge.getLanes():
            offsets[lane.getID()] = right + lane.getWidth() / 2.0
            right += lane.getWidth()
    return offsets


@pytest.mark.parametrize("name", [n for n in SHIPPED_SCENARIOS if n not in STAGED])
def test_lateral_position_is_continuous_through_lane_changes(name):
    spec = _spec(name)
    offsets = _lane_centre_offsets(spec.network)
    _, snaps = _run(spec, 120.0)
    previous: dict[str, tuple[str, int, float]] = {}
    max_jump, lane_changes, lat_speeds = 0.0, 0, []
    for snap in snaps:
        for vid, edge, lane, idx, lat, vlat in zip(snap.ids, snap.edge_id, snap.lane_id, snap.lane_index,
                                                   snap.lat_pos, snap.lat_speed):
            if edge.startswith(":"):  # junction-internal lanes have their own frame
                previous.pop(vid, None)
                continue
            lateral = offsets[lane] + lat
            if vid in previous and previous[vid][0] == edge:
                max_jump = max(max_jump, abs(lateral - previous[vid][2]))
                if previous[vid][1] != idx:
                    lane_changes += 1
                    lat_speeds.append(abs(vlat))
            previous[vid] = (edge, idx, lateral)
    assert max_jump <= 0.5
    if name not in ("intersection_priority", "intersection_occluded"):  # one lane per direction: no lane changes
        assert lane_changes >= 10  # the check above saw real lane changes...
        assert np.median(lat_speeds) > 0.5  # ...and SUMO reports the lateral speed of the manoeuvre [m/s]


def test_collisions_are_recorded_once_per_contact(valid_scenario, tmp_path):
    import libsumo

    from conftest import write_scenario
    from sumo_rss.trajectory import Trajectory

    # One car at a steady 10 m/s in lane 1 of the highway. The ego is placed with its front bumper 2 m behind
    # the car's front bumper (overlapping its 4.5 m body) for 1 s, then 20 m behind it for 1 s, then
    # overlapping again for 1 s: two contacts, each lasting many steps.
    valid_scenario["demand"]["vtypes"]["car"].update(max_speed=10.0, speed_dev=0.0, sigma=0.0)
    valid_scenario["demand"]["flows"] = [{"id": "slow", "route": ["hw0", "hw1", "hw2"], "veh_per_hour": 3600,
                                          "begin_s": 0.0, "end_s": 1.0, "depart_lane": 1, "depart_speed": 10.0}]
    valid_scenario["ego"].update(depart_s=2.0, depart_pos_m=5.0, depart_speed=10.0)
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    lane_y = -5.25  # centre of hw0 lane 1: lanes are 3.5 m wide, the edge's left border is y = 0
    colliding_steps = 0
    with Session(spec) as session:
        while not session.ego_on_road:
            session.step()
        for k in range(30):
            snap = session.snapshot
            leader_front = snap.x[snap.index_of("slow.0")] + 10.0 * spec.step_s
            behind = 20.0 if 10 <= k < 20 else 2.0
            t = session.time + spec.step_s
            x = leader_front - behind
            session.drive_ego(Trajectory(np.array([t - 1.0, t]), np.array([x - 10.0, x]), np.full(2, lane_y),
                                         np.zeros(2), np.full(2, 10.0), np.zeros(2)))
            session.step()
            colliding_steps += len(libsumo.simulation.getCollisions()) > 0
    assert colliding_steps >= 15  # SUMO reported the contacts on every overlapping step...
    assert len(session.collisions) == 2  # ...and the session recorded each contact once
    assert all({c.collider, c.victim} == {"ego", "slow.0"} for c in session.collisions)
    assert session.collisions[1].time - session.collisions[0].time == pytest.approx(2.0, abs=0.15)


def test_a_second_session_in_one_process_is_refused():
    spec = _spec("highway_sparse")
    with Session(spec):
        with pytest.raises(SessionError, match="another Session is already open"):
            Session(spec).start()


def test_session_is_closed_when_the_caller_raises():
    spec = _spec("highway_sparse")
    with pytest.raises(RuntimeError, match="boom"):
        with Session(spec) as session:
            session.step()
            raise RuntimeError("boom")
    with Session(spec) as again:  # the slot was released and SUMO restarted cleanly
        assert again.step().time == 0.0  # SUMO's output time stamp of the first step


def test_snapshot_values_are_rounded_as_sumo_writes_them():
    """Correctly rounded to 6 decimals, as SUMO's --precision 6 output (np.round scales by 10^6 first and read
    133.263348 and 296.255866 for these two, which SUMO writes as 133.263349 and 296.255865)."""
    ties = np.arange(-2000, 2000) * 0.0731 + 0.0000005  # values near a tie in the 7th decimal
    values = np.concatenate([[133.2633485, 296.25586549999997], ties])
    expected = [float(f"{v:.6f}") for v in values]
    assert as_written(values).tolist() == expected
    assert as_written(values.reshape(2, -1)).ravel().tolist() == expected


def test_the_route_file_and_command_line_keep_every_digit_of_a_time(tmp_path, valid_scenario):
    """Six significant digits wrote an ego departure at 12345.65 s as 12345.6 (0.05 s early)."""
    valid_scenario["duration_s"] = 20000.25
    valid_scenario["step_s"] = 0.05  # the duration is a whole number of steps
    valid_scenario["ego"]["depart_s"] = 12345.65
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    routes = ET.parse(write_route_file(spec, tmp_path / "routes.rou.xml")).getroot()
    assert routes.find("vehicle[@id='ego']").get("depart") == "12345.65"
    assert routes.find("flow").get("end") == "20000.25"
    args = sumo_arguments(spec, tmp_path / "routes.rou.xml")
    assert args[args.index("--end") + 1] == "20000.25" and args[args.index("--step-length") + 1] == "0.05"


def test_sumo_ending_the_run_is_a_session_error_naming_the_scenario(tmp_path, valid_scenario):
    """A vehicle SUMO cannot route ends the run with libsumo's FatalTraCIError, which reached the user as a
    traceback. (Scenario files refuse such routes; a spec changed from Python is not checked again.)"""
    tree = ET.parse(NETWORKS / "highway" / "highway.net.xml")
    for lane in tree.getroot().iter("lane"):
        if lane.get("id").startswith("hw1_"):
            lane.set("disallow", "truck")
    tree.write(tmp_path / "no_trucks.net.xml")
    valid_scenario["network"] = str(tmp_path / "no_trucks.net.xml")
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    spec = replace(spec, ego=replace(spec.ego, vehicle=replace(spec.ego.vehicle, vclass="truck")))
    with Session(spec) as session, pytest.raises(SessionError, match=r"SUMO stopped scenario .*scenario\.toml at "
                                                                     r"t = 1\.\d0 s: .*ego.*no valid route"):
        while not session.finished:
            session.step()
