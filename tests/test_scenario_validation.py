"""Bad scenario input: one valid base, one field broken per case; each error names file, key and form."""
from __future__ import annotations

import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import replace

import pytest

from conftest import REPO, write_scenario
from sumo_rss import ScenarioError, load_scenario
from sumo_rss.sim.demand import write_route_file


def _set(data: dict, dotted: str, value: object) -> None:
    keys = dotted.split(".")
    for key in keys[:-1]:
        data = data[int(key)] if isinstance(data, list) else data.setdefault(key, {})
    data[keys[-1]] = value


def _delete(data: dict, dotted: str) -> None:
    keys = dotted.split(".")
    for key in keys[:-1]:
        data = data[int(key)] if isinstance(data, list) else data[key]
    del data[keys[-1]]


# (case name, how to break the valid scenario, expected key path in the message, expected-form fragment)
BROKEN = [
    ("unknown top-level key", lambda d: _set(d, "netwrok", "highway"), "netwrok", "unknown key"),
    ("wrong type", lambda d: _set(d, "duration_s", "long"), "duration_s", "expected a number"),
    ("out of range step", lambda d: _set(d, "step_s", 5.0), "step_s", "in [0.001, 1]"),
    ("step not in whole ms", lambda d: _set(d, "step_s", 0.0125), "step_s", "a whole number of milliseconds"),
    ("duration between steps", lambda d: _set(d, "duration_s", 30.45), "duration_s",
     "a whole number of steps of step_s = 0.1 s (the run stops at a step), e.g. 30.4 or 30.5"),
    ("missing network", lambda d: _delete(d, "network"), "network", "required key is missing"),
    ("misspelt required key", lambda d: (_delete(d, "duration_s"), _set(d, "duraton_s", 30.0)), "duration_s",
     "required key is missing (did you mean 'duration_s' for 'duraton_s'?)"),
    ("unknown network", lambda d: _set(d, "network", "autobahn"), "network", "expected a network name"),
    ("missing net file", lambda d: _set(d, "network", "nowhere/x.net.xml"), "network", "existing .net.xml"),
    ("unknown rss preset", lambda d: _set(d, "rss.preset", "strict"), "rss.preset", "'ad_rss'"),
    ("unknown rss parameter", lambda d: _set(d, "rss.ego", {"reaction_time": 1.0}), "rss.ego.reaction_time",
     "unknown key"),
    ("rss brake ordering", lambda d: _set(d, "rss.background", {"lon_brake_min": 9.0}), "rss.background",
     "lon_brake_min_correct <= lon_brake_min <= lon_brake_max"),
    ("rss override of unknown vType", lambda d: _set(d, "rss.vtypes", {"bus": {"response_time": 2.0}}),
     "rss.vtypes.bus", "expected a vType of demand.vtypes"),
    ("both flow rates", lambda d: _set(d, "demand.flows.0.probability", 0.2), "demand.flows[0]",
     "exactly one of veh_per_hour, probability"),
    ("negative flow", lambda d: _set(d, "demand.flows.0.veh_per_hour", -5), "demand.flows[0].veh_per_hour",
     "expected a number in (0, 20000]"),
    ("edge not in net", lambda d: _set(d, "demand.flows.0.route", ["hw0", "hw9"]), "demand.flows[0].route[1]",
     "an edge of the network"),
    ("unconnected route", lambda d: _set(d, "demand.flows.0.route", ["hw0", "hw2"]), "demand.flows[0].route[1]",
     "reachable from 'hw0'"),
    ("lane index out of range", lambda d: _set(d, "ego.depart_lane", 3), "ego.depart_lane",
     "lane index 0..2 of 'hw0'"),
    ("sigma out of range", lambda d: _set(d, "demand.vtypes.car.sigma", 1.5), "demand.vtypes.car.sigma",
     "in [0, 1]"),
    ("emergency decel below decel", lambda d: _set(d, "demand.vtypes.car.emergency_decel", 2.0),
     "demand.vtypes.car.emergency_decel", ">= decel (4.5)"),
    ("unknown controller", lambda d: _set(d, "ego.controller", "autopilot"), "ego.controller", "'epsilon'"),
    # SUMO stops a run when a car departs faster than its vType or lane allows (hw0: 33.33 m/s).
    ("flow departs faster than a vType", lambda d: (_set(d, "demand.vtypes.car.max_speed", 25.0),
                                                    _set(d, "demand.flows.0.depart_speed", 30.0)),
     "demand.flows[0].depart_speed", "at most 25 m/s, the max_speed of vType 'car'"),
    ("flow departs above the limit", lambda d: _set(d, "demand.flows.0.depart_speed", 36.0),
     "demand.flows[0].depart_speed", "at most 33.33 m/s, speed_factor 1 x the speed limit of 'hw0'"),
    ("ego departs above its desired speed", lambda d: _set(d, "ego.depart_speed", 31.0), "ego.depart_speed",
     "at most 30 m/s, the ego's top speed under SUMO"),
    # A car's own limit is its speed factor x the lane's: SUMO stopped the run at the ego's insertion (t = 5 s).
    ("ego departs above its own limit", lambda d: (_set(d, "ego.depart_speed", 30.0),
                                                   _set(d, "ego.vehicle", {"speed_factor": 0.8})),
     "ego.depart_speed", "at most 26.664 m/s, speed_factor 0.8 x the speed limit of 'hw0'"),
    ("flow departs above its cars' own limit", lambda d: (_set(d, "demand.vtypes.car.speed_factor", 0.8),
                                                          _set(d, "demand.flows.0.depart_speed", 30.0)),
     "demand.flows[0].depart_speed", "at most 26.664 m/s, speed_factor 0.8 x the speed limit of 'hw0'"),
    ("ego departs after the end", lambda d: _set(d, "ego.depart_s", 40.0), "ego.depart_s",
     "before the end of the run"),
    ("boolean as number", lambda d: _set(d, "seed", True), "seed", "expected an integer"),
    ("outputs typo", lambda d: _set(d, "outputs", {"fcd_file": True}), "outputs.fcd_file", "unknown key"),
    ("unknown planner cost", lambda d: _set(d, "ego.planner.costs", {"overtake_bonus": 1.0}),
     "ego.planner.costs.overtake_bonus", "known keys here: beyond_horizon, blocked_by_leader"),
    ("negative planner cost", lambda d: _set(d, "ego.planner.costs", {"lane_change_left": -0.1}),
     "ego.planner.costs.lane_change_left", "expected a number >= 0"),
    ("planner discount above 1", lambda d: _set(d, "ego.planner.costs", {"discount": 1.5}),
     "ego.planner.costs.discount", "expected a number in (0, 1]"),
    ("misspelt flow rate", lambda d: (_delete(d, "demand.flows.0.veh_per_hour"),
                                      _set(d, "demand.flows.0.veh_per_hr", 600)),
     "demand.flows[0].veh_per_hour | probability", "did you mean 'veh_per_hour' for 'veh_per_hr'?"),
    ("misspelt rss parameter", lambda d: _set(d, "rss.background", {"lon_brake_mx": 6.0}),
     "rss.background.lon_brake_mx", "(did you mean 'lon_brake_max'?); known keys here: lat_accel_max"),
    ("unknown rss role", lambda d: _set(d, "rss.trucks", {"lon_brake_max": 6.0}), "rss.trucks",
     "known keys here: background, ego, evasive_effort, evasive_horizon_s, evasive_lookback_s, hold_standing"),
    ("rule 5 horizon of 0 s", lambda d: _set(d, "rss.evasive_horizon_s", 0.0), "rss.evasive_horizon_s",
     "expected a number in (0, 10]"),
    ("rule 5 look-back of 0 s", lambda d: _set(d, "rss.evasive_lookback_s", 0.0), "rss.evasive_lookback_s",
     "expected a number in (0, 60]"),
    ("ego named like a flow vehicle", lambda d: _set(d, "ego.id", "main.3"), "ego.id",
     "not a vehicle of flow 'main'"),
    ("reserved vType name", lambda d: _set(d, "demand.vtypes", {"ego_type": {"probability": 1.0}}),
     "demand.vtypes.ego_type", "the route file's own vType names"),
    ("no vType in the mix", lambda d: _set(d, "demand.vtypes.car.probability", 0.0), "demand.vtypes",
     "expected a vType with probability > 0 for the flows that draw from the mix (main)"),
    # The name is the folder of the scenario's runs: it must not lead out of the results folder.
    ("name leaving the results folder", lambda d: _set(d, "name", "../victim"), "name",
     "expected a name for the run folders: printable, not starting with '.', without '/'"),
    ("name of the results folder", lambda d: _set(d, "name", "."), "name", "not starting with '.'"),
    ("name with a comma", lambda d: _set(d, "name", "a,b"), "name", "without '/', '\\', ',' or ';'"),
    # Ids SUMO refuses, or that clash in the route file (route_<id>), are named here, not by SUMO at start-up.
    ("ego id with a space", lambda d: _set(d, "ego.id", "my ego"), "ego.id", "expected an id SUMO accepts"),
    ("flow id with markup", lambda d: _set(d, "demand.flows.0.id", 'a<b&"c'), "demand.flows[0].id",
     "none of | \\ ' \" ; , < > &"),
    ("vType id with a comma", lambda d: _set(d, "demand.vtypes", {"a,b": {"probability": 1.0}}),
     "demand.vtypes.a,b", "expected an id SUMO accepts"),
    ("ego id of a flow", lambda d: _set(d, "demand.flows.0.id", "ego"), "ego.id",
     "expected an id other than the flows' (each names its route route_<id> in the route file)"),
    # SUMO seeded from the clock: two runs of one scenario and seed differed.
    ("sumo --random", lambda d: _set(d, "sumo", {"extra_args": ["--max-depart-delay", "5", "--random"]}),
     "sumo.extra_args[2]", "expected no --random: the scenario's seed makes a run repeatable"),
    ("sumo --random=true", lambda d: _set(d, "sumo", {"extra_args": ["--random=true"]}), "sumo.extra_args[0]",
     "expected no --random"),
]


@pytest.mark.parametrize("case, breaker, key, expected", BROKEN, ids=[b[0] for b in BROKEN])
def test_broken_field_names_file_key_and_form(tmp_path, valid_scenario, case, breaker, key, expected):
    breaker(valid_scenario)
    path = write_scenario(tmp_path, valid_scenario)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {key}"), message
    assert expected in message, message


def test_rule5_settings_are_read_and_kept_in_the_written_scenario(tmp_path, valid_scenario):
    """Left at their defaults, the settings stay out of the scenario written next to a run (its hash as before)."""
    assert "evasive_horizon_s" not in load_scenario(write_scenario(tmp_path, valid_scenario)).to_toml_data()["rss"]
    _set(valid_scenario, "rss.evasive_horizon_s", 2.5)
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    assert (spec.rss.evasive.horizon_s, spec.rss.evasive.lookback_s) == (2.5, 5.0)
    assert spec.to_toml_data()["rss"]["evasive_horizon_s"] == 2.5


def test_the_valid_base_loads(tmp_path, valid_scenario):
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    assert spec.network == "highway" and spec.ego is not None and spec.ego.depart_lane == "1"
    assert spec.demand.flows[0].veh_per_hour == 1200.0


def test_a_file_saved_with_a_byte_order_mark_loads_as_without(tmp_path, valid_scenario):
    """Windows editors save UTF-8 with a BOM; it read as 'not valid TOML' at line 1, column 1."""
    plain = write_scenario(tmp_path, valid_scenario)
    marked = tmp_path / "marked.toml"
    marked.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    assert load_scenario(marked).to_toml_data() == load_scenario(plain).to_toml_data() | {"name": "marked"}


def test_planner_cost_weights_reach_the_planner_and_survive_the_resolved_scenario(tmp_path, valid_scenario):
    from sumo_rss.planner.driver import planner_config

    _set(valid_scenario, "ego.controller", "epsilon")
    _set(valid_scenario, "ego.planner.costs", {"leader_below_desired": 0.3, "discount": 0.8})
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    costs = planner_config(spec).costs
    assert (costs.leader_below_desired, costs.discount, costs.lane_change_left) == (0.3, 0.8, 0.015)
    again = load_scenario(write_scenario(tmp_path, spec.to_toml_data(), "resolved.toml"))
    assert again.ego.planner == spec.ego.planner


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(ScenarioError, match="scenario file not found"):
        load_scenario(tmp_path / "absent.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("network = \n", encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"bad\.toml: not valid TOML"):
        load_scenario(bad)


def test_cli_prints_one_line_and_exits_2(tmp_path, valid_scenario):
    valid_scenario["duration_s"] = -1.0
    path = write_scenario(tmp_path, valid_scenario)
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "run", str(path), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=REPO, check=False)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert lines == [f"sumo-rss: error: {path}: duration_s: expected a number in (0, 604800], got -1.0"]
    assert not (tmp_path / "out").exists()


def test_cli_debug_shows_the_traceback(tmp_path, valid_scenario):
    valid_scenario["network"] = "autobahn"
    path = write_scenario(tmp_path, valid_scenario)
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "--debug", "run", str(path)],
                          capture_output=True, text=True, cwd=REPO, check=False)
    assert proc.returncode != 0 and "Traceback" in proc.stderr and "ScenarioError" in proc.stderr


def test_the_documented_example_is_a_valid_scenario(tmp_path):
    text = (REPO / "docs" / "scenarios.md").read_text(encoding="utf-8")
    example = text.split("```toml\n", 1)[1].split("```", 1)[0]
    path = tmp_path / "example.toml"
    path.write_text(example, encoding="utf-8")
    spec = load_scenario(path)
    assert spec.name == "my_highway" and [v.id for v in spec.demand.vtypes] == ["car", "truck"]
    assert spec.demand.vtypes[0].lane_change_params == {"lcSpeedGain": 1.0, "lcKeepRight": 1.0}
    assert spec.rss.vtype_overrides == {"truck": {"lon_brake_max": 6.0}}


def test_a_flow_without_end_s_runs_until_the_end_of_the_run_also_after_a_duration_override(tmp_path,
                                                                                             valid_scenario):
    valid_scenario["demand"]["flows"].append({"id": "late", "route": ["hw0", "hw1", "hw2"], "veh_per_hour": 600,
                                              "begin_s": 20.0, "end_s": 25.0})
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    assert [f.end_s for f in spec.demand.flows] == [None, 25.0]
    longer = spec.with_overrides(duration_s=90.0)
    write_route_file(longer, tmp_path / "r.rou.xml")
    ends = {f.get("id"): f.get("end") for f in ET.parse(tmp_path / "r.rou.xml").getroot().iter("flow")}
    assert ends == {"main": "90", "late": "25"}
    resolved = write_scenario(tmp_path, longer.to_toml_data(), "resolved.toml")
    assert replace(load_scenario(resolved), source=longer.source) == longer  # end_s stays "until the end"
    with pytest.raises(ScenarioError, match=r"duration_s.*expected a number > the begin_s of flow 'main' \(10\)"):
        replace(spec, demand=replace(spec.demand, flows=(replace(spec.demand.flows[0], begin_s=10.0),))
                ).with_overrides(duration_s=5.0)


def test_a_vtype_with_probability_0_serves_only_the_flows_that_name_it(tmp_path, valid_scenario):
    valid_scenario["demand"]["vtypes"]["bus"] = {"probability": 0.0, "vclass": "bus", "length": 12.0}
    valid_scenario["demand"]["flows"].append({"id": "buses", "route": ["hw0", "hw1", "hw2"], "veh_per_hour": 120,
                                              "vtype": "bus"})
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    write_route_file(spec, tmp_path / "r.rou.xml")
    mix = ET.parse(tmp_path / "r.rou.xml").getroot().find("vTypeDistribution")
    assert {v.get("id"): v.get("probability") for v in mix} == {"car": "1", "bus": "0"}


@pytest.mark.parametrize("duration, message", [
    ("inf", "argument --duration: expected a finite number of seconds > 0, got 'inf'"),
    ("nan", "argument --duration: expected a finite number of seconds > 0, got 'nan'"),
    ("1e12", "{path}: duration_s override (e.g. --duration): expected a number <= 604800 (7 days), "
             "got 1000000000000.0"),
    ("0.5", "{path}: duration_s override (e.g. --duration): expected a number > ego.depart_s (1), got 0.5"),
    ("30.55", "{path}: duration_s override (e.g. --duration): expected a whole number of steps of step_s = 0.1 s "
              "(the run stops at a step), e.g. 30.5 or 30.6, got 30.55"),  # it ran 30.6 s (30.45: 30.4 s)
])
def test_a_bad_duration_option_is_refused_naming_the_option(tmp_path, valid_scenario, duration, message):
    """The scenario file is fine (its duration_s is 30 s): the error names the override, not the file's key."""
    path = write_scenario(tmp_path, valid_scenario)
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "run", str(path), "--duration", duration, "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, cwd=REPO, check=False)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].endswith(message.format(path=path))
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("override, message", [
    ({"seed": True}, "seed: expected an integer in [0, 2147483647], got True"),
    ({"seed": 3.7}, "seed: expected an integer in [0, 2147483647], got 3.7"),
    ({"duration_s": "60"}, "duration_s override (e.g. --duration): expected a number [s], got '60'"),
])
def test_overrides_from_python_are_checked_like_the_files_values(tmp_path, valid_scenario, override, message):
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    with pytest.raises(ScenarioError) as error:
        spec.with_overrides(**override)
    assert str(error.value).endswith(message)


def test_a_batch_file_given_as_a_scenario_says_so():
    with pytest.raises(ScenarioError, match=r"default\.toml: batch: expected a scenario file, not a batch file "
                                            r"\(\[batch\] table\): run it with 'sumo-rss batch'"):
        load_scenario(REPO / "scenarios" / "default.toml")


def _highway_without(tmp_path, vclass: str, edge: str = "hw1", lane: int | None = None):
    """The highway net with ``vclass`` disallowed on ``edge`` (all lanes, or only lane ``lane``)."""
    tree = ET.parse(REPO / "networks" / "highway" / "highway.net.xml")
    for element in tree.getroot().iter("lane"):
        if element.get("id").rsplit("_", 1)[0] == edge and lane in (None, int(element.get("index"))):
            element.set("disallow", vclass)
    path = tmp_path / f"no_{vclass}_{edge}_{lane}.net.xml"
    tree.write(path)
    return str(path)


@pytest.mark.parametrize("table, key, who", [("ego", "ego.route[1]", "the ego"),
                                             ("flow", "demand.flows[0].route[1]", "vType 'car'")])
def test_a_route_that_the_vehicle_class_may_not_drive_is_refused(tmp_path, valid_scenario, table, key, who):
    """SUMO stops a run (a traceback of libsumo's FatalTraCIError) at a vehicle whose vClass may not use a lane
    of its route: trucks on a motorway closed to trucks."""
    valid_scenario["network"] = _highway_without(tmp_path, "truck")
    if table == "ego":
        valid_scenario["ego"]["vehicle"] = {"vclass": "truck"}
    else:
        valid_scenario["demand"]["vtypes"]["car"]["vclass"] = "truck"
    with pytest.raises(ScenarioError, match=re.escape(f"{key}: expected an edge that {who} (vClass 'truck') may "
                                                      "reach from 'hw0' (no connection between lanes that permit "
                                                      "it), got 'hw1'")):
        load_scenario(write_scenario(tmp_path, valid_scenario))


def test_the_ego_departs_only_on_a_lane_that_its_class_may_use(tmp_path, valid_scenario):
    valid_scenario["ego"]["vehicle"] = {"vclass": "truck"}  # departs on lane 1 of hw0
    valid_scenario["network"] = _highway_without(tmp_path, "passenger", "hw0", lane=1)  # the flows use 0 and 2
    assert load_scenario(write_scenario(tmp_path, valid_scenario)).ego.vehicle.vclass == "truck"
    valid_scenario["network"] = _highway_without(tmp_path, "truck", "hw0", lane=1)
    with pytest.raises(ScenarioError, match=re.escape("ego.depart_lane: expected a lane of 'hw0' that the ego "
                                                      "(vClass 'truck') may use: 0, 2, got 1")):
        load_scenario(write_scenario(tmp_path, valid_scenario))
