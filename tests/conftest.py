"""Shared fixtures: paths of the shipped scenarios, a valid scenario to break one field at a time, and the
planning frame on the straight part of the highway net."""
from __future__ import annotations

import copy
import os
import subprocess
import sys
from pathlib import Path

import pytest
import tomli_w

from sumo_rss.planner.lanes import lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.model_cache import CACHE_ENV
from sumo_rss.road.network import RoadNetwork

REPO = Path(__file__).resolve().parent.parent
SCENARIOS = REPO / "scenarios"
NETWORKS = REPO / "networks"
SHIPPED_SCENARIOS = sorted(p.stem for p in SCENARIOS.glob("*.toml") if p.stem != "default")

# A small valid scenario on the 3-lane highway (geometry: lanes of 3.5 m; edge hw0 is 900 m long).
VALID_SCENARIO = {
    "network": "highway",
    "duration_s": 30.0,
    "seed": 1,
    "demand": {
        "vtypes": {"car": {"probability": 1.0, "length": 4.5, "width": 1.8}},
        "flows": [{"id": "main", "route": ["hw0", "hw1", "hw2"], "veh_per_hour": 1200}],
    },
    "ego": {"route": ["hw0", "hw1", "hw2"], "depart_s": 1.0, "depart_lane": 1, "depart_pos_m": 50.0,
            "depart_speed": 20.0, "desired_speed": 30.0},
    "rss": {"preset": "ad_rss"},
}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The tests marked slow first: pytest-xdist hands the first tests out to its workers in turn, so the long
    co-simulations start at once on both workers instead of one worker running the last of them alone."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@pytest.fixture(scope="session", autouse=True)
def road_model_cache(tmp_path_factory) -> Path:
    """The road model cache of this test session (a fresh folder; also for the commands tests start): tests never
    read a user's cache, nor depend on a warm one."""
    folder = tmp_path_factory.mktemp("road_model_cache")
    os.environ[CACHE_ENV] = str(folder)
    return folder


@pytest.fixture(scope="module")
def highway() -> tuple[RoadNetwork, RoadFrame]:
    """The highway net and the planning frame around its middle lane hw0_1 (lanes at y = -8.75 / -5.25 / -1.75,
    3.5 m apart; the frame's s runs along +x from the start of hw0)."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    frame = RoadFrame.build(lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1"])))
    return net, frame


@pytest.fixture
def valid_scenario() -> dict:
    return copy.deepcopy(VALID_SCENARIO)


def run_cli(*args: str, **options) -> subprocess.CompletedProcess:
    """``sumo-rss *args`` from the repository's root (its code, not an installed copy), output captured as text."""
    return subprocess.run([sys.executable, "-m", "sumo_rss", *args], capture_output=True, text=True, cwd=REPO,
                          check=False, **options)


@pytest.fixture(scope="module")
def dense_run(tmp_path_factory) -> Path:
    """The run folder of 60 s of highway_dense (seed 0) with its FCD, once per test module."""
    out = tmp_path_factory.mktemp("dense")
    proc = run_cli("run", str(SCENARIOS / "highway_dense.toml"), "--duration", "60", "--out", str(out), "--fcd",
                   "--quiet")
    assert proc.returncode == 0, proc.stderr
    return out / "highway_dense" / "0"


def write_scenario(folder: Path, data: dict, name: str = "scenario.toml") -> Path:
    path = folder / name
    path.write_bytes(tomli_w.dumps(data).encode("utf-8"))
    return path


def two_scenario_batch(folder: Path, data: dict, duration_s: float, seeds: str) -> Path:
    """Two highway scenarios of ``duration_s`` in ``folder``, light.toml (``data``'s demand) and busy.toml (3000
    veh/h), and batch.toml over ``seeds`` (TOML, e.g. "[0, 1]"); returns ``folder``."""
    data = copy.deepcopy(data)
    data["duration_s"] = duration_s
    write_scenario(folder, data, "light.toml")
    data["demand"]["flows"][0]["veh_per_hour"] = 3000
    write_scenario(folder, data, "busy.toml")
    (folder / "batch.toml").write_text(f'[batch]\nscenarios = ["light.toml", "busy.toml"]\nseeds = {seeds}\n')
    return folder


def audit_commanded(spec, setup, control, seconds: float, run_id: str = "test", routes: bool = True):
    """Co-simulate ``spec`` for ``seconds``, calling ``setup()`` once and ``control(time)`` before every step
    (libsumo commands), and audit every step; returns the AuditResult. ``routes=False`` audits the snapshots
    without the vehicles' routes, as an offline audit of an FCD file without its route file."""
    from dataclasses import replace

    from sumo_rss.batch.runner import param_resolver
    from sumo_rss.road.network import RoadNetwork
    from sumo_rss.rss.auditor import Auditor
    from sumo_rss.sim.session import Session

    auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec), run_id, evasive=spec.rss.evasive)
    with Session(spec) as session:
        setup()
        while session.steps < round(seconds / spec.step_s):
            control(session.time)
            snapshot = session.step() if routes else replace(session.step(), route_edges=None)
            auditor.observe(snapshot, session.new_collisions)
    return auditor.finish()
