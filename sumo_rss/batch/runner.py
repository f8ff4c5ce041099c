"""Run one task (scenario variant + seed) into its own run directory, written atomically.

A run directory ``<out>/<scenario>[__<variant>]/<seed>/`` holds: ``manifest.json`` (versions, seed, parameter
hash, and the size and SHA-256 of every other file of the folder: :mod:`~sumo_rss.batch.integrity`),
``summary.json``, the audit CSVs and ``rss_params.json``, ``ego_trace.csv``, ``pair_states.csv`` (the ego's episodes
step by step), ``episode_states.npz`` (every episode step by step) and ``trajectories.npz`` (the vehicles near the
ego, or all, per step: what ``sumo-rss view`` replays), the resolved ``scenario.toml``, the SUMO inputs/outputs and
logs.
"""
from __future__ import annotations

import csv
import fcntl
import os
import platform
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Protocol, TextIO

import pandas as pd
import tomli_w

from .. import __version__
from ..errors import ScenarioError, SumoRssError
from ..files import atomic_path, make_folder, output_error, write_json, write_text
from ..road.network import RoadNetwork
from ..rss.auditor import Auditor, ParamResolver
from ..rss.occlusion import read_occluders
from ..rss.params import MODEL_VERSION
from ..rss.records import RESPONSIBLE_VALUES
from ..scenario import ScenarioSpec
from ..sim.demand import EGO_TYPE
from ..sim.snapshot import EGO_CLASS, WorldSnapshot
from ..trajectory import TrajectoryState
from ..view.trajectories import NEAR_EGO_M, TRAJECTORY_FILE, TrajectoryRecorder
from .integrity import folder_files
from .spec import Task, variant_name

SUMMARY_FILE = "summary.json"
PLANNER_FILE = "planner.json"
MANIFEST_FILE = "manifest.json"
WRITER_LOCK = ".writer.lock"  # in a run's partial folder: locked (flock) while the run's process writes the folder
NEW_PARTIAL_S = 60.0  # [s] a starting folder younger than this without a writer lock may be a run just starting
PARTIAL_SUFFIX = ".partial"  # a run's folder while its process writes it (it holds the folder's writer lock)
STARTING_SUFFIX = ".starting"  # the same folder before its process took the lock (:func:`_work_folder`)
EGO_TRACE_COLUMNS = ("time_s", "x_m", "y_m", "speed_ms", "accel_ms2", "lane_id", "lane_pos_m", "lat_pos_m")


@dataclass(frozen=True)
class RunSummary:
    """What ``summary.json`` holds for one run. Times in s, speeds in m/s."""

    run_id: str
    scenario: str
    variant: str
    seed: int
    status: str  # 'ok'; 'interrupted': stopped early on request (run_one's ``stop``), audited up to there
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
    ego_responsible_episodes: int  # episodes in which the ego had a violation
    ego_mean_speed_ms: float | None  # over the steps the ego was on the road
    ego_id: str | None
    ego_controller: str | None
    collision_events: list[dict] = field(default_factory=list)
    versions: dict[str, str] = field(default_factory=dict)
    planner: dict | None = None  # planner runs: cycle times, backups, lane changes, guard interventions


def param_resolver(spec: ScenarioSpec) -> ParamResolver:
    """The RSS parameters of a scenario, per vehicle class and vType (those of its own SUMO files as SUMO resolves
    them, as an offline audit given those files reads them; this starts libsumo for a moment)."""
    dynamics = {}
    if spec.demand.route_files or spec.sumo.additional_files:
        from ..rss.fcd import read_vehicle_info

        dynamics = read_vehicle_info([*spec.sumo.additional_files, *spec.demand.route_files], spec.net_file).dynamics
    dynamics |= {vt.id: (vt.tau, vt.decel) for vt in spec.demand.vtypes}
    if spec.ego is not None:
        dynamics[EGO_TYPE] = (spec.ego.vehicle.tau, spec.ego.vehicle.decel)
    return ParamResolver(spec.rss.preset, spec.rss.role_overrides, spec.rss.vtype_overrides, dynamics,
                         spec.rss.hold_standing)


def run_directory(out_dir: Path, task: Task) -> Path:
    """``<out>/<scenario>[__<variant>]/<seed>``."""
    return Path(out_dir) / task.run_id


def versions() -> dict[str, str]:
    import libsumo

    return {"sumo_rss": __version__, "rss_model": MODEL_VERSION, "sumo": libsumo.getVersion()[1],
            "python": platform.python_version()}


class EgoController(Protocol):
    """Your own ego driver for :func:`run_one` (the EPSILON planner's ``EgoDriver`` is one)."""

    def command(self, snapshot: WorldSnapshot, auditor: Auditor) -> TrajectoryState | None:
        """Where the ego is at the end of the coming step (``snapshot.time + step_s``; e.g.
        ``trajectory.state_at(snapshot.time + step_s)``), from the current snapshot and the live audit
        (``auditor.owed_by(ego_id)``: the proper responses the ego owes now); None: SUMO's own models move it in
        this step (after any limits the controller set through libsumo, as ``sumo_restricted`` does)."""
        ...  # pragma: no cover


def responsible_counts(episodes: pd.DataFrame) -> dict[str, int]:
    """Episodes per value of ``responsible`` (a, b, both, none), every value present (0 where none)."""
    return {k: int((episodes["responsible"] == k).sum()) for k in RESPONSIBLE_VALUES}


def run_one(spec: ScenarioSpec, out_dir: Path, *, variant: str = "", fcd: bool | None = None,
            on_step: Callable[[float], None] | None = None, controller: EgoController | None = None,
            stop: Callable[[], bool] | None = None) -> RunSummary:
    """Co-simulate ``spec`` (its own seed), audit every step and write its run directory.

    The run is built in a temporary sibling folder and renamed into place only when complete, so a run
    directory either holds a whole run or does not exist. ``on_step(simulated_s)`` is called after every step.
    ``controller`` drives the ego instead of the scenario's ``ego.controller`` (recorded as 'custom'; without a
    ``variant`` the run is the variant 'controller=custom', so it never takes the folder of the scenario's own run);
    its ``summary()`` dict, if it has one, is written as planner.json. ``stop()`` is asked after every step: True
    ends the run there, and it is written as a whole run of that length with status 'interrupted' (a batch
    runs it again).
    """
    custom = None
    if controller is not None:
        if spec.ego is None:
            raise ScenarioError(spec.source, "ego", "expected an [ego] table: a controller needs an ego to drive",
                                has_got=False)
        if not callable(getattr(controller, "command", None)):
            raise TypeError(f"controller: expected an object with a method command(snapshot, auditor) -> "
                            f"TrajectoryState (sumo_rss.batch.runner.EgoController), got {controller!r}")
        custom = f"{type(controller).__module__}.{type(controller).__qualname__}"
        variant = variant or variant_name({"controller": "custom"})
    from ..sim.session import Session  # libsumo is only imported where a simulation runs
    from ..sim.vtypes import running_heights

    task = Task(spec, variant)
    final = run_directory(out_dir, task)
    created = [folder for folder in (final.parent, *final.parent.parents) if not folder.exists()]  # removed on failure
    work, writer = _work_folder(final, spec.seed)
    try:
        os.chmod(work, 0o777 & ~_umask())  # a folder like any other (mkdtemp's is private), also on a shared folder
        scenario_text = tomli_w.dumps(spec.to_toml_data())
        manifest = {"run_id": task.run_id, "scenario": spec.name, "variant": variant, "seed": spec.seed,
                    "parameter_hash": task.parameter_hash(custom), "versions": versions()}
        if custom is not None:
            scenario_text = (f"# The ego was driven by the Python controller {custom} (run_one(controller=...)), "
                             "not by ego.controller:\n# this file alone does not reproduce the run.\n"
                             + scenario_text)
            manifest["custom_controller"] = custom
        write_text(work / "scenario.toml", scenario_text)
        write_json(work / MANIFEST_FILE, manifest)
        started = time.perf_counter()
        network = RoadNetwork.from_file(spec.net_file)
        resolver = param_resolver(spec)
        auditor = Auditor(network, resolver, task.run_id, trace_class=EGO_CLASS, signal_rule=spec.rss.signal_rule,
                          raw_episodes=spec.rss.raw_episodes, junction_brake_min=spec.rss.junction_brake_min,
                          record_states=True, evasive=spec.rss.evasive, occlusion=spec.rss.occlusion,
                          occluders=read_occluders(spec.rss.occlusion.occluders) if spec.rss.occlusion.occluders
                          else None)
        every_vehicle = (spec.outputs.fcd if fcd is None else fcd) or spec.ego is None
        recorder = TrajectoryRecorder(spec.net_file, near_ego_m=None if every_vehicle else NEAR_EGO_M)
        driver = controller if controller is not None else _ego_driver(spec, network, resolver)
        report = getattr(driver, "summary", None)  # planner.json, and summary.json's 'planner'
        ego_rows = []
        interrupted = False
        with Session(spec, work, fcd=fcd) as session:
            if spec.rss.occlusion.enabled:
                auditor.set_heights(running_heights())
            while not session.finished:
                snapshot = session.step()
                auditor.observe(snapshot, session.new_collisions)
                recorder.add(snapshot)
                if session.ego_on_road:
                    k = snapshot.index_of(session.ego_id)
                    ego_rows.append((snapshot.time, snapshot.x[k], snapshot.y[k], snapshot.speed[k],
                                     snapshot.accel[k], snapshot.lane_id[k], snapshot.lane_pos[k],
                                     snapshot.lat_pos[k]))
                    if driver is not None and not session.finished:
                        command = driver.command(snapshot, auditor)
                        if command is not None:  # None: SUMO's own models move the ego (sumo_restricted)
                            session.place_ego(command)
                if on_step is not None:
                    on_step(session.steps * spec.step_s)
                if stop is not None and not session.finished and stop():
                    interrupted = True
                    break
        audit = auditor.finish()
        wall = time.perf_counter() - started
        simulated = round(session.steps * spec.step_s, 3)  # steps are whole ms: no float residue (30.400000000000002)
        if not (work / MANIFEST_FILE).is_file():  # its folder was removed meanwhile: what is written now is partial
            raise SumoRssError(f"{work}: the run's folder was removed while the run was writing it (by another "
                               "process); its results would be incomplete")
        session.check_outputs()
        audit.to_csv(work)
        recorder.write(work / TRAJECTORY_FILE)
        planner = report() if report is not None else None
        if planner is not None:
            write_json(work / PLANNER_FILE, planner)
        _write_ego_trace(work / "ego_trace.csv", ego_rows)
        episodes = audit.episodes
        ego_blamed = ((episodes.class_a == EGO_CLASS) & episodes.responsible.isin(["a", "both"])) | \
            ((episodes.class_b == EGO_CLASS) & episodes.responsible.isin(["b", "both"]))
        summary = RunSummary(
            run_id=task.run_id, scenario=spec.name, variant=variant, seed=spec.seed,
            status="interrupted" if interrupted else "ok",
            steps=session.steps, sim_time_s=simulated, wall_time_s=wall,
            real_time_factor=simulated / wall if wall > 0 else float("inf"),
            vehicles_inserted=session.vehicles_inserted, peak_vehicles=session.peak_vehicles,
            collisions=len(session.collisions), teleports=session.teleports, episodes=len(episodes),
            violations=len(audit.violations),
            responsible_episodes=responsible_counts(episodes),
            ego_responsible_episodes=int(ego_blamed.sum()),
            ego_mean_speed_ms=float(sum(r[3] for r in ego_rows) / len(ego_rows)) if ego_rows else None,
            ego_id=session.ego_id,
            ego_controller="custom" if controller is not None else spec.ego.controller if spec.ego else None,
            collision_events=[asdict(c) for c in session.collisions], versions=manifest["versions"],
            planner=planner)
        summary_data = asdict(summary)
        if audit.occluded_pair_steps:  # rule 4: only where cars could not see each other (summaries stay as they were)
            summary_data["occluded_pair_steps"] = audit.occluded_pair_steps
        write_json(work / SUMMARY_FILE, summary_data)
        manifest["files"] = folder_files(work, (MANIFEST_FILE, WRITER_LOCK))  # last: what a resume checks
        write_json(work / MANIFEST_FILE, manifest)
        _replace_dir(work, final)
        (final / WRITER_LOCK).unlink(missing_ok=True)  # once renamed: a partial folder without it would look dead
    except BaseException as exc:
        shutil.rmtree(work, ignore_errors=True)
        if isinstance(exc, SumoRssError) and exc.args and isinstance(exc.args[0], str):
            # the files it names as the run's folder has them (the hidden folder it was built in is gone)
            exc.args = (exc.args[0].replace(str(work), str(final)), *exc.args[1:])
        for folder in created:  # a failed run leaves no empty folders behind (a batch records its failure)
            try:
                folder.rmdir()
            except OSError:  # not empty (another run's), or gone
                break
        raise
    finally:
        writer.close()
    return summary


def _work_folder(final: Path, seed: int) -> tuple[Path, TextIO]:
    """A new hidden ``.<seed>.*.partial`` folder beside ``final`` (its parents made as needed) to build the run in,
    and its writer lock, held (a batch cleaning up dead runs' folders leaves it alone). The folder is made as
    ``.<seed>.*.starting`` and renamed once its lock is held, so that a ``.partial`` folder without a held lock
    is always a dead run's, however soon after its creation the run was killed. Tried again where a failing run
    of the same scenario removed the empty parent meanwhile."""
    attempts = 3
    while True:
        make_folder(final.parent)
        try:
            starting = Path(tempfile.mkdtemp(prefix=f".{seed}.", suffix=STARTING_SUFFIX, dir=final.parent))
            break
        except FileNotFoundError as exc:
            attempts -= 1
            if not attempts:
                raise output_error(final.parent, exc) from None
        except OSError as exc:
            raise output_error(final.parent, exc) from None
    work = starting.with_name(starting.name[:-len(STARTING_SUFFIX)] + PARTIAL_SUFFIX)
    writer = None
    try:
        writer = (starting / WRITER_LOCK).open("w")
        fcntl.flock(writer, fcntl.LOCK_EX)
        starting.rename(work)  # the lock stays held: it is on the file, which moves with its folder
    except BaseException as exc:
        if writer is not None:
            writer.close()
        shutil.rmtree(starting, ignore_errors=True)
        if isinstance(exc, OSError):
            raise output_error(final.parent, exc) from None
        raise
    return work, writer


def partial_run_is_live(partial: Path) -> bool:
    """Whether a run's process may still be writing the ``.partial`` or ``.starting`` folder: it holds the folder's
    writer lock, or the folder is a ``.starting`` one too new to have one yet (a run takes it right after creating
    the folder). A ``.partial`` folder without its lock file is a dead run's (:func:`_work_folder`)."""
    try:
        fh = (partial / WRITER_LOCK).open("r")
    except FileNotFoundError:  # a run that died before it took the lock, unless it is just starting
        if not partial.name.endswith(STARTING_SUFFIX):
            return False
        try:
            return time.time() - partial.stat().st_mtime < NEW_PARTIAL_S
        except OSError:  # the folder is gone
            return False
    with fh:
        try:  # shared: an exclusive lock needs a file open for writing on NFS, where Ray's shared folders live
            fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:  # held by the run (or locks unavailable: keep the folder rather than risk a live run)
            return True
    return False


def _ego_driver(spec: ScenarioSpec, network: RoadNetwork, resolver: ParamResolver):
    """The planner driving the ego (None when SUMO drives it; the RSS restrictor of SUMO's models for
    sumo_restricted). The planner judges RSS with the scenario's parameters unless ``[ego.planner] rss_preset``
    names another preset; the guard always uses the auditor's."""
    if spec.ego is None or spec.ego.controller == "sumo":
        return None
    if spec.ego.controller == "sumo_restricted":
        from ..planner.restricted import RestrictedSumoDriver

        return RestrictedSumoDriver(spec, network, resolver)
    from ..planner.driver import EgoDriver

    preset = spec.ego.planner.rss_preset
    planner_params = resolver if preset is None else ParamResolver(preset, {}, {}, resolver.vtype_dynamics,
                                                                   resolver.hold_standing)
    return EgoDriver(spec, network, resolver, planner_params)


def _write_ego_trace(path: Path, rows: list[tuple]) -> None:
    with atomic_path(path) as tmp, tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(EGO_TRACE_COLUMNS)
        writer.writerows((f"{t:.6f}", f"{x:.6f}", f"{y:.6f}", f"{v:.6f}", f"{a:.6f}", lane, f"{pos:.6f}",
                          f"{lat:.6f}") for t, x, y, v, a, lane, pos, lat in rows)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _replace_dir(src: Path, dst: Path) -> None:
    """Move the finished ``src`` to ``dst``, replacing an older run there."""
    if dst.exists():
        trash = Path(tempfile.mkdtemp(prefix=f".{dst.name}.", suffix=".old", dir=dst.parent))
        os.replace(dst, trash / dst.name)
        os.replace(src, dst)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.replace(src, dst)
