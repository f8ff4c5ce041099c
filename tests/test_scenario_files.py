"""A user's own scenario on a real network: its own SUMO route file (gzipped, as SUMO reads it) and additional file
(a signal program of its own) as scenario keys, resolved relative to the scenario file whatever the shell's folder;
the run's sumo_command.txt re-runs it with plain SUMO from the run folder, paths with spaces included (issue 46,
items 8 and 9)."""
from __future__ import annotations

import gzip
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from conftest import REPO, run_cli, write_scenario
from sumo_rss import load_scenario
from sumo_rss.batch.spec import Task
from sumo_rss.sumo_home import sumo_home

FRAGMENT = REPO / "tests" / "data" / "braunschweig_signal" / "bs_signal.net.xml"
SIGNAL = "cluster_104171179_28142770_28298581_28298587"
ROUTES = """<routes>
    <vType id="bus" vClass="bus" length="12.5" width="2.4" tau="1.5" decel="3.0"/>
    <route id="WE" edges="166445412 23207363#0"/>
    <route id="NS" edges="4314834#2 4314834#3 29136063#0"/>
    <route id="SN" edges="166445406 166445405 23204862"/>
    <flow id="we" route="WE" begin="0" end="40" vehsPerHour="600"/>
    <flow id="ns" route="NS" begin="0" end="40" vehsPerHour="400" type="bus"/>
    <flow id="sn" route="SN" begin="0" end="40" vehsPerHour="400"/>
</routes>
"""
# A fixed-time program of the user's own (SUMO runs the program loaded last), and the signal states written.
PROGRAM = ("GGGGGrrrrrGGGGGrrrrr", "yyyyyrrrrryyyyyrrrrr", "rrrrrGGGGGrrrrrGGGGG", "rrrrryyyyyrrrrryyyyy")
ADDITIONAL = f"""<additional>
    <tlLogic id="{SIGNAL}" type="static" programID="mine" offset="0">
        <phase duration="15" state="{PROGRAM[0]}"/>
        <phase duration="3" state="{PROGRAM[1]}"/>
        <phase duration="15" state="{PROGRAM[2]}"/>
        <phase duration="3" state="{PROGRAM[3]}"/>
    </tlLogic>
    <timedEvent type="SaveTLSStates" dest="tls states.xml"/>
</additional>
"""


def _own_scenario(folder: Path) -> Path:
    """A scenario in ``folder`` (a space in its name): the fragment, a gzipped route file, an additional file."""
    (folder / "net").mkdir(parents=True)
    shutil.copy(FRAGMENT, folder / "net" / "bs signal.net.xml")
    (folder / "demand.rou.xml.gz").write_bytes(gzip.compress(ROUTES.encode(), mtime=0))
    (folder / "signals.add.xml").write_text(ADDITIONAL)
    return write_scenario(folder, {"network": "net/bs signal.net.xml", "duration_s": 30.0,
                                   "demand": {"route_files": ["demand.rou.xml.gz"]},
                                   "sumo": {"additional_files": ["signals.add.xml"]}}, "own.toml")


@pytest.fixture(scope="module")
def own_run(tmp_path_factory) -> tuple[Path, Path]:
    """The scenario and its run folder: run with --fcd from another folder than the scenario's, into a results
    folder with a space in its name."""
    root = tmp_path_factory.mktemp("own")
    scenario = _own_scenario(root / "my scenario")
    elsewhere = root / "elsewhere"
    elsewhere.mkdir()
    out = root / "results with spaces"
    proc = subprocess.run([sys.executable, "-m", "sumo_rss", "run", str(scenario), "--fcd", "--out", str(out),
                           "--quiet"], cwd=elsewhere, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert proc.returncode == 0, proc.stderr
    return scenario, out / "own" / "0"


def test_route_and_additional_files_are_resolved_from_the_scenario_file_and_run(own_run):
    scenario, run = own_run
    fcd = (run / "fcd.xml").read_text()
    assert 'id="ns.0"' in fcd and 'type="bus"' in fcd and 'id="sn.0"' in fcd  # the route file's flows ran
    # The additional file's program is the one SUMO ran: its saved states are the program's.
    states = (scenario.parent / "tls states.xml").read_text()
    assert all(f'state="{phase}"' in states for phase in PROGRAM[:3]) and 'programID="mine"' in states  # 30 s
    # The resolved scenario names the files by absolute path; loading it again gives the same spec.
    resolved = tomllib.loads((run / "scenario.toml").read_text())
    assert resolved["demand"]["route_files"] == [str(scenario.parent / "demand.rou.xml.gz")]
    assert resolved["sumo"]["additional_files"] == [str(scenario.parent / "signals.add.xml")]
    spec = load_scenario(scenario)
    assert load_scenario(run / "scenario.toml").demand == spec.demand
    # The route file's bus is audited with its own size (SUMO's reading of the file, as an offline audit's).
    assert "background/bus" in (run / "rss_params.json").read_text()


def test_sumo_command_txt_reruns_the_run_from_its_folder(own_run, tmp_path):
    _, run = own_run
    again = tmp_path / "again"
    shutil.copytree(run, again)
    for name in ("fcd.xml", "collisions.xml", "sumo.log"):
        (again / name).unlink()
    assert "'" in (run / "sumo_command.txt").read_text()  # the paths with spaces are quoted for the shell
    env = {**os.environ, "PATH": f"{sumo_home() / 'bin'}{os.pathsep}{os.environ['PATH']}"}
    proc = subprocess.run(["sh", "sumo_command.txt"], cwd=again, capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr

    def body(path: Path) -> str:  # without SUMO's header comment (its time and the command's own file names)
        text = path.read_text()
        return text[text.index("-->"):]

    assert body(again / "fcd.xml") == body(run / "fcd.xml") and body(again / "fcd.xml").count("<timestep") == 300


def test_a_gzipped_vtype_file_is_read_as_sumo_reads_it(own_run, tmp_path):
    """`audit --vtypes x.rou.xml.gz` was refused as not XML (issue 46, item 8); given the run's files, the offline
    audit is the online one."""
    scenario, run = own_run
    net = scenario.parent / "net" / "bs signal.net.xml"
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(net), "--vtypes",
                   f"{scenario.parent / 'demand.rou.xml.gz'},{run / 'routes.rou.xml'}", "--collisions",
                   str(run / "collisions.xml"), "--tls-states", str(scenario.parent / "tls states.xml"), "--out",
                   str(tmp_path / "offline"), "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert len(pd.read_csv(run / "episodes.csv")) > 0
    for name in ("episodes.csv", "violations.csv", "collisions.csv"):
        assert (tmp_path / "offline" / name).read_bytes() == (run / name).read_bytes(), name


def test_a_changed_route_file_reruns_the_batch_run(tmp_path):
    """The route and additional files count in a run's parameter hash by their content, as the network does."""
    own_scenario = _own_scenario(tmp_path / "s")
    before = Task(load_scenario(own_scenario), "").parameter_hash()
    route_file = own_scenario.parent / "demand.rou.xml.gz"
    route_file.write_bytes(gzip.compress(ROUTES.replace('vehsPerHour="600"', 'vehsPerHour="700"').encode(), mtime=0))
    assert Task(load_scenario(own_scenario), "").parameter_hash() != before
