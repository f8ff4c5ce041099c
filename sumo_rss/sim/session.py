"""Session: one libsumo co-simulation of a scenario, stepped by the caller.

libsumo runs SUMO inside this process and is a process-wide singleton, so only one Session may be open
per process at a time; a second one is refused with :class:`SessionError`. A session is always closed,
also when the code using it raises (use it as a context manager).
"""
from __future__ import annotations

import math
import shlex
import shutil
import signal
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import libsumo
import numpy as np
from libsumo import constants as tc

from ..errors import SessionError
from ..files import make_folder, write_text
from ..scenario import ScenarioSpec
from ..sumo_home import captured_stderr, error_lines, sumo_errors
from ..sumo_xml import ends_with_end_tag
from ..trajectory import Trajectory, TrajectoryState
from . import ego as ego_actuation
from .collisions import CollisionEvent, ContactTracker
from .demand import sumo_number, write_route_file
from .fcd_output import correct_placed_vehicle
from .person_feed import PersonFeed
from .snapshot import BACKGROUND_CLASS, BICYCLE_CLASS, EGO_CLASS, WorldSnapshot, compass_deg_to_heading

FCD_ATTRIBUTES = "id,x,y,angle,type,speed,acceleration,pos,lane,posLat,speedLat,signals,edge"  # edge: of persons
FCD_PRECISION = 6  # decimals in SUMO outputs written by a session (FCD, collisions). Snapshot values are rounded
# to the same decimals in SUMO's own units (m, degrees, m/s, m/s²), so an audit of the FCD file sees exactly the
# numbers the online audit saw.

_VARS = (tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED, tc.VAR_ACCELERATION, tc.VAR_SPEED_LAT, tc.VAR_LANE_ID,
         tc.VAR_ROAD_ID, tc.VAR_LANE_INDEX, tc.VAR_LANEPOSITION, tc.VAR_LANEPOSITION_LAT, tc.VAR_SIGNALS,
         tc.VAR_ROUTE_INDEX)

LANE_END_TOLERANCE = 0.01  # [m] a lane position this close to a lane's end is at its end (SUMO keeps 1 mm off it)

_active: Session | None = None


@contextmanager
def _signals_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait until the block ends, then Python's handlers get them. Arriving while SUMO loaded
    (``libsumo.start``), the second of two quick signals was lost in about 1 of 12 tries; held, in none of 36 on a
    quiet machine. (Two sent at once can still count as one under a heavy load, also while SUMO steps: 1 in 16.)"""
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def libsumo_in_use() -> bool:
    """Whether a Session holds this process's libsumo."""
    return _active is not None


@dataclass(frozen=True)
class _Static:
    """What does not change while a vehicle is on the road."""

    length: float
    width: float
    vtype: str
    vclass: str
    route: tuple[str, ...]


def sumo_arguments(spec: ScenarioSpec, route_file: Path, *, fcd_file: Path | None = None,
                   collision_file: Path | None = None, log_file: Path | None = None) -> list[str]:
    """The SUMO command line of a session (also written to the run directory for reproduction)."""
    s = spec.sumo
    route_files = ",".join([*map(str, spec.demand.route_files), str(route_file)])  # the user's vTypes first
    args = [
        "sumo", "--net-file", str(spec.net_file), "--route-files", route_files,
        "--begin", "0", "--end", sumo_number(spec.duration_s), "--step-length", sumo_number(spec.step_s),
        "--seed", str(spec.seed), "--lanechange.duration", sumo_number(s.lanechange_duration_s),
        "--collision.action", "warn", "--collision.check-junctions", "true",
        "--collision.mingap-factor", sumo_number(s.collision_mingap_factor),
        "--time-to-teleport", sumo_number(s.time_to_teleport_s) if s.time_to_teleport_s > 0 else "-1",
        "--no-step-log", "true", "--duration-log.disable", "true", "--precision", str(FCD_PRECISION),
    ]
    if s.additional_files:
        args += ["--additional-files", ",".join(map(str, s.additional_files))]
    if log_file is not None:
        args += ["--error-log", str(log_file)]
    else:
        args += ["--no-warnings", "true"]
    if fcd_file is not None:
        args += ["--fcd-output", str(fcd_file), "--fcd-output.attributes", FCD_ATTRIBUTES]
    if collision_file is not None:
        args += ["--collision-output", str(collision_file)]
    return args + list(s.extra_args)


def as_written(values: np.ndarray) -> np.ndarray:
    """``values`` rounded to FCD_PRECISION decimals as SUMO writes them: correctly rounded. ``np.round`` scales by
    10^6 and rounds, which differs near a tie (133.2633485 → 133.263348; SUMO writes 133.263349), so values near
    one are rounded one by one."""
    out = np.round(values, FCD_PRECISION)
    scaled = np.abs(values) * 10.0**FCD_PRECISION
    near = np.flatnonzero(np.abs(scaled - np.floor(scaled) - 0.5) < 1e-3)
    if near.size:
        out.flat[near] = [round(float(v), FCD_PRECISION) for v in values.flat[near]]
    return out


class Session:
    """A running co-simulation. ``step()`` advances by ``spec.step_s`` and returns the new snapshot.

    With ``run_dir`` the route file, SUMO's log and the requested SUMO outputs are written there; without it
    they go to a temporary folder removed on close.
    """

    def __init__(self, spec: ScenarioSpec, run_dir: Path | None = None, *, fcd: bool | None = None):
        self.spec = spec
        self.run_dir = Path(run_dir) if run_dir is not None else None
        self.write_fcd = spec.outputs.fcd if fcd is None else fcd
        self.ego_id = spec.ego.id if spec.ego is not None else None
        self.collisions: list[CollisionEvent] = []
        self.new_collisions: list[CollisionEvent] = []  # the contacts that began in the last step
        self.teleports = 0
        self.vehicles_inserted = 0
        self.peak_vehicles = 0
        self.steps = 0
        self.snapshot: WorldSnapshot | None = None
        self._static: dict[str, _Static] = {}
        self._persons = PersonFeed(as_written)
        self._contacts = ContactTracker()
        self._ego_controlled = False
        self._ego_released = False  # handed back to SUMO at the end of its route, to arrive
        self._ego_shadows: ego_actuation.LaneShadows | None = None
        self._lane_geometry: dict[str, tuple[float, float, tuple]] = {}  # lane → (offset [m], length [m], shape)
        self._ego_lateral: tuple[str, float, float] | None = None  # (edge, lateral position, speed) last step
        self._ego_speed: float | None = None  # [m/s] at the last step
        self._ego_derived: dict[float, tuple[float, float]] = {}  # time → (accel, lateral speed) of a placed ego
        self._step_ms = round(spec.step_s * 1000)
        self._signals: tuple[str, ...] = ()
        self._tmp: str | None = None
        self._open = False

    # -- lifecycle -----------------------------------------------------------------------------------------
    def __enter__(self) -> Session:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        global _active
        if _active is not None:
            raise SessionError("another Session is already open in this process; libsumo allows one "
                               "simulation per process: close it first or run in a separate process")
        out = self.run_dir
        if out is None:
            self._tmp = tempfile.mkdtemp(prefix="sumo_rss_")
            out = Path(self._tmp)
        make_folder(out)
        write_route_file(self.spec, out / "routes.rou.xml")

        def arguments(folder: Path) -> list[str]:
            return sumo_arguments(
                self.spec, folder / "routes.rou.xml",
                fcd_file=folder / "fcd.xml" if self.write_fcd else None,
                collision_file=folder / "collisions.xml" if self.spec.outputs.collisions_xml and self.run_dir
                else None,
                log_file=folder / "sumo.log" if self.run_dir else None)

        args = arguments(out)
        ego = self.spec.ego
        driven = ego is not None and ego.controller != "sumo"
        note = (f"; its ego is driven by the {ego.controller} planner through libsumo, so plain SUMO runs only the "
                "background traffic the same way until the ego departs" if driven else
                "; run it from this folder to reproduce the run with plain SUMO")
        write_text(out / "sumo_command.txt", f"# SUMO command line of this run{note}.\n"
                   + shlex.join(arguments(Path("."))) + "\n")
        _active = self
        try:
            with _signals_held(), captured_stderr() as printed:  # its load warnings are in sumo.log
                libsumo.start(args)
        except libsumo.TraCIException as exc:
            self.close()
            # libsumo's own message does not say which option
            reason = error_lines(printed) or sumo_errors(args[1:]) or str(exc)
            extra = f" (with the scenario's sumo.extra_args: {shlex.join(self.spec.sumo.extra_args)})" \
                if self.spec.sumo.extra_args else ""
            raise SessionError(f"SUMO refused to start scenario {self.spec.source}{extra}: {reason}") from exc
        self._open = True
        self._signals = tuple(libsumo.trafficlight.getIDList())

    def close(self) -> None:
        """Close SUMO (flushing its output files) and release the process-wide slot; idempotent."""
        global _active
        try:
            if self._open:
                self._open = False
                libsumo.close()
                fcd = self.run_dir / "fcd.xml" if self.write_fcd and self.run_dir is not None else None
                if self._ego_derived and fcd is not None and ends_with_end_tag(fcd, "fcd-export"):
                    correct_placed_vehicle(fcd, str(self.ego_id), self._ego_derived)
        finally:
            if _active is self:
                _active = None
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)
                self._tmp = None

    def check_outputs(self) -> None:
        """After :meth:`close`: that SUMO wrote its output files to their end, and logged no error. libsumo has no
        exit status, and SUMO does not notice a write that fails (a full disk, a file-size limit): its file just
        ends there. SessionError naming the file otherwise."""
        if self.run_dir is None:
            return
        outputs = {"fcd.xml": "fcd-export" if self.write_fcd else None,
                   "collisions.xml": "collisions" if self.spec.outputs.collisions_xml else None}
        for name, root in outputs.items():
            if root is not None and not (self.run_dir / name).is_file():
                raise SessionError(f"{self.run_dir / name}: SUMO's output is missing")
            if root is not None and not ends_with_end_tag(self.run_dir / name, root):
                raise SessionError(f"{self.run_dir / name}: SUMO's output ends before its end tag </{root}> (it "
                                   "could not write the whole file: disk full, or a file-size limit?)")
        log = self.run_dir / "sumo.log"
        errors = [line.strip() for line in log.read_text(encoding="utf-8", errors="replace").splitlines()
                  if line.startswith("Error")] if log.is_file() else []
        if errors:
            raise SessionError(f"{log}: SUMO reported an error during the run: {' '.join(errors)}")

    # -- stepping ------------------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Time stamp [s] of the current snapshot, as SUMO writes it in its outputs (−step before the first)."""
        return self.snapshot.time if self.snapshot is not None else -self.spec.step_s

    @property
    def finished(self) -> bool:
        """Whether ``duration_s`` has been simulated (``duration_s / step_s`` steps)."""
        return self.steps >= round(self.spec.duration_s / self.spec.step_s)

    def step(self) -> WorldSnapshot:
        if not self._open:
            raise SessionError("the session is not running; use it as 'with Session(spec) as s:'")
        try:
            libsumo.simulationStep()
        except (libsumo.FatalTraCIError, libsumo.TraCIException) as exc:  # SUMO has ended the run
            raise SessionError(f"SUMO stopped scenario {self.spec.source} at t = {self.time + self.spec.step_s:.2f} "
                               f"s: {exc}") from exc
        self.steps += 1
        # SUMO stamps the state a step produced with the step's start time in all its output files (FCD,
        # collisions); snapshots use the same stamp, from SUMO's integer milliseconds (exact decimals).
        time = (libsumo.simulation.getCurrentTime() - self._step_ms) / 1000.0
        self._persons.step()
        for vid in libsumo.simulation.getDepartedIDList():
            self._on_depart(vid)
        arrived = libsumo.simulation.getArrivedIDList()
        for vid in arrived:
            self._static.pop(vid, None)
        self.teleports += libsumo.simulation.getStartingTeleportNumber()
        self._record_collisions(time)
        was_on_road = self.ego_on_road
        self.snapshot = self._build_snapshot(time)
        if was_on_road and not self.ego_on_road and self.ego_id not in arrived:
            warnings.warn(f"{self.spec.source}: the ego {self.ego_id!r} left the road at t = {time:.2f} s without "
                          "arriving (a command placed it off every lane, or SUMO teleported it); it is neither "
                          "driven nor audited while off the road", stacklevel=2)
        self.peak_vehicles = max(self.peak_vehicles, len(self.snapshot))
        return self.snapshot

    def _on_depart(self, vid: str) -> None:
        v = libsumo.vehicle
        v.subscribe(vid, _VARS)
        self.vehicles_inserted += 1
        self._static[vid] = _Static(v.getLength(vid), v.getWidth(vid), v.getTypeID(vid),
                                    EGO_CLASS if vid == self.ego_id else BICYCLE_CLASS
                                    if v.getVehicleClass(vid) == "bicycle" else BACKGROUND_CLASS, tuple(v.getRoute(vid)))

    def _record_collisions(self, time: float) -> None:
        reports = [CollisionEvent(time, c.collider, c.victim, c.colliderType, c.victimType, c.colliderSpeed,
                                  c.victimSpeed, c.type, c.lane, c.pos) for c in libsumo.simulation.getCollisions()]
        self.new_collisions = self._contacts.step(reports)
        self.collisions.extend(self.new_collisions)

    def _build_snapshot(self, time: float) -> WorldSnapshot:
        results = libsumo.vehicle.getAllSubscriptionResults()
        ids = [vid for vid, r in results.items() if r[tc.VAR_LANE_ID]]  # '' while teleporting
        rows = [results[vid] for vid in ids]
        if self.ego_id in self._static and self._ego_controlled:  # moveToXY may have replaced its route
            self._static[self.ego_id] = _Static(**{**self._static[self.ego_id].__dict__,
                                                   "route": tuple(libsumo.vehicle.getRoute(self.ego_id))})
        static = [self._static[vid] for vid in ids]
        n = len(ids)

        def col(var: int, dtype: type = float) -> np.ndarray:
            values = np.fromiter((r[var] for r in rows), dtype=dtype, count=n)
            return as_written(values) if dtype is float else values

        xy = as_written(np.array([r[tc.VAR_POSITION] for r in rows], dtype=float).reshape(n, 2))
        lat_speed, accel, speed = col(tc.VAR_SPEED_LAT), col(tc.VAR_ACCELERATION), col(tc.VAR_SPEED)
        if self._ego_controlled and self.ego_id in ids:
            # SUMO reports neither for a vehicle placed by moveToXY: derive them from the placed states.
            k = ids.index(self.ego_id)
            lat_speed[k] = self._ego_lateral_speed(rows[k])
            previous = self._ego_speed if self._ego_speed is not None else speed[k]
            accel[k] = round((speed[k] - previous) / self.spec.step_s, FCD_PRECISION)
            if self.write_fcd:
                self._ego_derived[round(time, 3)] = (float(accel[k]), float(lat_speed[k]))
        if self.ego_id in ids:
            self._ego_speed = speed[ids.index(self.ego_id)]
        return WorldSnapshot(
            time=time, ids=np.array(ids, dtype=str), x=xy[:, 0], y=xy[:, 1],
            heading=compass_deg_to_heading(col(tc.VAR_ANGLE)), speed=speed, accel=accel, lat_speed=lat_speed,
            length=np.fromiter((s.length for s in static), float, n),
            width=np.fromiter((s.width for s in static), float, n),
            lane_id=np.array([r[tc.VAR_LANE_ID] for r in rows], dtype=str),
            edge_id=np.array([r[tc.VAR_ROAD_ID] for r in rows], dtype=str),
            lane_index=col(tc.VAR_LANE_INDEX, int), lane_pos=col(tc.VAR_LANEPOSITION),
            lat_pos=col(tc.VAR_LANEPOSITION_LAT),
            vclass=np.array([s.vclass for s in static], dtype=str),
            vtype=np.array([s.vtype for s in static], dtype=str),
            signals=col(tc.VAR_SIGNALS, int), route_index=col(tc.VAR_ROUTE_INDEX, int),
            route_edges=tuple(s.route for s in static),
            tls_states={tl: libsumo.trafficlight.getRedYellowGreenState(tl) for tl in self._signals} or None,
            persons=self._persons.snapshot())

    def _ego_lateral_speed(self, row: dict) -> float:
        """Lateral speed [m/s] (+ = left) of the ego while it is placed by moveToXY, for which SUMO reports 0:
        the change of its lateral position across its edge (lane offset + posLat) over the step; carried over
        the step on which it enters a new edge."""
        lane, edge = row[tc.VAR_LANE_ID], row[tc.VAR_ROAD_ID]
        geometry = self._lane_geometry.get(lane)
        if geometry is None:
            widths = [libsumo.lane.getWidth(f"{edge}_{k}") for k in range(libsumo.edge.getLaneNumber(edge))]
            index = row[tc.VAR_LANE_INDEX]
            geometry = self._lane_geometry[lane] = (sum(widths[:index]) + 0.5 * widths[index],
                                                    libsumo.lane.getLength(lane), tuple(libsumo.lane.getShape(lane)))
        offset, length, shape = geometry
        lat = row[tc.VAR_LANEPOSITION_LAT]
        pos = row[tc.VAR_LANEPOSITION]
        if pos >= length - LANE_END_TOLERANCE or pos <= LANE_END_TOLERANCE:
            # A bumper placed just past either end of the lane is kept on it, with the overshoot reported as its
            # lateral offset (8.6 mm past hw1's end: posLat -0.0086): the offset from the end segment's line.
            (ax, ay), (bx, by) = shape[-2:] if pos > LANE_END_TOLERANCE else shape[:2]
            x, y = row[tc.VAR_POSITION]
            lat = ((bx - ax) * (y - ay) - (by - ay) * (x - ax)) / math.hypot(bx - ax, by - ay)
        edge_lat = offset + lat
        previous = self._ego_lateral
        speed = (edge_lat - previous[1]) / self.spec.step_s if previous and previous[0] == edge else \
            (previous[2] if previous else 0.0)
        self._ego_lateral = (edge, edge_lat, speed)
        return round(speed, FCD_PRECISION)

    # -- ego -------------------------------------------------------------------------------------------------
    @property
    def ego_on_road(self) -> bool:
        return self.snapshot is not None and self.ego_id is not None and bool(np.any(self.snapshot.ids == self.ego_id))

    def drive_ego(self, trajectory: Trajectory) -> None:
        """Place the ego at ``trajectory``'s state for the end of the coming step (call before ``step()``).

        ``trajectory`` is in simulation time as the snapshots stamp it: the state at ``session.time + step_s``
        is taken (interpolated), and the next snapshot shows the ego exactly there. The first call hands the ego
        over from SUMO (speed mode 32, lane-change mode 0); from then on it goes exactly where the trajectory puts
        it, without feasibility checks, and background traffic reacts to it. The snapshot's acceleration and
        lateral speed of the ego are the changes of its speed and lateral position over the step (the
        trajectory's ``accel`` is not used for them). In a step without a call the ego keeps its speed along its
        lane; at the end of its route it is handed back to SUMO to arrive.
        """
        self.place_ego(trajectory.state_at(self.time + self.spec.step_s))

    def place_ego(self, state: TrajectoryState) -> None:
        """Place the ego at ``state`` at the end of the coming step (see :meth:`drive_ego`)."""
        if self.ego_id is None:
            raise SessionError(f"scenario {self.spec.source} has no [ego]")
        if not self.ego_on_road:
            raise SessionError(f"the ego {self.ego_id!r} is not on the road at t = {self.time:.2f} s")
        if self._ego_released:
            return
        _check_command(state, self.time)
        if self._ego_arriving(state):
            ego_actuation.release(self.ego_id)
            self._ego_controlled, self._ego_released = False, True
            return
        if not self._ego_controlled:
            ego_actuation.take_control(self.ego_id)
            self._ego_controlled = True
            self._ego_shadows = ego_actuation.LaneShadows(self.ego_id)
        self._ego_shadows.before_placing()
        ego_actuation.place(self.ego_id, state)

    def _ego_arriving(self, state: TrajectoryState) -> bool:
        """Whether the ego passes the end of its route's last edge in the coming step (moveToXY would hold it
        at the end of the network, or of a route that ends there, instead of letting it arrive)."""
        snap = self.snapshot
        k = snap.index_of(self.ego_id)
        if snap.edge_id[k] != self.spec.ego.route[-1]:  # the scenario's route: moveToXY may have replaced it
            return False
        remaining = libsumo.lane.getLength(str(snap.lane_id[k])) - float(snap.lane_pos[k])
        return remaining <= max(state.speed, float(snap.speed[k])) * self.spec.step_s


def _check_command(state: TrajectoryState, time: float) -> None:
    """Refuse an ego command SUMO would misread: a NaN position loses the ego, a negative speed hands it back."""
    if not isinstance(state, TrajectoryState):
        raise SessionError(f"the ego command at t = {time:.2f} s: expected a sumo_rss.trajectory.TrajectoryState, "
                           f"got {type(state).__name__}")
    values = (state.x, state.y, state.heading, state.speed, state.accel)
    if not all(math.isfinite(float(v)) for v in values) or state.speed < 0.0:
        raise SessionError(f"the ego command at t = {time:.2f} s: expected finite x, y, heading, accel and a speed "
                           f">= 0 m/s, got {state}")
