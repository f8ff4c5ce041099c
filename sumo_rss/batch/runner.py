"""Run one scenario with one seed into its own run directory, written atomically."""
from __future__ import annotations

import json
import os
import platform
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import tomli_w

from .. import __version__
from ..errors import SumoRssError
from ..road.network import RoadNetwork
from ..rss.auditor import Auditor, CollisionInput, ParamResolver
from ..rss.params import MODEL_VERSION
from ..scenario import ScenarioSpec
from ..sim.demand import EGO_TYPE

SUMMARY_FILE = "summary.json"


@dataclass(frozen=True)
class RunSummary:
    """What ``summary.json`` holds for one run. Times in s."""

    scenario: str
    seed: int
    status: str  # 'ok'
    steps: int
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float  # simulated seconds per wall-clock second
    vehicles_inserted: int
    peak_vehicles: int
    collisions: int
    teleports: int
    episodes: int
    violations: int
    responsible_episodes: dict[str, int]  # responsible (a/b/both/none) → episodes
    ego_id: str | None
    ego_controller: str | None
    collision_events: list[dict] = field(default_factory=list)
    versions: dict[str, str] = field(default_factory=dict)


def param_resolver(spec: ScenarioSpec) -> ParamResolver:
    """The RSS parameters of a scenario, per vehicle class and vType."""
    dynamics = {vt.id: (vt.tau, vt.decel) for vt in spec.demand.vtypes}
    if spec.ego is not None:
        dynamics[EGO_TYPE] = (spec.ego.vehicle.tau, spec.ego.vehicle.decel)
    return ParamResolver(spec.rss.preset, spec.rss.role_overrides, spec.rss.vtype_overrides, dynamics)


def run_directory(out_dir: Path, spec: ScenarioSpec) -> Path:
    """``<out>/<scenario>/<seed>``."""
    return Path(out_dir) / spec.name / str(spec.seed)


def versions() -> dict[str, str]:
    import libsumo

    return {"sumo_rss": __version__, "rss_model": MODEL_VERSION, "sumo": libsumo.getVersion()[1],
            "python": platform.python_version()}


def run_one(spec: ScenarioSpec, out_dir: Path, *, fcd: bool | None = None,
            on_step: Callable[[float], None] | None = None) -> RunSummary:
    """Co-simulate ``spec`` (its own seed), audit every step and write ``<out>/<scenario>/<seed>/``.

    The run is built in a temporary sibling folder and renamed into place only when complete, so a run
    directory either holds a whole run or does not exist. ``on_step(simulated_s)`` is called after every step.
    """
    from ..sim.session import Session  # libsumo is only imported where a simulation runs

    if spec.ego is not None and spec.ego.controller != "sumo":
        raise SumoRssError(f"{spec.source}: ego.controller: {spec.ego.controller!r} needs the EPSILON planner, "
                           "which this version does not include yet; use controller = \"sumo\"")
    final = run_directory(out_dir, spec)
    final.parent.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=f".{spec.seed}.", suffix=".partial", dir=final.parent))
    try:
        (work / "scenario.toml").write_bytes(tomli_w.dumps(spec.to_toml_data()).encode("utf-8"))
        started = time.perf_counter()
        auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec), f"{spec.name}/{spec.seed}")
        with Session(spec, work, fcd=fcd) as session:
            while not session.finished:
                seen = len(session.collisions)
                snapshot = session.step()
                auditor.observe(snapshot, [CollisionInput(c.time, c.collider, c.victim, c.kind)
                                           for c in session.collisions[seen:]])
                if on_step is not None:
                    on_step(session.steps * spec.step_s)
        audit = auditor.finish()
        wall = time.perf_counter() - started
        simulated = session.steps * spec.step_s
        audit.to_csv(work)
        write_json(work / "rss_params.json", audit.params)
        summary = RunSummary(
            scenario=spec.name, seed=spec.seed, status="ok", steps=session.steps, sim_time_s=simulated,
            wall_time_s=wall, real_time_factor=simulated / wall if wall > 0 else float("inf"),
            vehicles_inserted=session.vehicles_inserted, peak_vehicles=session.peak_vehicles,
            collisions=len(session.collisions), teleports=session.teleports, ego_id=session.ego_id,
            episodes=len(audit.episodes), violations=len(audit.violations),
            responsible_episodes={k: int(v) for k, v in audit.episodes["responsible"].value_counts().sort_index().items()},
            ego_controller=spec.ego.controller if spec.ego else None,
            collision_events=[asdict(c) for c in session.collisions], versions=versions())
        write_json(work / SUMMARY_FILE, asdict(summary))
        _replace_dir(work, final)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return summary


def write_json(path: Path, data: object) -> None:
    """Write ``data`` as JSON atomically (temp file + rename)."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, path)


def _replace_dir(src: Path, dst: Path) -> None:
    """Move the finished ``src`` to ``dst``, replacing an older run there."""
    if dst.exists():
        trash = Path(tempfile.mkdtemp(prefix=f".{dst.name}.", suffix=".old", dir=dst.parent))
        os.replace(dst, trash / dst.name)
        os.replace(src, dst)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.replace(src, dst)
