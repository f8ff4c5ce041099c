"""The command line end to end: run directories, resolved scenarios, FCD, batches, help texts."""
from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import replace

import pandas as pd
import pytest

from conftest import REPO, SCENARIOS, SHIPPED_SCENARIOS, run_cli, write_scenario
from sumo_rss import load_scenario
from sumo_rss.batch.runner import responsible_counts
from sumo_rss.cli import main


def test_run_writes_the_run_directory_with_fcd(tmp_path):
    proc = run_cli("run", str(SCENARIOS / "merge_onramp.toml"), "--seed", "3", "--duration", "40", "--out",
                   str(tmp_path), "--fcd", "--quiet")
    assert proc.returncode == 0, proc.stderr
    run_dir = tmp_path / "merge_onramp" / "3"
    assert str(run_dir) in proc.stdout
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["seed"] == 3 and summary["steps"] == 400 and summary["sim_time_s"] == pytest.approx(40.0)
    assert summary["vehicles_inserted"] >= 30 and summary["peak_vehicles"] >= 20
    assert summary["collisions"] == 0 and summary["teleports"] == 0 and summary["real_time_factor"] > 1
    assert summary["versions"]["sumo"] == "SUMO 1.28.0" and summary["versions"]["rss_model"]
    episodes = pd.read_csv(run_dir / "episodes.csv")
    assert summary["responsible_episodes"] == {k: int((episodes.responsible == k).sum())
                                               for k in ("a", "b", "both", "none")}
    # A value no episode has counts 0 (it was left out: a reader of summary["both"] failed).
    assert responsible_counts(episodes[episodes.responsible != "both"])["both"] == 0
    # FCD: every step, with accelerations and lateral position/speed of every vehicle.
    root = ET.parse(run_dir / "fcd.xml").getroot()
    steps = root.findall("timestep")
    assert len(steps) == 400
    vehicle = steps[-1].find("vehicle")
    assert {"acceleration", "posLat", "speedLat", "lane", "pos", "angle"} <= set(vehicle.attrib)
    assert not list(tmp_path.glob("merge_onramp/.*"))  # no partial folders left behind


def test_resolved_scenario_reloads_to_the_same_spec(tmp_path):
    assert main(["run", str(SCENARIOS / "intersection_tls.toml"), "--duration", "25", "--out", str(tmp_path),
                 "--quiet"]) == 0
    resolved = tmp_path / "intersection_tls" / "0" / "scenario.toml"
    original = load_scenario(SCENARIOS / "intersection_tls.toml").with_overrides(duration_s=25.0)
    again = load_scenario(resolved)
    assert replace(again, source=original.source) == original


@pytest.mark.parametrize("name", SHIPPED_SCENARIOS)
def test_every_shipped_scenario_round_trips(tmp_path, name):
    spec = load_scenario(SCENARIOS / f"{name}.toml")
    again = load_scenario(write_scenario(tmp_path, spec.to_toml_data()))
    assert replace(again, source=spec.source) == spec


@pytest.mark.parametrize("command", ["run", "batch", "audit", "report", "merge-gaps", "view", "nets"])
def test_every_command_has_help_with_examples(command):
    proc = run_cli(command, "--help")
    assert proc.returncode == 0 and "examples:" in proc.stdout and f"sumo-rss {command}" in proc.stdout


def test_version():
    proc = run_cli("--version")
    assert proc.returncode == 0 and proc.stdout.strip().startswith("sumo-rss 0.")
    # ``python -m sumo_rss.cli`` is the same command line (it ran nothing and exited 0).
    module = subprocess.run([sys.executable, "-m", "sumo_rss.cli", "--version"], capture_output=True, text=True,
                            cwd=REPO, check=False)
    assert module.returncode == 0 and module.stdout == proc.stdout


def test_same_scenario_and_seed_give_byte_identical_audit_csvs(tmp_path):
    for out in ("first", "second"):
        assert main(["run", str(SCENARIOS / "merge_onramp.toml"), "--seed", "7", "--duration", "60", "--out",
                     str(tmp_path / out), "--quiet"]) == 0
    runs = [tmp_path / out / "merge_onramp" / "7" for out in ("first", "second")]
    assert (runs[0] / "episodes.csv").read_bytes().count(b"\n") > 5
    for name in ("episodes.csv", "violations.csv", "collisions.csv", "rss_params.json", "routes.rou.xml"):
        assert (runs[0] / name).read_bytes() == (runs[1] / name).read_bytes(), name
    summaries = [json.loads((r / "summary.json").read_text()) for r in runs]
    for s in summaries:
        del s["wall_time_s"], s["real_time_factor"]
    assert summaries[0] == summaries[1]


@pytest.mark.slow
def test_the_planners_own_rss_preset_is_written_beside_the_auditors_parameters(tmp_path, valid_scenario):
    """With ``[ego.planner] rss_preset`` the parameters the planner judged RSS with were written nowhere."""
    valid_scenario.update(duration_s=3.0)
    valid_scenario["ego"].update(controller="epsilon", planner={"rss_preset": "epsilon"})
    proc = run_cli("run", str(write_scenario(tmp_path, valid_scenario)), "--out", str(tmp_path), "--quiet")
    assert proc.returncode == 0, proc.stderr
    run_dir = tmp_path / "scenario" / "1"
    planner = json.loads((run_dir / "planner.json").read_text())["rss_params"]
    audited = json.loads((run_dir / "rss_params.json").read_text())
    assert planner.keys() <= audited.keys() and "ego/ego_type" in planner
    for key, own in planner.items():  # rss.md's presets: epsilon for the planner, the scenario's ad_rss audited
        assert (own["response_time"], own["lon_brake_max"], own["lat_accel_max"]) == (0.2, 5.0, 1.0), key
        assert (audited[key]["response_time"], audited[key]["lon_brake_max"]) == (1.0, 8.0), key


@pytest.mark.slow
def test_controller_option_drives_the_ego_with_the_chosen_controller(tmp_path, valid_scenario):
    """``run --controller`` replaces the scenario's controller (recorded in the resolved scenario) and writes the
    run where a batch's controller sweep would, beside the scenario's own run; ``batch --controller`` sweeps
    controllers as variants; a scenario without an ego is refused with a clear error."""
    valid_scenario["duration_s"] = 12.0
    scenario = write_scenario(tmp_path, valid_scenario, "hw.toml")
    proc = run_cli("run", str(scenario), "--controller", "epsilon", "--out", str(tmp_path / "one"), "--quiet")
    assert proc.returncode == 0, proc.stderr
    run_dir = tmp_path / "one" / "hw__controller=epsilon" / "1"
    assert str(run_dir) in proc.stdout
    assert json.loads((run_dir / "summary.json").read_text())["run_id"] == "hw__controller=epsilon/1"
    assert load_scenario(run_dir / "scenario.toml").ego.controller == "epsilon"
    planner = json.loads((run_dir / "planner.json").read_text())
    assert planner["cycles"] >= 100  # the ego departs at 1 s and is planned for every step from then on
    assert "rss_params" not in planner  # it used the auditor's, those of rss_params.json
    proc = run_cli("batch", str(scenario), "--controller", "sumo", "mpdm", "--duration", "8", "--out",
                   str(tmp_path / "sweep"), "--quiet")
    assert proc.returncode == 0, proc.stderr
    for controller in ("sumo", "mpdm"):
        resolved = tmp_path / "sweep" / f"hw__controller={controller}" / "1" / "scenario.toml"
        assert load_scenario(resolved).ego.controller == controller
        assert load_scenario(resolved).duration_s == 8.0  # --duration of the batch
    assert not (tmp_path / "sweep" / "hw__controller=sumo" / "1" / "planner.json").exists()
    del valid_scenario["ego"]
    no_ego = write_scenario(tmp_path, valid_scenario, "no_ego.toml")
    proc = run_cli("run", str(no_ego), "--controller", "epsilon", "--out", str(tmp_path / "none"))
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"sumo-rss: error: {no_ego}: ego: expected an [ego] table: the scenario has no ego " \
                                  "to drive"
