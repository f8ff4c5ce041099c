"""Offline audits from SUMO FCD files: identical to the online audit, derived attributes, clear errors."""
from __future__ import annotations

import gc
import json
import re
import subprocess
import tomllib
import tracemalloc
import warnings
import xml.etree.ElementTree as ET

import libsumo
import numpy as np
import pandas as pd
import pytest

from conftest import NETWORKS, SCENARIOS, run_cli, write_scenario
from sumo_rss import load_scenario
from sumo_rss.batch.runner import param_resolver
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, CollisionInput, ParamResolver
from sumo_rss.rss.fcd import FcdError, FcdReader, audit_fcd, overlap_contacts, read_collisions, read_vehicle_info
from sumo_rss.rss.params import EvasiveParams
from sumo_rss.rss.signals import SignalStates
from sumo_rss.sim.session import Session
from sumo_rss.sim.snapshot import WorldSnapshot
from sumo_rss.sumo_home import sumo_tool

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"


def test_online_and_offline_audits_of_one_run_give_identical_csvs(dense_run, tmp_path):
    proc = run_cli("audit", str(dense_run / "fcd.xml"), "--net", str(HIGHWAY), "--vtypes",
                   str(dense_run / "routes.rou.xml"), "--collisions", str(dense_run / "collisions.xml"), "--out",
                   str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    episodes = (dense_run / "episodes.csv").read_bytes()
    assert episodes.count(b"\n") > 50  # dense traffic under ad_rss parameters: plenty of episodes to compare
    for name in ("episodes.csv", "violations.csv", "collisions.csv"):
        assert (tmp_path / name).read_bytes() == (dense_run / name).read_bytes(), name


def _add_crash_pair() -> None:
    """A leader 50 m ahead of a follower in lane 1 of the highway (route 'hw'), both at 15 m/s, SUMO's safety off."""
    for vid, pos in (("leader", 150.0), ("follower", 100.0)):
        libsumo.vehicle.add(vid, "hw", typeID="car", depart="now", departLane="1", departPos=str(pos),
                            departSpeed="15")
        libsumo.vehicle.setSpeedMode(vid, 0)
        libsumo.vehicle.setLaneChangeMode(vid, 0)


def _crash_controls() -> None:
    """Before a step: the leader brakes at 5 m/s², the follower speeds up at 1 m/s² (while both are on the road)."""
    if libsumo.vehicle.getIDCount() == 2:
        libsumo.vehicle.setSpeed("leader", max(0.0, libsumo.vehicle.getSpeed("leader") - 0.5))
        libsumo.vehicle.setSpeed("follower", libsumo.vehicle.getSpeed("follower") + 0.1)


def test_collisions_are_joined_the_same_way_online_and_offline(tmp_path, valid_scenario):
    # A follower that keeps accelerating into a stopped leader (see test_rss_scenarios, case a).
    valid_scenario["demand"]["flows"] = []
    del valid_scenario["ego"]
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    rule5 = EvasiveParams(enabled=True)  # asked of the collision, from the kept steps, both ways alike
    online = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec), "crash", evasive=rule5)
    run_dir = tmp_path / "run"
    with Session(spec, run_dir, fcd=True) as session:
        libsumo.route.add("hw", ["hw0", "hw1", "hw2"])
        _add_crash_pair()
        for _ in range(120):
            _crash_controls()
            seen = len(session.collisions)
            snap = session.step()
            online.observe(snap, [CollisionInput(c.time, c.collider, c.victim, c.kind)
                                  for c in session.collisions[seen:]])
    on = online.finish()
    assert len(on.collisions) == 1 and on.collisions.blamed[0] == "follower"
    off = audit_fcd(run_dir / "fcd.xml", RoadNetwork.from_file(spec.net_file), param_resolver(spec),
                    vehicles=read_vehicle_info(run_dir / "routes.rou.xml", spec.net_file),
                    collisions=run_dir / "collisions.xml",
                    run_id="crash", evasive=rule5)
    assert on.episodes.evasive_checked.tolist() == [True]
    for name in ("episodes", "violations", "collisions"):
        assert getattr(off, name).to_csv(index=False) == getattr(on, name).to_csv(index=False), name
    # Without SUMO's collision file the contact is found from overlapping bounding boxes, one step later at most.
    boxes = audit_fcd(run_dir / "fcd.xml", RoadNetwork.from_file(spec.net_file), param_resolver(spec),
                      vehicles=read_vehicle_info(run_dir / "routes.rou.xml", spec.net_file), run_id="crash")
    assert len(boxes.collisions) == 1 and boxes.collisions.blamed[0] == "follower"
    assert boxes.collisions.time_s[0] == pytest.approx(on.collisions.time_s[0], abs=0.1 + 1e-9)


def test_junction_contacts_are_found_from_the_footprints_without_sumos_collision_file(tmp_path):
    """intersection_tls with drivers that ignore their foes at the junction: SUMO reports crossing collisions
    inside it. Without SUMO's collision file each is found from the cars' footprints, at most one step apart, with
    the same blame (a crossing pair's gaps are distances to the conflict area, not between the cars)."""
    scenario = tomllib.loads((SCENARIOS / "intersection_tls.toml").read_text())
    scenario["demand"]["vtypes"]["car"]["car_follow_params"] = {
        "jmIgnoreFoeProb": 1.0, "jmIgnoreJunctionFoeProb": 1.0, "jmIgnoreFoeSpeed": 100.0,
        "jmDriveAfterRedTime": 100.0}
    proc = run_cli("run", str(write_scenario(tmp_path, scenario, "crash.toml")), "--duration", "30", "--out",
                   str(tmp_path / "out"), "--fcd", "--quiet")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "out" / "crash" / "0"
    live = pd.read_csv(run / "collisions.csv", keep_default_na=False)
    assert len(live) >= 2 and set(live.sumo_type) == {"junction"}
    spec = load_scenario(run / "scenario.toml")
    found = audit_fcd(run / "fcd.xml", RoadNetwork.from_file(spec.net_file), param_resolver(spec),
                      vehicles=read_vehicle_info(run / "routes.rou.xml", spec.net_file), run_id=live.run_id[0]).collisions
    assert len(found) == len(live)
    for contact, sumo in zip(found.itertuples(), live.itertuples()):
        assert {contact.collider, contact.victim} == {sumo.collider, sumo.victim}
        assert contact.time_s == pytest.approx(sumo.time_s, abs=0.1 + 1e-9)
        assert (contact.blamed, contact.episode_key) == (sumo.blamed, sumo.episode_key)


def test_the_rear_car_of_a_merging_pair_in_contact_is_named_the_collider():
    """Car 'b_rear' on the acceleration lane mw_merge_0 (straight along +x, lanes 3.5 m apart), 2 m behind 'a_front'
    on mw_merge_1 and 2 m to the left of its lane's centre: the 1.8 m wide bodies overlap by 0.3 m across and
    2.5 m along. A merge pair whose car a is in front: b_rear is the collider (SUMO names the rear car)."""
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    lanes = np.array(["mw_merge_1", "mw_merge_0"])
    k = net.lane_indices(lanes)
    start = net.shapes.points[k, 0]  # both lanes start at x = 675.69 and run along +x
    lat = np.array([0.0, 2.0])
    zero = np.zeros(2)
    snapshot = WorldSnapshot(
        time=5.0, ids=np.array(["a_front", "b_rear"]), x=start[:, 0] + np.array([100.0, 98.0]),
        y=start[:, 1] + lat, heading=zero, speed=np.full(2, 20.0), accel=zero, lat_speed=zero,
        length=np.full(2, 4.5), width=np.full(2, 1.8), lane_id=lanes, edge_id=np.full(2, "mw_merge"),
        lane_index=np.array([1, 0]), lane_pos=np.array([100.0, 98.0]), lat_pos=lat,
        vclass=np.full(2, "background"), vtype=np.full(2, "car"), signals=np.zeros(2, int),
        route_index=np.zeros(2, int))
    pairs = Auditor(net, ParamResolver("ad_rss")).observe(snapshot)
    assert pairs.kind.tolist() == [2] and not pairs.a_is_rear[0]  # merge; car a ('a_front') is the front car
    (contact,) = overlap_contacts(snapshot, pairs, net)
    assert (contact.collider, contact.victim, contact.kind) == ("b_rear", "a_front", "overlap")


def _strip(src, dst, keep: set[str]) -> None:
    tree = ET.parse(src)
    for vehicle in tree.iter("vehicle"):
        for name in list(vehicle.attrib):
            if name not in keep:
                del vehicle.attrib[name]
    tree.write(dst)


def test_missing_attributes_are_derived(dense_run, tmp_path):
    network = RoadNetwork.from_file(HIGHWAY)
    vehicles = read_vehicle_info(dense_run / "routes.rou.xml", HIGHWAY)
    _strip(dense_run / "fcd.xml", tmp_path / "bare.xml", {"id", "x", "y", "angle", "speed", "lane", "type"})
    full = list(FcdReader(dense_run / "fcd.xml", network, vehicles))
    bare = list(FcdReader(tmp_path / "bare.xml", network, vehicles))
    assert len(full) == len(bare) == 600
    for f, b in zip(full[1:], bare[1:]):
        assert np.array_equal(f.ids, b.ids)
        # SUMO's acceleration is the speed change over the last step: derived exactly (to the file's 1e-6).
        np.testing.assert_allclose(b.accel, f.accel, atol=2e-5)
        np.testing.assert_allclose(b.lane_pos, f.lane_pos, atol=1e-3)  # from x, y and the lane shape [m]
        np.testing.assert_allclose(b.lat_pos, f.lat_pos, atol=1e-3)
        # Lateral speed from lateral-position differences: equal except at a lane change's first step.
        assert np.mean(np.abs(b.lat_speed - f.lat_speed) < 1e-3) > 0.97


def test_a_damaged_fcd_names_the_file_and_time_step(dense_run, tmp_path):
    """Damage inside the file is an error (a file that merely breaks off is read up to there: test_rss_cut_outputs)."""
    text = (dense_run / "fcd.xml").read_text()
    middle = text.index("</timestep>", len(text) // 2)
    damaged = tmp_path / "damaged.xml"
    damaged.write_text(text[:middle] + "</timestap>" + text[middle + len("</timestep>"):])
    reader = FcdReader(damaged, RoadNetwork.from_file(HIGHWAY))
    with pytest.raises(FcdError, match=r"damaged\.xml: malformed or truncated FCD after time step \d+\.\d+ s"):
        for _ in reader:
            pass


def test_wrong_network_and_bad_files_give_one_line_errors(dense_run, tmp_path):
    merge = NETWORKS / "merge" / "merge.net.xml"
    proc = run_cli("audit", str(dense_run / "fcd.xml"), "--net", str(merge), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2
    (line,) = proc.stderr.strip().splitlines()
    assert "fcd.xml, time step 0.0 s: lanes not in merge.net.xml: hw0_" in line and "--net" in line
    assert not (tmp_path / "out").exists()  # nothing half-written
    not_fcd = tmp_path / "routes.xml"
    not_fcd.write_text((dense_run / "routes.rou.xml").read_text())
    proc = run_cli("audit", str(not_fcd), "--net", str(HIGHWAY))
    assert proc.returncode == 2 and "expected <fcd-export>" in proc.stderr
    proc = run_cli("audit", str(tmp_path / "nope.xml"), "--net", str(HIGHWAY))
    assert proc.returncode == 2 and "nope.xml: FCD file not found" in proc.stderr
    # A route file or a non-XML file given as the network is named as the network, not as a vType problem.
    (tmp_path / "junk.xml").write_text("hello")
    for net, message in ((dense_run / "routes.rou.xml", "routes.rou.xml: not a SUMO network (root element <routes>, "
                                                         "expected <net>)"),
                         (tmp_path / "junk.xml", "junk.xml: not a readable SUMO network (")):
        proc = run_cli("audit", str(dense_run / "fcd.xml"), "--net", str(net), "--vtypes",
                       str(dense_run / "routes.rou.xml"))
        assert proc.returncode == 2 and message in proc.stderr and "vType" not in proc.stderr, proc.stderr
    # A value that is not a number names the vehicle and the attribute.
    bad = tmp_path / "bad_x.xml"
    bad.write_text('<fcd-export><timestep time="0.00"><vehicle id="car.7" x="abc" y="1" angle="90" speed="3" '
                   'lane="hw0_0" pos="5"/></timestep></fcd-export>')
    proc = run_cli("audit", str(bad), "--net", str(HIGHWAY), "--out", str(tmp_path / "out2"))
    assert proc.returncode == 2
    assert "bad_x.xml, time step 0.0 s: vehicle 'car.7': x: expected a finite number, got 'abc'" in proc.stderr, \
        proc.stderr


def _fcd_vehicle(vid: str, at: float, **changed: str | None) -> str:
    """A vehicle element; ``changed`` attributes replace the defaults (None: left out)."""
    attributes = {"id": vid, "x": f"{at}", "y": "-1.75", "angle": "90", "speed": "3", "lane": "hw0_1", "pos": f"{at}",
                  "posLat": "0", "acceleration": "0", "type": "car", **changed}
    return "<vehicle " + " ".join(f'{k}="{v}"' for k, v in attributes.items() if v is not None) + "/>"


@pytest.mark.parametrize("changed, message", [
    ({"x": "nan"}, "vehicle 'a': x: expected a finite number, got 'nan'"),
    ({"speed": "inf"}, "vehicle 'a': speed: expected a finite number, got 'inf'"),
    ({"speed": "-5"}, "vehicle 'a': speed: expected a number >= 0 (m/s) and at most 200 m/s, got -5"),
    ({"pos": "abc10"}, "vehicle 'a': pos: expected a finite number, got 'abc10'"),
    ({"acceleration": "x0"}, "vehicle 'a': acceleration: expected a finite number, got 'x0'"),
    ({"signals": "0.0"}, "vehicle 'a': signals: expected an integer in [0, 2147483647] (SUMO's signal bits), got '0.0'"),
    ({"id": "b"}, "vehicle 'b' is listed more than once"),
    ({"lane": None}, "vehicle 'a' lacks the attribute 'lane' (needed: id, x, y, angle, speed, lane; SUMO writes them "
                     "by default, and with --fcd-output.attributes they must be listed)"),
    ({"angle": None}, "vehicle 'a' lacks the attribute 'angle' (needed: id, x, y, angle, speed, lane; SUMO writes "
                      "them by default, and with --fcd-output.attributes they must be listed)"),
], ids=["nan", "inf", "negative-speed", "optional", "acceleration", "signals", "twice", "no-lane", "no-angle"])
@pytest.mark.filterwarnings("ignore:.*vType car is not defined")
def test_bad_values_in_an_fcd_name_the_time_step_vehicle_and_attribute(tmp_path, changed, message):
    """Every attribute read is checked (finite numbers, integer signals, ids once per step): a bad value is an
    error naming where it is, not a traceback, a NaN in the geometry or a silently different audit."""
    fcd = tmp_path / "f.xml"
    fcd.write_text(f'<fcd-export><timestep time="0.00">{_fcd_vehicle("b", 60.0)}</timestep>'
                   f'<timestep time="0.10">{_fcd_vehicle("a", 20.0, **changed)}{_fcd_vehicle("b", 60.3)}'
                   "</timestep></fcd-export>")
    with pytest.raises(FcdError) as error:
        list(FcdReader(fcd, RoadNetwork.from_file(HIGHWAY)))
    assert str(error.value) == f"{fcd}, time step 0.1 s: {message}"


@pytest.mark.parametrize("time, after", [('time="abc30"', "after time step 0.0 s"), ("", "after time step 0.0 s")],
                         ids=["not-a-number", "missing"])
def test_a_time_step_without_a_time_is_named_by_the_step_before(tmp_path, time, after):
    fcd = tmp_path / "f.xml"
    fcd.write_text('<fcd-export><timestep time="0.00"></timestep>'
                   f"<timestep {time}></timestep></fcd-export>")
    with pytest.raises(FcdError, match=re.escape(f"f.xml: <timestep> ({after}): time: expected a number of seconds")):
        list(FcdReader(fcd, RoadNetwork.from_file(HIGHWAY)))


def test_vtypes_are_read_as_sumo_resolves_them(tmp_path):
    """What a vType leaves out is SUMO's default for its vClass (documented: a truck is 7.1 m x 2.4 m and brakes at
    4.0 m/s², a bicycle is 0.65 m wide), vTypes inside a distribution count, SUMO's built-in types are known
    without a file, and a route may be named or written inside its vehicle."""
    routes = tmp_path / "mixed.rou.xml"
    routes.write_text("""<routes>
    <vType id="lorry" vClass="truck"/>
    <vType id="bike" vClass="bicycle" length="1.8" tau="1.4"/>
    <vTypeDistribution id="cars"><vType id="small" length="3.5" probability="1"/></vTypeDistribution>
    <route id="main" edges="hw0 hw1 hw2"/>
    <vehicle id="a" type="lorry" depart="0" route="main"/>
    <vehicle id="b" type="bike" depart="0"><route edges="hw1 hw2"/></vehicle>
    <flow id="f" type="cars" begin="0" end="10" number="2"><route edges="hw0 hw1"/></flow>
    <trip id="t" depart="0" from="hw0" to="hw2"/>
</routes>""")
    info = read_vehicle_info(routes, HIGHWAY)
    assert info.sizes["lorry"] == (7.1, 2.4) and info.dynamics["lorry"] == (1.0, 4.0)
    assert info.sizes["bike"] == (1.8, 0.65) and info.dynamics["bike"] == (1.4, 3.0)
    assert info.sizes["small"] == (3.5, 1.8) and info.sizes["DEFAULT_VEHTYPE"] == (5.0, 1.8)
    assert read_vehicle_info(None, HIGHWAY).sizes["DEFAULT_BIKETYPE"] == (1.6, 0.65)
    assert (info.route_of("a"), info.route_of("b"), info.route_of("f.1"), info.route_of("t")) == \
        (("hw0", "hw1", "hw2"), ("hw1", "hw2"), ("hw0", "hw1"), None)


def test_a_misspelt_vtype_attribute_is_named_not_silently_ignored(tmp_path):
    """SUMO ignores an attribute it does not know: 'lenght' leaves the truck at its vClass's 7.1 m."""
    routes = tmp_path / "typo.rou.xml"
    routes.write_text('<routes><vType id="lorry" vClass="truck" lenght="4" tau="1.2"/></routes>')
    with pytest.warns(UserWarning, match=r"typo\.rou\.xml: vType 'lorry': unknown attribute\(s\) lenght, which SUMO "
                                         r"ignores"):
        info = read_vehicle_info(routes, HIGHWAY)
    assert info.sizes["lorry"] == (7.1, 2.4)


def test_unknown_vtypes_are_named_once_and_bad_vtypes_are_errors(dense_run, tmp_path):
    reader = FcdReader(dense_run / "fcd.xml", RoadNetwork.from_file(HIGHWAY), read_vehicle_info(None, HIGHWAY))
    with pytest.warns(UserWarning, match=r"fcd\.xml: vType .* is not defined") as caught:
        lengths = {float(v) for snapshot in reader for v in snapshot.length}
    named = [name for w in caught for name in re.search(r"vType (.*) is not", str(w.message)).group(1).split(", ")]
    assert sorted(named) == ["car", "ego_type", "truck", "van"]  # each once, when it first appears
    assert lengths == {5.0}  # SUMO's passenger size for every car of the file
    bad = tmp_path / "bad.rou.xml"
    bad.write_text('<routes><vType id="car" length="-1"/></routes>')
    proc = run_cli("audit", str(dense_run / "fcd.xml"), "--net", str(HIGHWAY), "--vtypes", str(bad), "--out",
                   str(tmp_path / "out"))
    assert proc.returncode == 2
    assert "sumo-rss: error: " in proc.stderr and "bad.rou.xml: SUMO cannot load the vTypes (Error: " in proc.stderr


def test_reader_uses_constant_memory(dense_run, tmp_path):
    # The last time step of the run (about 100 vehicles) repeated 1500 times: constant traffic, growing file.
    steps = ET.parse(dense_run / "fcd.xml").getroot().findall("timestep")
    body = ET.tostring(steps[-1], encoding="unicode").split(">", 1)[1].rsplit("</timestep>", 1)[0]
    long_fcd = tmp_path / "long.xml"
    with long_fcd.open("w") as fh:
        fh.write("<fcd-export>\n")
        for k in range(1500):
            fh.write(f'<timestep time="{k / 10:.2f}">{body}</timestep>\n')
        fh.write("</fcd-export>\n")
    reader = FcdReader(long_fcd, RoadNetwork.from_file(HIGHWAY))
    tracemalloc.start()
    live = []
    for k, _ in enumerate(reader):
        if k in (150, 1499):
            gc.collect()
            live.append(tracemalloc.get_traced_memory()[0])
    tracemalloc.stop()
    assert live[1] < 1.2 * live[0]  # ten times the steps read, the same live memory


def test_param_resolver_uses_vtype_dynamics_for_krauss():
    resolver = ParamResolver("krauss", vtype_dynamics={"truck": (1.5, 4.0)})
    truck = resolver.get("background", "truck")
    assert (truck.response_time, truck.lon_brake_min, truck.lon_brake_max, truck.lon_accel_max) == (1.5, 4.0, 4.0, 0.0)


def test_online_and_offline_audits_agree_at_a_signalised_junction(tmp_path):
    """Offline, signal states come from the net's fixed-time program and routes from the route file (plain ad_rss:
    standing cars not held, unlike the shipped scenario)."""
    data = tomllib.loads((SCENARIOS / "intersection_tls.toml").read_text(encoding="utf-8"))
    data["network"] = "intersection_tls"
    data["rss"] = {**data.get("rss", {}), "hold_standing": False}
    scenario = write_scenario(tmp_path, data, "intersection_tls.toml")
    proc = run_cli("run", str(scenario), "--duration", "120", "--out", str(tmp_path), "--fcd", "--quiet")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "intersection_tls" / "0"
    net = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(net), "--vtypes", str(run / "routes.rou.xml"),
                   "--collisions", str(run / "collisions.xml"), "--out", str(tmp_path / "offline"))
    assert proc.returncode == 0, proc.stderr
    episodes = (run / "episodes.csv").read_text()
    assert "intersection-priority" in episodes  # signal-decided situations were audited
    for name in ("episodes.csv", "violations.csv", "collisions.csv"):
        assert (tmp_path / "offline" / name).read_bytes() == (run / name).read_bytes(), name


def test_sumo_signal_state_output_gives_the_online_states_and_csvs(tmp_path):
    """SUMO writes signal states through a ``SaveTLSStates`` timed event in an additional file (docs/rss.md). Read
    with --tls-states, that file gives at every step the states the online audit saw (here: the net's fixed-time
    program), and the offline audit the online CSVs."""
    states_file = tmp_path / "tls.xml"
    additional = tmp_path / "tls.add.xml"
    additional.write_text(f'<additional><timedEvent type="SaveTLSStates" dest="{states_file}"/></additional>\n')
    data = tomllib.loads((SCENARIOS / "intersection_tls.toml").read_text(encoding="utf-8"))
    data["network"] = "intersection_tls"
    data["sumo"] = {**data.get("sumo", {}), "additional_files": [additional.name]}  # relative to the scenario file
    scenario = write_scenario(tmp_path, data, "intersection_tls.toml")
    proc = run_cli("run", str(scenario), "--duration", "120", "--out", str(tmp_path / "online"), "--fcd", "--quiet")
    assert proc.returncode == 0, proc.stderr
    net = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
    saved, program = SignalStates(net, states_file), SignalStates(net)
    times = np.round(np.arange(0.0, 120.0, 0.1), 1)
    assert len({saved.states(t)["C"] for t in times}) >= 4  # the phases change within the run
    assert [t for t in times if saved.states(t) != program.states(t)] == []
    run = tmp_path / "online" / "intersection_tls" / "0"
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(net), "--vtypes", str(run / "routes.rou.xml"),
                   "--collisions", str(run / "collisions.xml"), "--tls-states", str(states_file), "--out",
                   str(tmp_path / "offline"), "--hold-standing")  # as the scenario sets
    assert proc.returncode == 0, proc.stderr
    assert "intersection-priority" in (run / "episodes.csv").read_text()
    for name in ("episodes.csv", "violations.csv", "collisions.csv"):
        assert (tmp_path / "offline" / name).read_bytes() == (run / name).read_bytes(), name


def test_a_signal_state_file_of_another_run_is_refused_or_named(tmp_path):
    """--tls-states must be SUMO's signal-state output for this network: another file was read as 'no states', and
    every signal fell back to equal priority (a different audit, silently). A signal without states keeps its
    network program, with a warning."""
    net = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
    wrong = tmp_path / "collisions.xml"
    wrong.write_text('<collisions></collisions>')
    with pytest.raises(ValueError, match=r"collisions\.xml: not a readable SUMO signal-state file \(SaveTLSStates "
                                         r"output: root element <collisions>, expected <tlsStates>"):
        SignalStates(net, wrong)
    foreign = tmp_path / "other.xml"
    foreign.write_text('<tlsStates><tlsState time="0.00" id="J9" state="GGrr"/></tlsStates>')
    with pytest.raises(ValueError, match=r"other\.xml: states of signal\(s\) J9 that .*intersection_tls\.net\.xml "
                                         "does not have"):
        SignalStates(net, foreign)
    empty = tmp_path / "empty.xml"
    empty.write_text("<tlsStates></tlsStates>")
    with pytest.warns(UserWarning, match=r"empty\.xml: no states of signal\(s\) C; their network programs are used"):
        fallback = SignalStates(net, empty)
    assert fallback.states(12.3) == SignalStates(net).states(12.3)


def test_hold_standing_is_the_same_online_and_offline_and_counts_fewer_queued_dangers(tmp_path):
    """A run with ``[rss] hold_standing = true`` and the offline audit of its FCD with --hold-standing write the same
    CSVs; without the option the offline audit finds the pairs in danger for longer (cars queued at the red lights:
    as many episodes, but a queue's stays open while it stands)."""
    data = tomllib.loads((SCENARIOS / "intersection_tls.toml").read_text(encoding="utf-8"))
    data["network"] = "intersection_tls"
    data["rss"] = {**data.get("rss", {}), "hold_standing": True}
    scenario = write_scenario(tmp_path, data, "intersection_tls.toml")
    proc = run_cli("run", str(scenario), "--duration", "120", "--out", str(tmp_path / "online"), "--fcd", "--quiet")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "online" / "intersection_tls" / "0"
    common = (str(run / "fcd.xml"), "--net", str(NETWORKS / "intersection_tls" / "intersection_tls.net.xml"),
              "--vtypes", str(run / "routes.rou.xml"), "--collisions", str(run / "collisions.xml"))
    for out, flags in (("held", ("--hold-standing",)), ("plain", ())):
        proc = run_cli("audit", *common, *flags, "--out", str(tmp_path / out))
        assert proc.returncode == 0, proc.stderr
    for name in ("episodes.csv", "violations.csv", "collisions.csv"):
        assert (tmp_path / "held" / name).read_bytes() == (run / name).read_bytes(), name
    for out, said in ((run, True), (tmp_path / "held", True), (tmp_path / "plain", None)):
        params = json.loads((out / "rss_params.json").read_text())
        assert {p.get("hold_standing") for p in params.values()} == {said}
    held, plain = (pd.read_csv(tmp_path / out / "episodes.csv").duration_s.sum() for out in ("held", "plain"))
    assert held < 0.9 * plain  # 1130 s against 1434 s of danger, summed over the episodes


def test_vtypes_and_routes_may_come_from_several_files(dense_run, tmp_path):
    """As with sumo -r a,b: vTypes in one file, a named route in another, the vehicle in a third."""
    (tmp_path / "types.add.xml").write_text('<additional><vType id="lorry" vClass="truck"/></additional>')
    (tmp_path / "route.rou.xml").write_text('<routes><route id="main" edges="hw0 hw1 hw2"/></routes>')
    (tmp_path / "cars.rou.xml").write_text('<routes><vehicle id="a" type="lorry" depart="0" route="main"/></routes>')
    info = read_vehicle_info([tmp_path / n for n in ("types.add.xml", "route.rou.xml", "cars.rou.xml")], HIGHWAY)
    assert info.sizes["lorry"] == (7.1, 2.4) and info.route_of("a") == ("hw0", "hw1", "hw2")
    proc = run_cli("audit", str(dense_run / "fcd.xml"), "--net", str(HIGHWAY), "--vtypes",
                   f"{dense_run / 'routes.rou.xml'},{tmp_path / 'nope.xml'}", "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "nope.xml: vType file not found" in proc.stderr


def test_instantaneous_lane_changes_are_named_once(dense_run, tmp_path):
    """SUMO without --lanechange.duration moves a car a lane width sideways in one step: the reader warns once.
    The session's FCD (continuous lane changes) gives no warning."""
    network = RoadNetwork.from_file(HIGHWAY)
    vehicles = read_vehicle_info(dense_run / "routes.rou.xml", HIGHWAY)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(list(FcdReader(dense_run / "fcd.xml", network, vehicles))) == 600
    subprocess.run([str(sumo_tool("sumo")), "--net-file", str(HIGHWAY), "--route-files",
                    str(dense_run / "routes.rou.xml"), "--step-length", "0.1", "--end", "60", "--no-step-log", "true",
                    "--no-warnings", "true", "--fcd-output", str(tmp_path / "jumps.xml")], check=True,
                   capture_output=True)
    with pytest.warns(UserWarning, match=r"jumps\.xml: .* moves 3\.\d+ m sideways onto another lane in one 0\.1 s "
                                         r"step") as caught:
        list(FcdReader(tmp_path / "jumps.xml", network, vehicles))
    assert len([w for w in caught if "sideways" in str(w.message)]) == 1
    # SUMO writes speedLat 0 at such a lane change; without speedLat in the FCD the derived lateral speed is 0 there
    # too (not 3.2 m / 0.1 s = 32 m/s, which opened a lateral episode at every lane change): the two files of one
    # run audit alike.
    with_lat = tmp_path / "with_lat.xml"
    subprocess.run([str(sumo_tool("sumo")), "--net-file", str(HIGHWAY), "--route-files",
                    str(dense_run / "routes.rou.xml"), "--step-length", "0.1", "--end", "60", "--no-step-log", "true",
                    "--no-warnings", "true", "--fcd-output", str(with_lat), "--fcd-output.attributes",
                    "x,y,angle,type,speed,acceleration,pos,lane,posLat,speedLat"], check=True, capture_output=True)
    text = with_lat.read_text()
    assert 'speedLat="0.00"' in text and 'speedLat="' not in text.replace('speedLat="0.00"', "")
    without_lat = tmp_path / "without_lat.xml"
    without_lat.write_text(text.replace(' speedLat="0.00"', ""))
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".*sideways")
        audits = [audit_fcd(f, network, ParamResolver(), vehicles=vehicles) for f in (with_lat, without_lat)]
    assert len(audits[0].episodes) > 100
    for name in ("episodes", "violations"):
        pd.testing.assert_frame_equal(getattr(audits[0], name), getattr(audits[1], name))


@pytest.mark.parametrize("step, lane_changes", [("0.1", ["--lanechange.duration", "3"]), ("1", [])])
def test_lateral_speeds_from_sumos_rounded_positions_are_sumos_own(dense_run, tmp_path, step, lane_changes):
    """Without speedLat the lateral speed comes from position differences. SUMO writes positions with 2 decimals by
    default: on the curved hw1 their rounding read as up to ±0.12 m/s of lateral speed for cars keeping their lane
    (974 violations where the file with speedLat gave 178). At SUMO's default 1 s step a lane changed in one step
    moved 3.5 m/s sideways, below the jump speed, and was judged as a lateral movement."""
    network = RoadNetwork.from_file(HIGHWAY)
    vehicles = read_vehicle_info(dense_run / "routes.rou.xml", HIGHWAY)
    files = [tmp_path / "derived.xml", tmp_path / "sumo.xml"]
    for out, attributes in zip(files, ("x,y,angle,type,speed,pos,lane", "x,y,angle,type,speed,pos,lane,speedLat")):
        subprocess.run([str(sumo_tool("sumo")), "--net-file", str(HIGHWAY), "--route-files",
                        str(dense_run / "routes.rou.xml"), "--step-length", step, *lane_changes, "--end", "100",
                        "--no-step-log", "true", "--no-warnings", "true", "--fcd-output", str(out),
                        "--fcd-output.attributes", attributes], check=True, capture_output=True)
    with pytest.warns(UserWarning, match=r"derived\.xml: positions are written with 2 decimals: a car's lateral "
                                         r"movement of up to 0\.0141 m in a step \(its rounding\) is read as none"):
        pairs = list(zip(FcdReader(files[0], network, vehicles), FcdReader(files[1], network, vehicles),
                         strict=True))
    derived, sumo = (np.concatenate([p[k].lat_speed for p in pairs]) for k in (0, 1))
    moving = sumo != 0.0
    assert moving.sum() > 100 if lane_changes else not moving.any()
    np.testing.assert_array_equal(derived[~moving], 0.0)
    # A moving car's lateral movement over the step, within the rounding of the positions (√2 x 0.005 m per end).
    assert np.abs(derived[moving] - sumo[moving]).max(initial=0.0) <= 0.0142 / float(step)


def test_a_car_moving_sideways_onto_another_edge_keeps_its_lateral_speed(tmp_path):
    """Without speedLat, a lateral movement is measured within an edge; a car entering the next edge in the middle
    of a lane change read as not moving sideways there (0 m/s), which moved the start of its episodes."""
    steps = [(0.0, "hw0_1", 898.0, 0.0), (0.1, "hw0_1", 898.8, 0.1), (0.2, "hw0_1", 899.6, 0.2),
             (0.3, "hw1_1", 0.5, 0.3), (0.4, "hw1_1", 1.3, 0.4)]
    fcd = tmp_path / "f.xml"
    fcd.write_text("<fcd-export>" + "".join(
        f'<timestep time="{t:.2f}">' + _fcd_vehicle("a", 0.0, lane=lane, pos=f"{pos:.6f}", posLat=f"{lat:.6f}",
                                                   x=f"{pos if lane == 'hw0_1' else 900.17 + pos:.6f}",
                                                   y=f"{-5.25 + lat:.6f}", speed="8.000000") + "</timestep>"
        for t, lane, pos, lat in steps) + "</fcd-export>")
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".*vType car is not defined")
        speeds = [float(s.lat_speed[0]) for s in FcdReader(fcd, RoadNetwork.from_file(HIGHWAY))]
    np.testing.assert_allclose(speeds, [0.0, 1.0, 1.0, 1.0, 1.0], atol=1e-9)


def test_a_car_that_sumo_teleports_past_a_red_light_did_not_run_it(tmp_path):
    """SUMO teleports a car that waited too long (here 20 s) onto its next edge within the step, so it stays in the
    data: standing at the stop line, then 13.9 m/s beyond the junction. Every such teleport was reported as a
    red-light entry (18 of 18 in a 200 s run)."""
    net = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
    routes = tmp_path / "r.rou.xml"
    routes.write_text(
        '<routes><vType id="car" length="4.5" width="1.8" accel="2.6" decel="4.5" sigma="0.5" maxSpeed="15" '
        'impatience="0.5"/><vType id="bus" vClass="bus"/>'
        '<route id="NS" edges="N_in S_out"/><route id="NE" edges="N_in E_out"/><route id="SN" edges="S_in N_out"/>'
        '<route id="SW" edges="S_in W_out"/><route id="EW" edges="E_in W_out"/>'
        '<flow id="fNS" type="car" route="NS" begin="0" end="150" vehsPerHour="500"/>'
        '<flow id="fNE" type="car" route="NE" begin="0" end="150" vehsPerHour="300"/>'
        '<flow id="fSN" type="car" route="SN" begin="0" end="150" vehsPerHour="500"/>'
        '<flow id="fSW" type="car" route="SW" begin="0" end="150" vehsPerHour="300"/>'
        '<flow id="fEW" type="bus" route="EW" begin="0" end="150" vehsPerHour="150"/></routes>')
    (tmp_path / "tls.add.xml").write_text('<additional><timedEvent type="SaveTLSStates" dest="tls.xml"/></additional>')
    log = subprocess.run([str(sumo_tool("sumo")), "-n", str(net), "-r", str(routes), "-a", "tls.add.xml",
                          "--step-length", "0.1", "--lanechange.duration", "3", "--precision", "6",
                          "--time-to-teleport", "20", "--end", "80", "--no-step-log", "true", "--fcd-output",
                          "fcd.xml"], check=True, capture_output=True, text=True, cwd=tmp_path).stderr
    teleported = set(re.findall(r"Vehicle '([^']+)' ends teleporting", log))
    assert teleported, log
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".*(sideways|decimals)")
        audit = audit_fcd(tmp_path / "fcd.xml", RoadNetwork.from_file(net), ParamResolver(),
                          vehicles=read_vehicle_info(routes, net), tls_states=tmp_path / "tls.xml")
    signal = audit.violations[audit.violations.role == "signal"]
    assert not set(signal.vehicle_id) & teleported, signal


def test_an_fcd_without_types_takes_each_cars_type_from_the_route_file(tmp_path):
    """``--fcd-output.attributes`` without ``type``: every car was audited at SUMO's default 5 m x 1.8 m although
    the route file gives its vehicle or flow a vType."""
    routes = tmp_path / "r.rou.xml"
    routes.write_text('<routes><vType id="small" length="3.0" width="1.5"/>'
                      '<vehicle id="a" type="small" depart="0"><route edges="hw0 hw1 hw2"/></vehicle>'
                      '<flow id="f" type="small" begin="0" end="10" number="2"><route edges="hw0 hw1 hw2"/></flow>'
                      '<vehicle id="d" depart="0"><route edges="hw0 hw1 hw2"/></vehicle></routes>')
    fcd = tmp_path / "f.xml"
    cars = "".join(_fcd_vehicle(v, x) for v, x in (("a", 20.0), ("f.1", 60.0), ("d", 100.0), ("z", 140.0)))
    untyped = cars.replace(' type="car"', "")
    fcd.write_text(f'<fcd-export><timestep time="0.00">{untyped}</timestep></fcd-export>')
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".*decimals")
        (snap,) = FcdReader(fcd, RoadNetwork.from_file(HIGHWAY), read_vehicle_info(routes, HIGHWAY))
    assert snap.vtype.tolist() == ["small", "small", "DEFAULT_VEHTYPE", "DEFAULT_VEHTYPE"]
    assert snap.length.tolist() == [3.0, 3.0, 5.0, 5.0] and snap.width.tolist() == [1.5, 1.5, 1.8, 1.8]


def test_accelerations_from_rounded_speeds_carry_their_resolution(tmp_path):
    """Without 'acceleration' the FCD's speeds (2 decimals here) give the accelerations, off by up to 0.01 / 0.1 s
    = 0.1 m/s²: the snapshots say so, and the audit widens its tolerance by it. With the attribute: 0."""
    network = RoadNetwork.from_file(HIGHWAY)
    for with_accel, resolution in ((False, 0.1), (True, 0.0)):
        fcd = tmp_path / "f.xml"
        cars = [_fcd_vehicle("a", 20.0 + k, speed=f"{10.0 - 0.4 * k:.2f}") for k in range(3)]
        text = "".join(f'<timestep time="{0.1 * k:.2f}">{car}</timestep>' for k, car in enumerate(cars))
        fcd.write_text("<fcd-export>" + (text if with_accel else text.replace(' acceleration="0"', "")) +
                       "</fcd-export>")
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", ".*(vType car|decimals)")
            snaps = list(FcdReader(fcd, network))
        assert [s.accel_resolution for s in snaps[1:]] == pytest.approx([resolution] * 2)


def _crash_with_sumo_defaults(folder) -> tuple:
    """A follower accelerating into a braking leader, run by SUMO with its default collision action (teleport:
    the collider is moved on to the next edge in the step of the collision); returns (fcd, collisions, routes)."""
    routes = folder / "crash.rou.xml"
    routes.write_text('<routes><vType id="car" length="4.5" width="1.8"/>'
                      '<route id="hw" edges="hw0 hw1 hw2"/></routes>', encoding="utf-8")
    fcd, collisions = folder / "fcd.xml", folder / "collisions.xml"
    libsumo.start(["sumo", "-n", str(HIGHWAY), "-r", str(routes), "--step-length", "0.1", "--no-step-log", "true",
                   "--no-warnings", "true", "--fcd-output", str(fcd), "--fcd-output.acceleration", "true",
                   "--collision-output", str(collisions)])
    try:
        _add_crash_pair()
        for _ in range(60):
            _crash_controls()
            libsumo.simulationStep()
    finally:
        libsumo.close()
    return fcd, collisions, routes


def test_a_collision_joins_the_episode_that_its_collision_action_ended(tmp_path):
    """SUMO's default collision action moves the collider away in the step of the collision, so the pair is no
    longer a candidate then; the collision still closes (and is blamed by) the pair's episode."""
    fcd, collisions, routes = _crash_with_sumo_defaults(tmp_path)
    net, vehicles = RoadNetwork.from_file(HIGHWAY), read_vehicle_info(routes, HIGHWAY)
    crash_time = float(ET.parse(collisions).getroot().find("collision").get("time"))
    crash = audit_fcd(fcd, net, ParamResolver(), vehicles=vehicles, collisions=collisions, run_id="crash")
    assert crash.collisions[["time_s", "collider", "victim", "blamed"]].values.tolist() == \
        [[crash_time, "follower", "leader", "follower"]]
    episode = crash.episodes.set_index("episode_key").loc[crash.collisions.episode_key[0]]
    assert (episode.ended_by, episode.t_end_s, episode.responsible, episode.collider) == \
        ("collision", crash_time, "a", "follower")
    # A car that leaves the data (here: removed from the file at the collision) ends its pair's episode by the end
    # of its data, at the last step with both cars; it used to end 'safe' at the first step without it.
    tree = ET.parse(fcd)
    for step in tree.getroot().iter("timestep"):
        if float(step.get("time")) >= crash_time - 1e-9:
            for vehicle in step.findall("vehicle[@id='follower']"):
                step.remove(vehicle)
    tree.write(tmp_path / "cut.xml")
    cut = audit_fcd(tmp_path / "cut.xml", net, ParamResolver(), vehicles=vehicles, run_id="crash")
    assert cut.collisions.empty and len(cut.episodes) == 1
    assert cut.episodes[["ended_by", "t_end_s", "responsible"]].values.tolist() == \
        [["end-of-data", round(crash_time - 0.1, 6), "a"]]


def test_audit_with_the_runs_scenario_applies_its_rss_overrides(tmp_path, valid_scenario):
    valid_scenario["rss"].update({"hold_standing": True, "background": {"response_time": 1.5},
                                  "vtypes": {"car": {"lon_brake_max": 7.0}}})
    del valid_scenario["ego"]
    proc = run_cli("run", str(write_scenario(tmp_path, valid_scenario)), "--fcd", "--out", str(tmp_path / "runs"),
                   "--quiet")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "runs" / "scenario" / "1"
    common = (str(run / "fcd.xml"), "--net", str(HIGHWAY), "--vtypes", str(run / "routes.rou.xml"),
              "--collisions", str(run / "collisions.xml"))
    proc = run_cli("audit", *common, "--scenario", str(run / "scenario.toml"), "--out", str(tmp_path / "same"))
    assert proc.returncode == 0, proc.stderr
    for name in ("episodes.csv", "violations.csv", "collisions.csv", "rss_params.json"):
        assert (tmp_path / "same" / name).read_bytes() == (run / name).read_bytes(), name
    assert run_cli("audit", *common, "--out", str(tmp_path / "preset")).returncode == 0  # plain ad_rss differs
    assert (tmp_path / "preset" / "episodes.csv").read_bytes() != (run / "episodes.csv").read_bytes()
    clash = run_cli("audit", *common, "--scenario", str(run / "scenario.toml"), "--hold-standing")
    assert clash.returncode == 2 and "--scenario sets the RSS parameters" in clash.stderr


def test_another_file_given_as_the_collision_output_is_refused(tmp_path):
    """An FCD file given as --collisions was read as 'no collisions' without a word."""
    fcd = tmp_path / "fcd.xml"
    fcd.write_text('<fcd-export><timestep time="0.00"/></fcd-export>')
    with pytest.raises(FcdError, match=r"fcd\.xml: not a readable SUMO collision-output file \(root element "
                                       r"<fcd-export>, expected <collisions>\)"):
        read_collisions(fcd)
    (tmp_path / "c.xml").write_text('<collisions><collision time="3.10" collider="a" victim="b" type="collision"/>'
                                    "</collisions>")
    assert [(c.time, c.collider, c.victim) for c in read_collisions(tmp_path / "c.xml")] == [(3.1, "a", "b")]


@pytest.mark.parametrize("record, message", [
    ('time="3.10" collider="a"', "<collision> 2: attribute 'victim' is missing or empty"),
    ('collider="a" victim="b"', "<collision> 2: attribute 'time' is missing or empty"),
    ('time="abc" collider="a" victim="b"', "<collision> 2: attribute time='abc' is not a finite number"),
    ('time="3.10" collider="a" victim="b" colliderSpeed="nan"', "attribute colliderSpeed='nan' is not a finite"),
])
def test_a_collision_record_without_its_time_or_cars_is_named(tmp_path, record, message):
    """A record without a victim was a collision with '', one without a time was never audited (a NaN step)."""
    path = tmp_path / "c.xml"
    path.write_text(f'<collisions><collision time="1.00" collider="x" victim="y"/><collision {record}/></collisions>')
    with pytest.raises(FcdError, match=re.escape(f"{path}: {message}") if message.startswith("<") else message):
        read_collisions(path)


def test_collisions_between_the_steps_of_a_sparser_fcd_are_audited_at_the_step_after(tmp_path):
    """The collision reports were looked up by the FCD step's exact time: an FCD written every second lost the
    collision that SUMO (stepping 0.1 s) reported between two of its steps, without a word; reports outside the
    FCD's time span (a cut file) are named."""
    fcd, collisions, routes = _crash_with_sumo_defaults(tmp_path)
    net, vehicles = RoadNetwork.from_file(HIGHWAY), read_vehicle_info(routes, HIGHWAY)
    crash_time = float(ET.parse(collisions).getroot().find("collision").get("time"))
    tree = ET.parse(fcd)
    steps = tree.getroot().findall("timestep")
    kept = [s for s in steps if round(float(s.get("time")) * 10) % 10 == 0]
    assert all(abs(float(s.get("time")) - crash_time) > 0.05 for s in kept)  # no step at the collision
    for step in steps:
        if step not in kept:
            tree.getroot().remove(step)
    tree.write(tmp_path / "sparse.xml")
    sparse = audit_fcd(tmp_path / "sparse.xml", net, ParamResolver(), vehicles=vehicles, collisions=collisions)
    assert sparse.collisions[["time_s", "collider", "victim", "blamed"]].values.tolist() == \
        [[crash_time, "follower", "leader", "follower"]]
    for step in kept:
        if float(step.get("time")) > crash_time:
            tree.getroot().remove(step)
    tree.write(tmp_path / "cut.xml")
    last = max(float(s.get("time")) for s in kept if float(s.get("time")) < crash_time)
    with pytest.warns(UserWarning, match=re.escape(f"{collisions}: 1 collision report(s) outside the time steps of "
                                                   f"{tmp_path / 'cut.xml'} (0-{last:g} s) not audited: "
                                                   f"follower/leader at {crash_time:g} s")):
        cut = audit_fcd(tmp_path / "cut.xml", net, ParamResolver(), vehicles=vehicles, collisions=collisions)
    assert cut.collisions.empty


@pytest.mark.filterwarnings("ignore:.*vType car is not defined")
def test_an_ego_id_that_is_not_in_the_fcd_is_named(tmp_path):
    """A mistyped --ego audited the whole file as background traffic without a word."""
    fcd = tmp_path / "f.xml"
    fcd.write_text(f'<fcd-export><timestep time="0.00">{_fcd_vehicle("a", 20.0)}{_fcd_vehicle("b", 60.0)}'
                   "</timestep></fcd-export>")
    network = RoadNetwork.from_file(HIGHWAY)
    with pytest.warns(UserWarning, match=r"f\.xml: no vehicle egoo \(given as the ego\): audited without it"):
        audit_fcd(fcd, network, ParamResolver(), ego_ids=("a", "egoo"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        warnings.filterwarnings("ignore", ".*vType car is not defined")
        warnings.filterwarnings("ignore", ".*positions are written with 1 decimals")
        audit_fcd(fcd, network, ParamResolver(), ego_ids=("a",))


@pytest.mark.filterwarnings("ignore:.*vType car is not defined")
def test_a_gzipped_fcd_reads_as_the_plain_one_and_a_cut_one_up_to_its_cut(dense_run, tmp_path):
    """SUMO writes ``fcd.xml.gz`` when asked for that name; it was reported as a malformed FCD."""
    import gzip

    data = (dense_run / "fcd.xml").read_bytes()
    packed = tmp_path / "fcd.xml.gz"
    packed.write_bytes(gzip.compress(data))
    network = RoadNetwork.from_file(HIGHWAY)
    plain, unpacked = FcdReader(dense_run / "fcd.xml", network), FcdReader(packed, network)
    read = []  # bytes of each file read at every step (the audit's progress over the file's size on disk)
    for a, b in zip(plain, unpacked, strict=True):
        assert a.time == b.time and np.array_equal(a.ids, b.ids) and np.array_equal(a.x, b.x)
        read.append((plain.bytes_read, unpacked.bytes_read))
    for done, size in zip(np.array(read).T, (len(data), packed.stat().st_size)):
        assert np.all(np.diff(done) >= 0) and 0 < done[0] < size // 2 and 0.9 * size < done[-1] <= size
    cut = tmp_path / "cut.xml.gz"  # a gzip stream that breaks off: read up to its last complete time step
    cut.write_bytes(gzip.compress(data)[: packed.stat().st_size // 2])
    with pytest.warns(UserWarning, match=r"cut\.xml\.gz: the file breaks off after time step"):
        times = [snapshot.time for snapshot in FcdReader(cut, network)]
    assert 0 < len(times) < len(read) and times == [s.time for s, _ in zip(FcdReader(packed, network), times)]


@pytest.mark.filterwarnings("ignore:.*vType car is not defined")
def test_unevenly_spaced_time_steps_are_named_once(tmp_path):
    """A missing step (or another output period) changes what is judged and the derived accelerations."""
    fcd = tmp_path / "f.xml"
    steps = "".join(f'<timestep time="{t:.2f}">{_fcd_vehicle("a", 20.0 + 3.0 * t)}</timestep>'
                    for t in (0.0, 0.1, 0.3, 0.4, 0.7))
    fcd.write_text(f"<fcd-export>{steps}</fcd-export>")
    with pytest.warns(UserWarning, match=r"f\.xml: time step 0\.3 s comes 0\.2 s after the one before, where the "
                                         r"file's steps were 0\.1 s apart") as record:
        list(FcdReader(fcd, RoadNetwork.from_file(HIGHWAY)))
    assert sum("comes" in str(w.message) for w in record) == 1


def test_an_fcd_without_time_steps_is_named(tmp_path):
    """An FCD with its root and no step (SUMO run with begin after end, a wrong filter) gave '0 episodes' without
    a word."""
    fcd = tmp_path / "empty.xml"
    fcd.write_text("<fcd-export></fcd-export>")
    with pytest.warns(UserWarning, match=r"empty\.xml: no <timestep> in the file: nothing to audit"):
        result = audit_fcd(fcd, RoadNetwork.from_file(HIGHWAY), ParamResolver())
    assert result.episodes.empty


@pytest.mark.filterwarnings("ignore:.*vType car is not defined")
@pytest.mark.filterwarnings("ignore:.*positions are written with 1 decimals")
def test_persons_in_an_fcd_are_read_and_paired_with_the_vehicles(tmp_path):
    """Persons are road users of their own (rss.md §10): read beside the vehicles, not named as not audited. One
    walking on a road without a sidewalk (the highway's hw0) is on a vehicle lane: paired with the car on its edge
    (docs/rss.md, "Persons and bicycles": the jaywalking wedge)."""
    fcd = tmp_path / "f.xml"
    person = '<person id="p1" x="30.0" y="-8.0" angle="90" speed="1.2" pos="30.0" edge="hw0"/>'
    fcd.write_text("<fcd-export>" + "".join(f'<timestep time="{t:.2f}">{_fcd_vehicle("a", 20.0 + 3.0 * t)}{person}'
                                             "</timestep>" for t in (0.0, 0.1, 0.2)) + "</fcd-export>")
    snapshots = list(FcdReader(fcd, RoadNetwork.from_file(HIGHWAY)))
    assert [s.ids.tolist() for s in snapshots] == [["a"]] * 3
    assert [s.persons.ids.tolist() for s in snapshots] == [["p1"]] * 3
    assert snapshots[0].persons.speed.tolist() == [1.2] and snapshots[0].persons.edge_id.tolist() == ["hw0"]
    pair_steps = []
    with warnings.catch_warnings():
        warnings.filterwarnings("error", ".*not audited")
        audit_fcd(fcd, RoadNetwork.from_file(HIGHWAY), ParamResolver(),
                  on_progress=lambda p: pair_steps.append(p.pair_steps))
    assert pair_steps == [1, 2, 3]
