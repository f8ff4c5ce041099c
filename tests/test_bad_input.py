"""Damaged inputs, table-driven: each case writes one bad input (a scenario and what it names, a network, an FCD
plain or gzipped, a vType file, a collision file, a signal-state file, a batch folder, a report's CSVs, an output
folder) and runs the command line on it in this process (`main`, the same code path as `sumo-rss`). Every case
must end with exit code 2 and one line `sumo-rss: error: ...` that names the file and the field, with no traceback
and nothing written to the output folder (docs/outputs.md, "Bad input, full disks and interruptions")."""
from __future__ import annotations

import gzip
import signal
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
import tomli_w

from conftest import NETWORKS, VALID_SCENARIO
from sumo_rss.cli import main

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
TLS_NET = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
# A valid FCD on the highway: two cars in lane hw0_1, 20 m apart, at 3 m/s (SUMO's default attributes and posLat).
FCD_STEPS = [(0.0, 20.0, 40.0), (0.1, 20.3, 40.3), (0.2, 20.6, 40.6)]
ROUTES = ('<routes>\n    <vType id="car" length="4.5" width="1.8" tau="1.0" decel="4.5"/>\n'
          '    <route id="r" edges="hw0 hw1 hw2"/>\n'
          '    <vehicle id="a" type="car" route="r" depart="0"/>\n    <vehicle id="b" type="car" route="r" depart="0"/>\n'
          "</routes>\n")
TLS_STATES = ('<tlsStates>\n    <tlsState time="0.00" id="C" programID="fixed" phase="0" state="GGgrrrGGgrrr"/>\n'
              '    <tlsState time="30.00" id="C" programID="fixed" phase="1" state="yygrrryygrrr"/>\n</tlsStates>\n')


def fcd_text(every: dict[str, str] | None = None, **changed: str | None) -> str:
    """The valid FCD, with the attributes ``every`` added to every vehicle and the attributes ``changed`` of car a at
    0.1 s replaced (e.g. ``x="1e300"``; None: left out)."""
    steps = []
    for time, xa, xb in FCD_STEPS:
        cars = []
        for vid, x in (("a", xa), ("b", xb)):
            attributes = {"id": vid, "x": f"{x:.2f}", "y": "-5.25", "angle": "90.00", "type": "car", "speed": "3.00",
                          "pos": f"{x:.2f}", "lane": "hw0_1", "posLat": "0.00", **(every or {})}
            if vid == "a" and time == 0.1:
                attributes.update(changed)
            attributes = {k: v for k, v in attributes.items() if v is not None}
            cars.append("        <vehicle " + " ".join(f'{k}="{v}"' for k, v in attributes.items()) + "/>")
        steps.append(f'    <timestep time="{time:.2f}">\n' + "\n".join(cars) + "\n    </timestep>")
    return "<fcd-export>\n" + "\n".join(steps) + "\n</fcd-export>\n"


@dataclass(frozen=True)
class Case:
    """A damaged input: ``build(folder)`` writes it into ``folder`` and returns the command line; the one-line error
    must contain every text of ``named`` (the file, the element or column, what is expected)."""

    build: Callable[[Path], list[str]]
    named: tuple[str, ...]

    def __post_init__(self) -> None:
        assert isinstance(self.named, tuple), self.named  # ("x") is a string, whose letters any message has


def write(folder: Path, name: str, text: str | bytes) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def damaged_gzip(text: str) -> bytes:
    """``text`` gzipped, with bytes in the middle of its deflate stream overwritten (its header is whole)."""
    data = bytearray(gzip.compress(text.encode(), mtime=0))
    middle = len(data) // 2
    data[middle:middle + 8] = b"\xff" * 8
    return bytes(data)


def audit(fcd: str | bytes = fcd_text(), *, name: str = "f.xml", net: Path | None = None,
          routes: str | bytes | None = ROUTES, routes_name: str = "r.rou.xml", extra: tuple[str, ...] = ()
          ) -> Callable[[Path], list[str]]:
    """An audit of ``fcd`` (text, or bytes for a gzipped or damaged one) on the highway net (``net``: another
    network file, written by the case), with the vType file ``routes``."""
    def build(folder: Path) -> list[str]:
        argv = ["audit", str(write(folder, name, fcd)), "--net", str(net or HIGHWAY), "--out", str(folder / "out"),
                "--quiet"]
        if routes is not None:
            argv += ["--vtypes", str(write(folder, routes_name, routes))]
        return argv + [part.replace("{folder}", str(folder)) for part in extra]
    return build


def net_with(old: str, new: str, source: Path = HIGHWAY, count: int = 1) -> str:
    """A copy of ``source``'s text with ``old`` replaced by ``new`` (``count`` times; -1: everywhere)."""
    text = source.read_text(encoding="utf-8")
    assert old in text, old
    return text.replace(old, new, count)


def audit_on_net(net_text: str | bytes, name: str = "bad.net.xml") -> Callable[[Path], list[str]]:
    def build(folder: Path) -> list[str]:
        net = write(folder, name, net_text)
        return audit(net=net, routes=None)(folder)
    return build


def scenario(changes: dict | None = None, files: dict[str, str | bytes] | None = None, name: str = "s.toml",
             command: str = "run") -> Callable[[Path], list[str]]:
    """``sumo-rss run`` (or batch) of the valid scenario with ``changes`` (dotted keys; None values delete) and the
    ``files`` it names written beside it."""
    def build(folder: Path) -> list[str]:
        data = _copy(VALID_SCENARIO)
        for dotted, value in (changes or {}).items():
            *path, last = dotted.split(".")
            table = data
            for key in path:
                table = table.setdefault(key, {})
            table[last] = value
        for file_name, content in (files or {}).items():
            write(folder, file_name, content)
        toml = write(folder, name, tomli_w.dumps(data))
        return [command, str(toml), "--out", str(folder / "out"), "--quiet"]
    return build


def _copy(data: object) -> object:
    if isinstance(data, dict):
        return {k: _copy(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_copy(v) for v in data]
    return data


CASES: dict[str, Case] = {
    # -- scenario files and what they name -----------------------------------------------------------------------
    "scenario-network-missing": Case(scenario({"network": "nowhere.net.xml"}), ("s.toml", "network", "nowhere.net")),
    "scenario-network-is-routes": Case(scenario({"network": "r.net.xml"}, {"r.net.xml": ROUTES}),
                                       ("r.net.xml", "network", "root element <routes>, expected <net>")),
    "scenario-lanes-without-shape": Case(scenario({"network": "n.net.xml"}, {"n.net.xml": net_with(
        ' shape="0.00,-8.75 899.87,-8.75"', "")}), ("s.toml: network:", "n.net.xml", "<lane id='hw0_0'>", "shape")),
    "scenario-lane-length-not-a-number": Case(scenario({"network": "n.net.xml"}, {"n.net.xml": net_with(
        'length="899.87"', 'length="long"')}), ("n.net.xml", "<lane id='hw0_0'>", "length", "a finite number")),
    "scenario-connection-to-a-missing-lane": Case(scenario({"network": "n.net.xml"}, {"n.net.xml": net_with(
        'fromLane="2" toLane="2" via=":h1_0_2"', 'fromLane="2" toLane="7" via=":h1_0_2"')}),
        ("n.net.xml", "<connection from='hw0' to='hw1'>", "lane 7 of 'hw1'")),
    "scenario-signal-state-characters": Case(scenario({"network": "n.net.xml"}, {"n.net.xml": net_with(
        'state="GGgrrrGGgrrr"', 'state="GGgrrrGGgrrX"', TLS_NET)}), ("n.net.xml", "<tlLogic id='C'>: phase 1: state", "ruyYgGoOs")),
    "scenario-gzip-network-damaged": Case(scenario({"network": "n.net.xml.gz"}, {
        "n.net.xml.gz": damaged_gzip(HIGHWAY.read_text())}), ("n.net.xml.gz", "network", "not a readable SUMO network")),
    "scenario-route-file-missing": Case(scenario({"demand.route_files": ["mine.rou.xml"]}),
                                        ("s.toml", "demand.route_files[0]", "mine.rou.xml", "expected an existing")),
    "scenario-route-file-is-a-network": Case(scenario({"demand.route_files": ["n.net.xml"]}, {
        "n.net.xml": HIGHWAY.read_text()}), ("demand.route_files[0]", "n.net.xml", "has <net>")),
    "scenario-route-file-not-xml": Case(scenario({"demand.route_files": ["r.rou.xml"]}, {"r.rou.xml": "vehicles!"}),
                                        ("demand.route_files[0]", "r.rou.xml", "expected a readable SUMO XML file")),
    "scenario-route-file-comma": Case(scenario({"demand.route_files": ["a,b.rou.xml"]}, {"a,b.rou.xml": ROUTES}),
                                      ("demand.route_files[0]", "without ',' or ';'")),
    "scenario-additional-file-damaged-gzip": Case(scenario({"sumo.additional_files": ["a.add.xml.gz"]}, {
        "a.add.xml.gz": damaged_gzip("<additional>" + "<!-- padding -->" * 200 + "</additional>")}),
        ("sumo.additional_files[0]", "a.add.xml.gz", "expected a readable SUMO XML file")),
    "scenario-extra-args-unknown-option": Case(scenario({"sumo.extra_args": ["--max-depart-dealy", "5"]}),
                                               ("s.toml", "sumo.extra_args[0]", "--max-depart-dealy",
                                                "did you mean --max-depart-delay")),
    "scenario-extra-args-own-option": Case(scenario({"sumo.extra_args": ["-e", "100"]}),
                                           ("sumo.extra_args[0]", "set it with the scenario key duration_s")),
    "scenario-extra-args-value-sumo-refuses": Case(scenario({"sumo.extra_args": ["--max-depart-delay", "soon"]}),
                                                   ("s.toml", "sumo.extra_args: --max-depart-delay soon",
                                                    "Invalid Number Format")),
    "scenario-5000-digit-seed": Case(lambda folder: ["run", str(write(folder, "s.toml", 'network = "highway"\n'
                                                                      'duration_s = 10\nseed = ' + "9" * 5000)),
                                                     "--out", str(folder / "out")],
                                     ("s.toml: line 3: seed: expected a number of at most 4300 digits, got one of 5000 digits",)),
    "scenario-5000-character-name": Case(scenario({"name": "a/" * 2500}), ("s.toml", "name", "(5002 characters)")),
    "scenario-named-like-a-batch-file": Case(scenario({"name": "episodes.csv"}, command="batch"),
                                             ("s.toml", "name", "episodes.csv", "expected a name other than")),
    "scenario-negative-seeds-option": Case(lambda folder: scenario(command="batch")(folder) + ["--seeds", "-1,2"],
                                           ("--seeds", "expected a list of integers in [0,", "'-1,2'")),
    # -- networks given to an audit ------------------------------------------------------------------------------
    "network-lanes-without-shape": Case(audit_on_net(net_with(' shape="0.00,-5.25 899.87,-5.25"', "")),
                                        ("bad.net.xml", "<lane id='hw0_1'>", "shape", "at least two points")),
    "network-shape-1e300": Case(audit_on_net(net_with('shape="0.00,-5.25 899.87,-5.25"',
                                                      'shape="0.00,-5.25 1e300,-5.25"')),
                                ("bad.net.xml", "<lane id='hw0_1'>", "shape")),
    "network-lane-width-negative": Case(audit_on_net(net_with('width="3.50"', 'width="-3.50"')),
                                        ("bad.net.xml", "<lane id=':h1_0_0'>", "width", "> 0")),
    "network-junction-without-x": Case(audit_on_net(net_with('<junction id="h0" type="dead_end" x="0.00"',
                                                             '<junction id="h0" type="dead_end"')),
                                       ("bad.net.xml", "<junction id='h0'>", "x", "a finite number")),
    "network-connection-via-unknown-lane": Case(audit_on_net(net_with('via=":h1_0_0"', 'via=":h1_9_9"')),
                                                ("bad.net.xml", "<connection from='hw0' to='hw1'>", "via")),
    "network-empty-file": Case(audit_on_net(""), ("bad.net.xml", "not a readable SUMO network")),
    "network-gzip-damaged": Case(audit_on_net(damaged_gzip(HIGHWAY.read_text()), "bad.net.xml.gz"),
                                 ("bad.net.xml.gz", "not a readable SUMO network")),
    # -- vType files -----------------------------------------------------------------------------------------------
    "vtypes-root-is-fcd": Case(audit(routes=fcd_text()), ("r.rou.xml", "root element <fcd-export>",
                                                          "expected <routes> or <additional>")),
    "vtypes-not-xml": Case(audit(routes="vType car length=5"), ("r.rou.xml", "not a readable SUMO route/vType file")),
    "vtypes-gzip-damaged": Case(audit(routes=damaged_gzip(ROUTES * 20), routes_name="r.rou.xml.gz"),
                                ("r.rou.xml.gz", "not a readable SUMO route/vType file")),
    "vtypes-length-1e300-sumo-accepts": Case(audit(routes=ROUTES.replace('length="4.5"', 'length="1e300"')), (
        "r.rou.xml", "vType 'car': length: expected a number in [0.1, 2000] m")),
    "vtypes-decel-1e-300": Case(audit(routes=ROUTES.replace('decel="4.5"', 'decel="1e-300"')), (
        "r.rou.xml", "vType 'car': decel:")),
    "vtypes-length-sumo-refuses": Case(audit(routes=ROUTES.replace('length="4.5"', 'length="-4.5"')),
                                       ("r.rou.xml", "SUMO cannot load the vTypes")),
    # -- output folders --------------------------------------------------------------------------------------------
    "out-run-is-a-file": Case(lambda folder: scenario()(folder)[:2] + ["--out", str(write(folder, "o", "x"))],
                              ("--out must be a folder", "o is a file")),
    "out-audit-under-a-file": Case(lambda folder: audit()(folder) + ["--out", str(write(folder, "o", "x") / "sub")],
                                   ("--out", "o is a file (expected a folder there)")),
    "out-audit-csv-is-a-folder": Case(lambda folder: audit()(folder) + ["--out", str(
        (folder / "o" / "violations.csv").mkdir(parents=True) or folder / "o")],
        ("--out", "violations.csv is a folder (expected a file there")),
    "out-audit-npz-is-a-folder": Case(lambda folder: audit()(folder) + ["--out", str(
        (folder / "o" / "trajectories.npz").mkdir(parents=True) or folder / "o")],
        ("--out", "trajectories.npz is a folder (expected a file there")),
    "audit-fcd-is-a-folder": Case(lambda folder: [str((folder / "fdir").mkdir() or folder / "fdir")
                                                  if part.endswith("f.xml") else part for part in audit()(folder)],
                                  ("fdir: FCD file not found (a folder stands there",)),
    "scenario-is-a-folder": Case(lambda folder: ["run", str((folder / "s.toml").mkdir() or folder / "s.toml")], (
        "s.toml: scenario file not found (a folder stands there",)),
    "report-of-a-file": Case(lambda folder: ["report", str(write(folder, "b", "x")), "--quiet"], (
        "b: is a file (expected a batch folder",)),
    "out-train-intent-is-a-file": Case(lambda folder: ["train-intent", "--out", str(write(folder, "o", "x"))], (
        "--out must be a folder", "o is a file")),
    "out-batch-is-a-file": Case(lambda folder: scenario(command="batch")(folder)[:2] + ["--out", str(
        write(folder, "o", "x"))], ("--out must be a folder", "o is a file")),
}


TLS_FCD = ('<fcd-export>\n    <timestep time="0.00">\n        <vehicle id="a" x="200.00" y="4.80" angle="270.00" '
           'type="car" speed="10.00" pos="100.00" lane="E_in_0"/>\n    </timestep>\n</fcd-export>\n')
COLLISION = ('<collisions>\n    <collision time="0.10" type="collision" lane="hw0_1" pos="20.30" collider="{collider}" '
             'victim="{victim}" colliderType="car" victimType="car" colliderSpeed="3.00" victimSpeed="3.00"/>\n'
             "</collisions>\n")


def with_collisions(text: str, name: str = "c.xml") -> Callable[[Path], list[str]]:
    def build(folder: Path) -> list[str]:
        return audit()(folder) + ["--collisions", str(write(folder, name, text))]
    return build


def with_signal_states(text: str) -> Callable[[Path], list[str]]:
    """An audit on the signalised junction's net with the signal-state file ``text``."""
    def build(folder: Path) -> list[str]:
        return audit(TLS_FCD, net=TLS_NET, routes=None)(folder) + ["--tls-states", str(write(folder, "t.xml", text))]
    return build


def batch_file(text: str) -> Callable[[Path], list[str]]:
    def build(folder: Path) -> list[str]:
        scenario()(folder)  # s.toml beside it
        return ["batch", str(write(folder, "b.toml", text)), "--out", str(folder / "out"), "--quiet"]
    return build


# A batch folder as 'sumo-rss batch' writes it, one run with one episode, the ego's, traced (for report cases).
BATCH = {
    "batch_summary.csv": "run_id,scenario,variant,seed,status,ego_mean_speed_ms,error\nhw/0,hw,,0,ok,20.5,\n",
    "episodes.csv": "run_id,scenario,variant,seed,episode_key,vehicle_a,vehicle_b,class_a,class_b,episode_index,"
                    "situation,conflict_area,t_b_s,t_end_s,duration_s,trigger,owed_a,owed_b,responsible,"
                    "min_lon_margin_m,min_lat_margin_m,collision,collider,victim,ended_by\n"
                    "hw/0,hw,,0,car.1|ego|1,car.1,ego,background,ego,1,same-direction,,2.000000,3.000000,1.000000,"
                    "lon,lon:brake-at-most-max,lon:brake-min,b,-1.500000,-2.000000,False,,,safe\n",
    "violations.csv": "run_id,scenario,variant,seed,episode_key,vehicle_id,vehicle_class,role,constraint,bound,"
                      "worst_actual,excess,t_start_s,t_end_s\nhw/0,hw,,0,car.1|ego|1,ego,ego,rear,"
                      "lon-brake-after-response-time,-4.000000,-1.000000,3.000000,2.100000,3.000000\n",
    "collisions.csv": "run_id,scenario,variant,seed,time_s,collider,victim,sumo_type,blamed,episode_key\n",
    "pair_states.csv": "run_id,scenario,variant,seed,episode_key,time_s,lon_gap_m,lon_d_min_m,lat_gap_m,lat_d_min_m,"
                       "dangerous\nhw/0,hw,,0,car.1|ego|1,2.000000,10.000000,11.500000,-2.000000,0.300000,True\n"
                       "hw/0,hw,,0,car.1|ego|1,2.100000,9.000000,11.000000,-2.000000,0.300000,True\n",
    "hw/0/ego_trace.csv": "time_s,x_m,y_m,speed_ms,accel_ms2,lane_id,lane_pos_m,lat_pos_m\n"
                          "2.000000,10.0,-5.25,20.500000,0.0,hw0_1,10.0,0.0\n",
}


def report(**damaged: str | bytes) -> Callable[[Path], list[str]]:
    """``sumo-rss report`` of the batch folder BATCH with the files ``damaged`` (by name) replaced or added."""
    def build(folder: Path) -> list[str]:
        files = {**BATCH, **damaged}
        for name, text in files.items():
            if text is not None:
                write(folder / "batch", name, text)
        return ["report", str(folder / "batch"), "--quiet"]
    return build


def without_column(name: str, column: str) -> str:
    """BATCH's CSV ``name`` without ``column`` (header and cells)."""
    rows = [line.split(",") for line in BATCH[name].splitlines()]
    k = rows[0].index(column)
    return "".join(",".join(row[:k] + row[k + 1:]) + "\n" for row in rows)


def replaced(name: str, old: str, new: str) -> str:
    assert old in BATCH[name], old
    return BATCH[name].replace(old, new, 1)


CASES.update({
    # -- FCD files: values no vehicle can have, or that contradict the network; damage; structure -----------------
    "fcd-x-1e300": Case(audit(fcd_text(x="1e300")), ("f.xml, time step 0.1 s", "vehicle 'a'", "x:")),
    "fcd-speed-1e300": Case(audit(fcd_text(speed="1e300")), ("f.xml, time step 0.1 s", "vehicle 'a'", "speed:",
                                                             "at most 200 m/s")),
    "fcd-position-1e6-m-off-its-lane": Case(audit(fcd_text(y="1000000")), (
        "f.xml, time step 0.1 s", "vehicle 'a'", "x, y: expected a position on its lane 'hw0_1'")),
    "fcd-position-off-its-lane-without-pos": Case(audit(fcd_text(y="60", pos=None)), (
        "f.xml, time step 0.1 s", "vehicle 'a'", "x, y: expected a position on its lane")),
    "fcd-pos-past-the-lane-end": Case(audit(fcd_text(pos="5000")), ("f.xml", "vehicle 'a'", "pos:")),
    "fcd-posLat-50-m": Case(audit(fcd_text(posLat="50")), ("f.xml", "vehicle 'a'", "posLat:")),
    "fcd-acceleration-1e9": Case(audit(fcd_text({"acceleration": "0.00"}, acceleration="1e9")), (
        "f.xml", "vehicle 'a'", "acceleration:")),
    "fcd-speedLat-1e5": Case(audit(fcd_text({"speedLat": "0.00"}, speedLat="1e5")), ("f.xml", "vehicle 'a'",
                                                                                     "speedLat:")),
    "fcd-angle-1e300": Case(audit(fcd_text(angle="1e300")), ("f.xml", "vehicle 'a'", "angle:")),
    "fcd-signals-overflow": Case(audit(fcd_text(signals="99999999999999999999999")), (
        "f.xml, time step 0.1 s", "vehicle 'a'", "signals: expected an integer in [0, 2147483647] (SUMO's signal bits)",
        "got '99999999999999999999999'")),
    "fcd-signals-negative": Case(audit(fcd_text(signals="-1")), ("f.xml", "vehicle 'a'", "signals:", "[0, ")),
    "fcd-5000-digit-x": Case(audit(fcd_text(x="9" * 5000)), ("f.xml", "vehicle 'a'", "x:", "(5002 characters)")),
    "fcd-speed-nan": Case(audit(fcd_text(speed="nan")), ("f.xml", "vehicle 'a'", "speed: expected a finite number")),
    "fcd-unknown-lane": Case(audit(fcd_text(lane="nowhere_0")), ("f.xml, time step 0.1 s",
                                                                 "lanes not in highway.net.xml: nowhere_0", "--net")),
    "fcd-5000-character-lane": Case(audit(fcd_text(lane="l" * 5000)), ("f.xml", "lanes not in highway.net.xml",
                                                                       "(5000 characters)")),
    "fcd-vehicle-without-id": Case(audit(fcd_text(id=None)), ("f.xml, time step 0.1 s", "lacks the attribute 'id'")),
    "fcd-vehicle-twice": Case(audit(fcd_text(id="b")), ("f.xml, time step 0.1 s", "vehicle 'b' is listed more than once")),
    "fcd-time-nan": Case(audit(fcd_text().replace('time="0.10"', 'time="nan"')), (
        "f.xml", "<timestep> (after time step 0.0 s): time: expected a number of seconds")),
    "fcd-time-going-back": Case(audit(fcd_text().replace('time="0.20"', 'time="0.05"')), (
        "f.xml", "time step 0.05 s comes after 0.1 s: time: expected a time after the step before")),
    "fcd-time-steps-1-us-apart": Case(audit(fcd_text().replace('time="0.10"', 'time="0.000001"')), (
        "f.xml", "time: expected at least 0.001 s after the time step before")),
    "fcd-time-1e300": Case(audit(fcd_text().replace('time="0.20"', 'time="1e300"')), ("f.xml", "time: expected at most")),
    "fcd-root-is-routes": Case(audit(ROUTES), ("f.xml", "not an FCD file (root element <routes>, expected <fcd-export>)")),
    "fcd-damaged-inside": Case(audit(fcd_text().replace("</timestep>", "</timestap>", 2)), (
        "f.xml", "malformed or truncated FCD after time step 0.00 s")),
    "fcd-gzip-damaged-deflate-stream": Case(audit(damaged_gzip(fcd_text() * 30), name="f.xml.gz"), (
        "f.xml.gz", "malformed or truncated FCD")),
    "fcd-gzip-not-gzip": Case(audit(fcd_text(), name="f.xml.gz"), ("f.xml.gz", "malformed or truncated FCD",
                                                                    "Not a gzipped file")),
    "fcd-gzip-speed-1e300": Case(audit(gzip.compress(fcd_text(speed="1e300").encode()), name="f.xml.gz"), (
        "f.xml.gz, time step 0.1 s", "vehicle 'a'", "speed:")),
    "fcd-gzip-unknown-lane": Case(audit(gzip.compress(fcd_text(lane="x_0").encode()), name="f.xml.gz"), (
        "f.xml.gz, time step 0.1 s", "lanes not in highway.net.xml: x_0")),
    # -- collision files --------------------------------------------------------------------------------------------
    "collisions-collider-is-victim": Case(with_collisions(COLLISION.format(collider="a", victim="a")), (
        "c.xml: <collision> 1", "collider and victim are both 'a'")),
    "collisions-vehicle-not-in-the-fcd": Case(with_collisions(COLLISION.format(collider="a", victim="zz")), (
        "c.xml: <collision> at 0.1 s", "'zz' not in", "f.xml")),
    "collisions-time-nan": Case(with_collisions(COLLISION.format(collider="a", victim="b").replace(
        'time="0.10"', 'time="nan"')), ("c.xml: <collision> 1", "time='nan' is not a finite number")),
    "collisions-no-victim": Case(with_collisions(COLLISION.format(collider="a", victim="")), (
        "c.xml: <collision> 1", "attribute 'victim' is missing or empty")),
    "collisions-root-is-fcd": Case(with_collisions(fcd_text()), ("c.xml", "not a readable SUMO collision-output file",
                                                                 "expected <collisions>")),
    "collisions-gzip-damaged": Case(with_collisions(damaged_gzip(COLLISION.format(collider="a", victim="b") * 30),
                                                    "c.xml.gz"), ("c.xml.gz", "not a readable SUMO collision-output")),
    # -- signal-state files -----------------------------------------------------------------------------------------
    "signal-states-state-too-short": Case(with_signal_states(TLS_STATES.replace('"GGgrrrGGgrrr"', '"GGgrrr"')), (
        "t.xml: <tlsState> 1 (signal 'C')", "state: expected 12 characters", "(6 characters)")),
    "signal-states-invalid-characters": Case(with_signal_states(TLS_STATES.replace("GGgrrrGGgrrr", "GGgrrrGGgrXX")), (
        "t.xml: <tlsState> 1 (signal 'C')", "state:", "ruyYgGoOs")),
    "signal-states-time-nan": Case(with_signal_states(TLS_STATES.replace('time="30.00"', 'time="nan"')), (
        "t.xml: <tlsState> 2 (signal 'C')", "time: expected a number of seconds >= 0")),
    "signal-states-time-going-back": Case(with_signal_states(TLS_STATES.replace('time="30.00"', 'time="-5"')), (
        "t.xml: <tlsState> 2", "time: expected a number of seconds >= 0")),
    "signal-states-earlier-than-before": Case(with_signal_states(TLS_STATES.replace('time="0.00"', 'time="40.00"')), (
        "t.xml: <tlsState> 2 (signal 'C')", "time: expected no earlier than the signal's state before (40 s)")),
    "signal-states-of-another-net": Case(with_signal_states(TLS_STATES.replace('id="C"', 'id="J9"')), (
        "t.xml", "states of signal(s) J9 that", "does not have")),
    "signal-states-without-id": Case(with_signal_states(TLS_STATES.replace(' id="C"', "", 1)), (
        "t.xml: <tlsState> 1: id: expected the id of a signal of the network",)),
    "signal-states-root-is-fcd": Case(with_signal_states(fcd_text()), ("t.xml", "not a readable SUMO signal-state")),
    # -- batch files and folders ------------------------------------------------------------------------------------
    "batch-scenario-missing": Case(batch_file('[batch]\nscenarios = ["nope.toml"]\n'), (
        "b.toml", "batch.scenarios[0]", "expected an existing scenario file")),
    "batch-seeds-negative": Case(batch_file('[batch]\nscenarios = ["s.toml"]\nseeds = [-1]\n'), (
        "b.toml", "batch.seeds", "expected a list of integers in [0,")),
    "batch-grid-unknown-preset": Case(batch_file('[batch]\nscenarios = ["s.toml"]\n[batch.grid]\n'
                                                 'rss_preset = ["nope"]\n'), ("b.toml", "batch.grid.rss_preset")),
    "batch-the-same-scenario-twice": Case(batch_file('[batch]\nscenarios = ["s.toml", "./s.toml"]\n'), (
        "b.toml", "batch.scenarios", "distinct names")),
    # -- the report's inputs ----------------------------------------------------------------------------------------
    "report-episodes-column-missing": Case(report(**{"episodes.csv": without_column("episodes.csv", "responsible")}),
                                           ("episodes.csv", "column 'responsible' is missing")),
    "report-episodes-time-not-a-number": Case(report(**{"episodes.csv": replaced(
        "episodes.csv", "2.000000,3.000000", "two,3.000000")}), ("episodes.csv: line 2: column 't_b_s'",
                                                                 "expected a finite number, got 'two'")),
    "report-episodes-responsible-unknown": Case(report(**{"episodes.csv": replaced(
        "episodes.csv", "lon:brake-min,b,", "lon:brake-min,maybe,")}), ("episodes.csv: line 2: column 'responsible'",
                                                                         "expected one of a, b, both, none")),
    "report-pair-states-gap-not-a-number": Case(report(**{"pair_states.csv": replaced(
        "pair_states.csv", "9.000000,11.000000", "nine,11.000000")}), ("pair_states.csv: line 3: column 'lon_gap_m'",)),
    "report-violations-bound-inf": Case(report(**{"violations.csv": replaced(
        "violations.csv", "-4.000000", "-inf")}), ("violations.csv: line 2: column 'bound'",)),
    "report-summary-seed-not-a-number": Case(report(**{"batch_summary.csv": replaced(
        "batch_summary.csv", "hw,,0,ok", "hw,,zero,ok")}), ("batch_summary.csv: line 2: column 'seed'",)),
    "report-ego-trace-speed-not-a-number": Case(report(**{"hw/0/ego_trace.csv": BATCH["hw/0/ego_trace.csv"].replace(
        "20.500000", "fast")}), ("ego_trace.csv: line 2: column 'speed_ms'",)),
    "report-violations-not-a-csv": Case(report(**{"violations.csv": b"\x00\xff\xfe" * 50}), (
        "violations.csv: not a CSV file",)),
    "report-html-is-a-folder": Case(report(**{"report.html/x": "a file in a folder report.html"}), (
        "the batch folder", "report.html is a folder (expected a file there")),
    "report-figures-folder-is-a-file": Case(lambda folder: report(report="not a folder")(folder), (
        "batch/report: cannot be written", "report is a file (expected a folder there)")),
})


@pytest.fixture
def handlers():
    """The audit and run commands install Ctrl-C / SIGTERM handlers: put this process's back afterwards."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


def assert_one_line_error(code: int, err: str, named: tuple[str, ...]) -> str:
    """The command failed with exit code 2 and one line ``sumo-rss: error: ...`` naming every text of ``named``
    (warnings before it are lines of their own); no traceback, no line of any other kind."""
    lines = err.strip().splitlines()
    errors = [line for line in lines if line.startswith("sumo-rss: error: ")]
    assert code == 2 and len(errors) == 1 and lines[-1] == errors[0], err
    assert all(line.startswith(("sumo-rss: warning: ", "sumo-rss: error: ")) for line in lines), err
    assert "Traceback" not in err and len(errors[0]) < 700, err
    for text in named:
        assert text in errors[0], (text, errors[0])
    return errors[0]


def assert_refused(case: Case, folder: Path, capfd: pytest.CaptureFixture) -> None:
    """The command line of ``case``, built in ``folder``, fails with its one-line error and writes nothing."""
    argv = case.build(folder)
    before = sorted(p.relative_to(folder) for p in folder.rglob("*"))
    code = main(argv)
    assert_one_line_error(code, capfd.readouterr().err, case.named)
    assert sorted(p.relative_to(folder) for p in folder.rglob("*")) == before  # nothing written, nothing left


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_a_damaged_input_is_one_line_naming_the_file_and_field_and_leaves_nothing(case, tmp_path, capfd, handlers):
    assert_refused(CASES[case], tmp_path, capfd)


def test_the_valid_inputs_the_cases_damage_are_valid(tmp_path, capfd, handlers):
    """The control: the undamaged inputs are accepted (else the cases above would pass trivially)."""
    assert main(with_collisions(COLLISION.format(collider="a", victim="b"))(tmp_path / "audit")) == 0
    assert (tmp_path / "audit" / "out" / "episodes.csv").is_file()
    assert main(with_signal_states(TLS_STATES)(tmp_path / "tls")) == 0
    assert main(report()(tmp_path / "report")) == 0
    assert (tmp_path / "report" / "batch" / "report.html").is_file()
    assert main(scenario({"duration_s": 5.0})(tmp_path / "run")) == 0
    assert main(scenario({"duration_s": 5.0, "name": "b"}, command="batch")(tmp_path / "batch")) == 0
    assert "sumo-rss: error" not in capfd.readouterr().err
