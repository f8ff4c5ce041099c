"""Offline audits: SUMO FCD files → WorldSnapshot stream → the same auditor as online.

The FCD file is streamed (:mod:`.fcd_parse`) and every ``<timestep>`` is dropped once read, so memory does not
grow with the file. Missing attributes are derived: accelerations from speed differences, lane position and
lateral offset from x, y and the lane shapes, lateral speeds from lateral-position differences on one edge.
Vehicle sizes come from a vType/route file or SUMO's defaults; collisions from SUMO's collision-output file.
"""
from __future__ import annotations

import functools
import itertools
import math
import warnings
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..boxes import boxes_overlap
from ..errors import SumoRssError, cut, listed, shown
from ..road.network import RoadNetwork, UnknownLaneError
from ..sim.collisions import CollisionEvent, ContactTracker
from ..sim.demand import EGO_TYPE
from ..sim.snapshot import BACKGROUND_CLASS, BICYCLE_CLASS, EGO_CLASS, WorldSnapshot, compass_deg_to_heading
from ..sumo_home import vtype_attribute_names
from ..sumo_xml import MALFORMED, bytes_consumed, ends_cut, open_output, output_elements
from .auditor import AuditResult, Auditor, ParamResolver
from .params import EvasiveParams
from .occlusion import OccluderEdges, OcclusionParams
from .fcd_checks import SIGNALS_FORM, StepValues, check_step, pedestrian_lanes, warn_on_walkways
from .fcd_parse import FcdParser, FcdStep
from .fcd_persons import check_distinct_ids, check_person_edges, person_snapshot
from .numbering import Numbering
from .record_checks import (check_collision_record, check_collisions_in_fcd, warn_late_signal_states,
                            warn_without_signal_states)
from .signals import SignalStates
from .situations import FIRST_INTERSECTION_CODE, SAME_DIRECTION_CODES, PairSituations, against_lane, body_poses

JUMP_SPEED = 5.0  # [m/s] lateral motion faster than this between two FCD steps is a lane change done in one step
CENTRED = 0.05  # [m] a car this close to its lane's centre line at two steps, in another lane, jumped between them
FINE_DECIMALS = 6  # positions written with this many decimals (sumo --precision 6) give exact lateral speeds
# What the reader remembers of a car from the step before (FcdReader._prev), and what it takes for one not seen then:
# speed [m/s], edge, lane, lateral position in the lane (off-centre) and across the edge [m], lateral speed [m/s].
_UNSEEN = (0.0, -1, -1, 1.0, 0.0, 0.0)
SUMO_DEFAULT_SIZE = (5.0, 1.8)  # [m] length, width of SUMO's default passenger vType (for vTypes SUMO was not given)
NEEDED_ATTRIBUTES = ("needed: id, x, y, angle, speed, lane; SUMO writes them by default, and with "
                     "--fcd-output.attributes they must be listed")
STEP_TIME_TOLERANCE = 1e-6  # [s] a report at a step's time (both written with SUMO's few decimals) belongs to it


class FcdError(SumoRssError):
    """An FCD, vType or collision file cannot be audited."""


@dataclass
class VehicleInfo:
    """What a route file tells about vehicles: vType sizes and dynamics, and routes by vehicle or flow id."""

    sizes: dict[str, tuple[float, float]] = field(default_factory=dict)  # vType → (length, width) [m]
    dynamics: dict[str, tuple[float, float]] = field(default_factory=dict)  # vType → (tau [s], decel [m/s²])
    routes: dict[str, tuple[str, ...]] = field(default_factory=dict)  # vehicle or flow id → edges
    types: dict[str, str] = field(default_factory=dict)  # vehicle or flow id → vType (for an FCD without 'type')
    bicycles: frozenset[str] = frozenset({"DEFAULT_BIKETYPE"})  # vTypes of SUMO vClass bicycle
    heights: dict[str, float] = field(default_factory=dict)  # vType → height [m] (rule 4)

    def route_of(self, vehicle_id: str) -> tuple[str, ...] | None:
        """The route of a vehicle, or of the flow that made it (``flow.k``); None if unknown."""
        return _of_vehicle(self.routes, vehicle_id)

    def type_of(self, vehicle_id: str) -> str | None:
        """The vType of a vehicle, or of the flow that made it (``flow.k``); None if unknown."""
        return _of_vehicle(self.types, vehicle_id)


def _of_vehicle(table: dict, vehicle_id: str):
    """``table``'s entry for a vehicle, or for the flow that made it (``flow.k``); None if neither has one."""
    if vehicle_id in table:
        return table[vehicle_id]
    flow = vehicle_id.rsplit(".", 1)[0]
    return table.get(flow) if flow != vehicle_id else None


def read_vehicle_info(paths: Path | Sequence[Path] | None, net_file: Path) -> VehicleInfo:
    """Sizes and dynamics of every vType as SUMO resolves them (:func:`~sumo_rss.sim.vtypes.sumo_vtypes`: SUMO's
    built-in types and the vTypes of the route/additional file(s) ``paths``, with SUMO's vClass defaults for what
    they leave out), and the routes of the files' vehicles and flows (a named route, also one of an earlier file,
    or one written inside them)."""
    from ..sim.vtypes import sumo_vtypes  # libsumo is only imported where SUMO runs

    files = [] if paths is None else [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]
    documents = []
    for path in files:  # gzipped (*.rou.xml.gz) as SUMO reads them
        try:
            with open_output(path) as source:
                documents.append(ET.parse(source).getroot())
        except MALFORMED as exc:
            raise FcdError(f"{path}: not a readable SUMO route/vType file ({exc})") from exc
        if documents[-1].tag not in ("routes", "additional"):
            raise FcdError(f"{path}: not a SUMO route/vType file (root element <{documents[-1].tag}>, expected "
                           "<routes> or <additional>)")
    known = vtype_attribute_names() | {"id"}
    for path, document in zip(files, documents):
        for vtype in document.iter("vType"):
            unknown = sorted(set(vtype.attrib) - known)
            if unknown:
                warnings.warn(f"{path}: vType {shown(vtype.get('id', '?'))}: unknown attribute(s) {listed(unknown)}, "
                              "which SUMO ignores (a typo?)", stacklevel=2)
    try:
        types = sumo_vtypes(net_file, documents, ", ".join(str(p) for p in files))
    except ValueError as exc:
        raise FcdError(str(exc)) from exc
    info = VehicleInfo({t: (p.length, p.width) for t, p in types.items()},
                       {t: (p.tau, p.decel) for t, p in types.items()},
                       bicycles=frozenset(t for t, p in types.items() if p.vclass == "bicycle"),
                       heights={t: p.height for t, p in types.items()})
    named_routes: dict[str, tuple[str, ...]] = {}
    for path, document in zip(files, documents):
        for elem in document.iter():  # document order: a route before its use
            if elem.tag == "route" and elem.get("id"):
                named_routes[elem.get("id", "")] = _route_edges(path, elem, f"<route id={shown(elem.get('id'))}>",
                                                                net_file)
            elif elem.tag in ("flow", "vehicle"):
                info.types[elem.get("id", "")] = elem.get("type", "DEFAULT_VEHTYPE")
                inside = elem.find("route")
                if inside is not None:
                    info.routes[elem.get("id", "")] = _route_edges(
                        path, inside, f"<{elem.tag} id={shown(elem.get('id', ''))}>: <route>", net_file)
                elif elem.get("route") in named_routes:
                    info.routes[elem.get("id", "")] = named_routes[elem.get("route", "")]
    return info


def _route_edges(path: Path, route: ET.Element, what: str, net_file: Path) -> tuple[str, ...]:
    """The edges of a ``<route>`` element (``what`` names it in ``path``); FcdError naming the first edge that is not
    one of ``net_file``'s (the audit follows each vehicle's route through the network)."""
    from ..road.topology import read_topology

    edges = tuple(route.get("edges", "").split())
    known = read_topology(net_file).edges
    unknown = [edge for edge in edges if edge not in known]
    if unknown:
        raise FcdError(f"{path}: {what}: edges: expected edges of the network {Path(net_file).name}, got "
                       f"{shown(unknown[0])} (not in it; a file of a run on another network?)")
    return edges


def read_collisions(path: Path) -> list[CollisionEvent]:
    """SUMO's collision-output file, its reports in time order. Every record needs a numeric ``time`` and a
    ``collider`` and a ``victim``; FcdError names the record and attribute otherwise."""
    reports: list[CollisionEvent] = []
    try:
        for number, elem in enumerate(output_elements(path, "collisions", "collision"), start=1):
            record = f"{path}: <collision> {number}"
            for name in ("time", "collider", "victim"):
                if not elem.get(name):
                    raise FcdError(f"{record}: attribute {name!r} is missing or empty")
            time, collider_speed, victim_speed, pos = (_record_number(elem, name, record) for name in (
                "time", "colliderSpeed", "victimSpeed", "pos"))
            reports.append(CollisionEvent(
                time, elem.get("collider", ""), elem.get("victim", ""), elem.get("colliderType", ""),
                elem.get("victimType", ""), collider_speed, victim_speed, elem.get("type", ""), elem.get("lane", ""),
                pos))
            check_collision_record(reports[-1], record)
    except (*MALFORMED, ValueError) as exc:
        raise FcdError(f"{path}: not a readable SUMO collision-output file ({exc})") from exc
    return sorted(reports, key=lambda c: c.time)


def _record_number(elem: ET.Element, name: str, record: str) -> float:
    """A collision record's attribute ``name`` as a finite number (0 where an optional one is absent)."""
    text = elem.get(name, "0")
    try:
        value = float(text)
    except ValueError:
        value = np.nan
    if not np.isfinite(value):
        raise FcdError(f"{record}: attribute {name}={shown(text)} is not a finite number")
    return value


class _CollisionReports:
    """SUMO's collision reports (in time order) handed out to the FCD's time steps: each step takes those since the
    step before, so a collision between two steps of an FCD written less often than SUMO stepped is audited at the
    step after it (SUMO reports a lasting contact every step; :class:`ContactTracker` makes it one event)."""

    def __init__(self, reports: list[CollisionEvent]):
        self._reports = reports
        self._next = 0  # the first report not handed out
        self._before = 0  # reports before the first step
        self._steps: list[float] = []  # the first and the last step's time [s]

    def take_until(self, time: float) -> list[CollisionEvent]:
        """The reports after the step before and up to ``time`` [s] (the first step: at ``time`` only)."""
        reports, start = self._reports, self._next
        if self._steps:
            self._steps[1] = time
        else:
            while start < len(reports) and reports[start].time < time - STEP_TIME_TOLERANCE:
                start += 1
            self._before = start
            self._steps = [time, time]
        end = start
        while end < len(reports) and reports[end].time <= time + STEP_TIME_TOLERANCE:
            end += 1
        self._next = end
        return reports[start:end]

    def parties(self) -> np.ndarray:
        """The ids of every collider and victim of the reports."""
        return np.array(sorted({who for c in self._reports for who in (c.collider, c.victim)}), dtype=str)

    def audited(self) -> list[CollisionEvent]:
        """The reports handed out to the time steps so far."""
        return self._reports[self._before:self._next]

    def warn_unused(self, collisions: Path, fcd: Path) -> None:
        """Warn about the reports outside the FCD's time span (a cut FCD, or files of different runs)."""
        outside = self._reports[:self._before] + self._reports[self._next:]
        if outside:
            span = f"{self._steps[0]:g}-{self._steps[1]:g} s" if self._steps else "no time steps"
            first = ", ".join(f"{cut(c.collider)}/{cut(c.victim)} at {c.time:g} s" for c in outside[:3])
            warnings.warn(f"{collisions}: {len(outside)} collision report(s) outside the time steps of {fcd} ({span}) "
                          f"not audited: {first}{', ...' if len(outside) > 3 else ''}", stacklevel=3)


class FcdReader:
    """Iterate over the WorldSnapshots of an FCD file (constant memory)."""

    def __init__(self, path: str | Path, network: RoadNetwork, vehicles: VehicleInfo | None = None,
                 ego_ids: tuple[str, ...] = ()):
        self.path = Path(path)
        self.network = network
        self.vehicles = vehicles or VehicleInfo()
        self.ego_ids = set(ego_ids)
        self._prev = _PreviousStep(np.zeros(0, dtype=np.int64), np.zeros((0, len(_UNSEEN))))
        self._resolution: float | None = None  # [m] of a lateral position difference written with few decimals
        self._speed_decimals: int | None = None  # of the speeds as written (for accelerations worked out from them)
        self._prev_time: float | None = None
        self._unknown_types: set[str] = set()  # vTypes warned about
        self._warned_jump = False  # about instantaneous lane changes
        self._warned_containers = False  # about containers, which are not audited
        self._warned_walkway = False  # about a vehicle on a lane only pedestrians may use
        self.people: set[str] = set()  # ids of the persons and containers in the file so far
        self._walkers: set[str] = set()  # ids of the persons audited (walking) in the file so far
        self._step: float | None = None  # [s] the file's first step length
        self._warned_step = False  # about unevenly spaced steps
        self.bytes_read = 0  # of the file on disk, up to the last step yielded (progress over its size)
        self._lane_index = dict(zip(network.lane_ids.tolist(), range(len(network.lane_ids))))
        self._route_of: dict[str, tuple[str, ...]] = {}  # of each vehicle seen (VehicleInfo.route_of, () for none)
        self._numbers = Numbering()  # of each vehicle seen (the step before's look-up)
        self._types = Numbering()  # of each vType seen: its row of _type_table
        self._type_table = np.zeros((0, 3))  # per vType seen: length, width [m], whether of vClass bicycle

    def __iter__(self) -> Iterator[WorldSnapshot]:
        if not self.path.is_file():
            raise FcdError(f"{self.path}: FCD file not found")
        parser = None
        try:
            with open_output(self.path) as source:
                parser = FcdParser(source)
                root = parser.read_root()
                if root != "fcd-export":
                    raise FcdError(f"{self.path}: not an FCD file (root element <{root}>, expected <fcd-export>)")
                last = None  # the last complete time step [s]
                try:
                    for step in parser:
                        last = self._time_of(step)
                        snapshot = self._snapshot(step, last)
                        self.bytes_read = bytes_consumed(source)
                        yield snapshot
                except MALFORMED as exc:
                    if last is None or not ends_cut(exc, source):
                        raise
                    warnings.warn(f"{self.path}: the file breaks off after time step {last:g} s (no end tag "
                                  "</fcd-export>, as when SUMO is killed while writing it): read the time steps up "
                                  f"to {last:g} s", stacklevel=2)
        except MALFORMED as exc:
            time = parser.started_time if parser is not None else None
            where = f"after time step {time} s" if time is not None else "before the first time step"
            raise FcdError(f"{self.path}: malformed or truncated FCD {where} ({exc})") from exc

    def _check_step(self, dt: float, time: float) -> None:
        """Warn once per file when the time steps are not evenly spaced (steps missing, or another output
        period): RSS is judged only at the steps written, and accelerations and lateral speeds derived from
        differences span the longer step."""
        if self._step is None:
            self._step = dt
        elif abs(dt - self._step) > 1e-6 and not self._warned_step:
            self._warned_step = True
            warnings.warn(f"{self.path}: time step {time:g} s comes {dt:g} s after the one before, where the file's "
                          f"steps were {self._step:g} s apart (steps missing, or another output period): RSS is "
                          "judged at the steps written only", stacklevel=3)

    def _projections(self, lane: np.ndarray, x: np.ndarray, y: np.ndarray, heading: np.ndarray, length: np.ndarray,
                     fronts: bool, centres: bool) -> tuple[tuple | None, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """In one projection onto the cars' lanes: the front bumpers (x, y [m]) if ``fronts`` (s, d, heading of
        the lane, as ``RoadNetwork.frenet``), and if ``centres`` those of the cars on an edge with an opposite
        direction (their rows, s along the lane [m] and its heading; for :func:`situations.against_lane`)."""
        k = np.flatnonzero(self.network.edge_opposite[self.network.lane_edge[lane]] >= 0) if centres else \
            np.zeros(0, dtype=int)
        cx, cy = x[k] - 0.5 * length[k] * np.cos(heading[k]), y[k] - 0.5 * length[k] * np.sin(heading[k])
        n = len(lane) if fronts else 0
        if not n and not k.size:  # nothing to project (also a step without vehicles)
            empty = np.zeros(0)
            return ((empty, empty, empty) if fronts else None), (k, empty, empty)
        s, d, lane_heading = self.network.frenet(np.concatenate([lane[:n], lane[k]]), np.concatenate([x[:n], cx]),
                                                 np.concatenate([y[:n], cy]))
        return ((s[:n], d[:n], lane_heading[:n]) if fronts else None), (k, s[n:], lane_heading[n:])

    def _against_lane(self, lane: np.ndarray, heading: np.ndarray, length: np.ndarray,
                      centres: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
        """Whether each car drives against its lane (:func:`situations.against_lane`), from ``centres``
        (:meth:`_projections`)."""
        against = np.zeros(len(lane), dtype=bool)
        k, s, lane_heading = centres
        if k.size:
            against[k] = against_lane(self.network, lane[k], s, lane_heading, heading[k], length[k])
        return against

    def _lateral_resolution(self, xs: Sequence[str | None], from_pos_lat: bool) -> float:
        """[m] the largest error of a lateral movement measured from positions as the file writes them (0 for
        FINE_DECIMALS or more; SUMO's --precision applies to x, y and posLat alike); warns once when it is coarse.
        posLat is rounded itself, an offset worked out from x and y by up to √2 of the rounding."""
        decimals = max(_decimals(x or "") for x in xs[:100])
        if decimals >= FINE_DECIMALS:
            return 0.0
        resolution = 10.0 ** -decimals * (1.0 if from_pos_lat else math.sqrt(2.0))
        warnings.warn(f"{self.path}: positions are written with {decimals} decimals: a car's lateral movement of up to "
                      f"{resolution:.3g} m in a step (its rounding) is read as none and accelerations from speed "
                      f"differences are rounded too; write the FCD with sumo --precision {FINE_DECIMALS} (or with "
                      "speedLat and acceleration) for exact values", stacklevel=3)
        return resolution

    def _warn_lane_jumps(self, ids: np.ndarray, lat_moved: np.ndarray, jumped: np.ndarray, dt: float,
                         time: float) -> None:
        """Warn once per file when cars (``jumped``) moved sideways faster than any car can (``JUMP_SPEED``): SUMO
        changed their lanes in one step (their lateral speed there is taken as 0, as SUMO's own ``speedLat``)."""
        if not self._warned_jump:
            self._warned_jump = True
            k = int(np.flatnonzero(jumped)[0])
            warnings.warn(f"{self.path}: {cut(str(ids[k]))} moves {abs(lat_moved[k]):.2f} m sideways onto another "
                          f"lane in one {dt:g} s step at "
                          f"{time:g} s: its lane changes are instantaneous (SUMO without --lanechange.duration or "
                          "--lateral-resolution); at such steps the lateral speed is taken as 0, as SUMO reports it",
                          stacklevel=3)

    def _type_rows(self, types: Sequence[str]) -> np.ndarray:
        """Each vehicle's row of ``_type_table`` (by its vType; rows added for vTypes not seen before: their sizes,
        or SUMO's passenger size for a vType not defined)."""
        rows = self._types.of(types)
        if len(self._types) > len(self._type_table):
            new = list(self._types.number)[len(self._type_table):]
            self._type_table = np.vstack([self._type_table, [(*self.vehicles.sizes.get(t, SUMO_DEFAULT_SIZE),
                                                              float(t in self.vehicles.bicycles)) for t in new]])
        return rows

    @functools.cached_property
    def _walkways(self) -> np.ndarray:
        return pedestrian_lanes(self.network)

    def _time_of(self, step: FcdStep) -> float:
        """A time step's ``time`` [s]; FcdError naming the step before where it is not a number."""
        value = step.time
        try:
            time = float(value) if value is not None else math.nan
        except ValueError:
            time = math.nan
        if not math.isfinite(time):
            after = f"after time step {self._prev_time} s" if self._prev_time is not None else "first time step"
            raise FcdError(f"{self.path}: <timestep> ({after}): time: expected a number of seconds, got {shown(value)}")
        return time

    def _snapshot(self, step: FcdStep, time: float) -> WorldSnapshot:
        if self._prev_time is not None and not time > self._prev_time:
            what = "is repeated" if time == self._prev_time else f"comes after {self._prev_time} s"
            raise FcdError(f"{self.path}: time step {time} s {what}: time: expected a time after the step before's "
                           "(SUMO writes every step once, in time order; docs/outputs.md)")
        where = f"{self.path}, time step {time} s"
        self.people.update(step.unaudited)
        if step.unaudited and not self._warned_containers:
            self._warned_containers = True
            warnings.warn(f"{where}: containers are not audited (the RSS model covers vehicles and persons; a "
                          "collision with one is listed with blamed 'none')", stacklevel=3)
        try:
            persons = person_snapshot(step.persons, self.vehicles.sizes, where) if step.persons else None
        except ValueError as exc:
            raise FcdError(str(exc)) from None
        if persons is not None:
            check_person_edges(where, persons, self.network)
            self.people.update(persons.ids.tolist())
            self._walkers.update(persons.ids.tolist())
        if len(step) and not (step.has("id") and step.has("lane")):
            vid, name = next((r.get("id", "?"), name) for r in step.rows() for name in ("id", "lane") if name not in r)
            raise FcdError(f"{where}: vehicle {shown(vid)} lacks the attribute {name!r} ({NEEDED_ATTRIBUTES})")
        id_column, lane_column = step.column("id"), step.column("lane")
        if "" in id_column or "" in lane_column:
            name, column = ("id", id_column) if "" in id_column else ("lane", lane_column)
            k = list(column).index("")
            raise FcdError(f"{where}: vehicle {shown(id_column[k] or '?')} (vehicle {k + 1} of the step): {name}: "
                           f"expected SUMO's {'vehicle' if name == 'id' else 'lane'} id, got ''")
        ids = np.array(id_column, dtype=str)
        lane_id = np.array(lane_column, dtype=str)
        if len(set(id_column)) < len(ids):
            twice = next(v for v, count in Counter(id_column).items() if count > 1)
            raise FcdError(f"{where}: vehicle {shown(twice)} is listed more than once")
        x, y, angle, speed = (_numbers(step, name, where) for name in ("x", "y", "angle", "speed"))
        lane = np.fromiter(map(self._lane_index.get, lane_column, itertools.repeat(-1)), int, len(step))
        if np.any(lane < 0):
            missing = sorted(set(lane_id[lane < 0].tolist()))
            raise FcdError(f"{where}: lanes not in {self.network.path.name}: {listed(missing)}; is --net the network "
                           "of this run?")
        if not self._warned_walkway:
            self._warned_walkway = warn_on_walkways(where, ids, lane, self.network, self._walkways)
        # Without 'type' in the FCD, the route files' vehicles and flows tell it.
        types = step.column("type")
        if None in types or "" in types:
            types = tuple(t or self.vehicles.type_of(v) or "DEFAULT_VEHTYPE" for t, v in zip(types, id_column))
        vtype = np.array(types, dtype=str)
        unknown = set(types) - self.vehicles.sizes.keys() - self._unknown_types
        if unknown:
            self._unknown_types |= unknown
            warnings.warn(f"{self.path}: vType {listed(sorted(unknown))} is not defined (give its route or vType "
                          f"file); audited at SUMO's passenger size {SUMO_DEFAULT_SIZE[0]:g} m x "
                          f"{SUMO_DEFAULT_SIZE[1]:g} m", stacklevel=2)
        kind = self._type_rows(types)
        length, width, bicycle = (self._type_table[kind, c] for c in range(3))
        heading = compass_deg_to_heading(angle)

        def optional(name: str) -> np.ndarray | None:
            return _numbers(step, name, where) if step.has(name) else None

        lane_pos, lat_pos = optional("pos"), optional("posLat")
        accel, lat_speed = optional("acceleration"), optional("speedLat")
        signals = _numbers(step, "signals", where, integer=SIGNALS_FORM, default="0")

        @functools.cache  # made once, after check_step has checked the values they need (inside it or after it)
        def projections() -> tuple[tuple | None, tuple[np.ndarray, np.ndarray, np.ndarray]]:
            return self._projections(lane, x, y, heading, length, lane_pos is None or lat_pos is None,
                                     lat_speed is None)

        check_step(where, time, self._prev_time, StepValues(ids, lane, x, y, angle, speed, lane_pos, lat_pos, accel,
                                                            lat_speed, signals), self.network,
                   (lambda: np.abs(projections()[0][1])) if lane_pos is None or lat_pos is None else None)
        if self._resolution is None and len(step) and not step.has("speedLat"):
            self._resolution = self._lateral_resolution(step.column("x"), lat_pos is not None)
        fronts, centres = projections()
        if fronts is not None:  # SUMO's pos and posLat are those of the front-bumper centre
            s_f, d_f, _ = fronts
            # SUMO measures pos along the lane's own length (with elevation), not its 2-D shape's.
            lane_pos = self.network.shapes.lane_pos(lane, s_f) if lane_pos is None else lane_pos
            lat_pos = d_f if lat_pos is None else lat_pos
        edge = self.network.lane_edge[lane]
        edge_lat = self.network.lane_offset[lane] + lat_pos
        dt = time - self._prev_time if self._prev_time is not None else None
        if dt is not None:
            self._check_step(dt, time)
        known = len(self._numbers)
        number = self._numbers.of(id_column)
        check_distinct_ids(where, ids[number >= known], self._walkers, persons, self._numbers.number)
        seen, prev = self._prev.of(number)
        prev_speed, prev_edge, prev_lane, prev_lat_pos, prev_edge_lat, prev_lat_speed = prev.T
        same_edge = seen & (prev_edge == edge)
        lat_moved = np.where(same_edge, edge_lat - prev_edge_lat, 0.0)  # [m]
        # A car that moves sideways faster than any car can, or from one lane's centre line to another's, changed
        # its lane in one step (SUMO's default; at a 1 s step a lane width is only 3.5 m/s).
        centred = same_edge & (np.abs(lat_pos) <= CENTRED) & (np.abs(prev_lat_pos) <= CENTRED)
        jumped = (np.abs(lat_moved) > JUMP_SPEED * dt) | (centred & (prev_lane != lane)) if dt else \
            np.zeros(len(ids), bool)
        if (jumped & (prev_lane != lane)).any():  # a jump within a lane (SUMO's own, on one lane) is no lane change
            self._warn_lane_jumps(ids, lat_moved, jumped & (prev_lane != lane), dt, time)
        accel_resolution = 0.0
        if accel is None:
            accel = np.where(seen, (speed - prev_speed) / dt, 0.0) if dt else np.zeros(len(ids))
            # Two speeds each rounded to the file's decimals: the difference is off by up to 10^-N m/s.
            if self._speed_decimals is None and len(step):
                self._speed_decimals = max(_decimals(v) for v in step.column("speed")[:100])
            decimals = FINE_DECIMALS if self._speed_decimals is None else self._speed_decimals
            accel_resolution = 10.0 ** -decimals / dt if dt and decimals < FINE_DECIMALS else 0.0
        if lat_speed is None:  # a lane changed in one step has no lateral speed: SUMO writes speedLat 0 for it
            # A movement within the positions' rounding is none; a car entering a new edge keeps its last speed.
            moved = np.where(np.abs(lat_moved) > (self._resolution or 0.0), lat_moved, 0.0)
            across = np.where(jumped, 0.0, np.where(same_edge | ~seen, moved / dt, prev_lat_speed)) if dt else \
                np.zeros(len(ids))
            # SUMO's speedLat is the car's own (+ = left of its travel); a car overtaking through the oncoming lane
            # has its posLat in that lane's frame, so its movement there is the other way round.
            lat_speed = np.where(self._against_lane(lane, heading, length, centres), -across, across)
        else:
            across = np.zeros(len(ids))  # not needed: SUMO wrote the lateral speeds
        self._prev = _PreviousStep(number, np.column_stack([speed, edge, lane, lat_pos, edge_lat, across]))
        self._prev_time = time
        is_ego = (np.isin(ids, sorted(self.ego_ids)) if self.ego_ids else False) | (vtype == EGO_TYPE)
        routes = tuple(map(self._route_of.get, id_column))
        if None in routes:
            self._route_of.update((v, self.vehicles.route_of(v) or ()) for v in id_column if v not in self._route_of)
            routes = tuple(map(self._route_of.__getitem__, id_column))
        return WorldSnapshot(
            time=time, ids=ids, x=x, y=y, heading=heading, speed=speed, accel=accel, lat_speed=lat_speed,
            length=length, width=width, lane_id=lane_id, edge_id=self.network.edge_ids[edge],
            lane_index=self.network.lane_index[lane], lane_pos=lane_pos, lat_pos=lat_pos,
            vclass=np.where(is_ego, EGO_CLASS, np.where(bicycle > 0.0, BICYCLE_CLASS, BACKGROUND_CLASS)), vtype=vtype,
            signals=signals,
            route_index=np.full(len(ids), -1, dtype=int), route_edges=routes if any(routes) else None,
            accel_resolution=accel_resolution, persons=persons)


@dataclass(frozen=True)
class AuditProgress:
    """How far an offline audit has got, after a time step."""

    bytes_read: int  # of the FCD file, on disk (of its size: a gzipped file's compressed bytes)
    time: float  # [s] of the step
    steps: int  # audited so far
    pair_steps: int  # pairs evaluated so far (road and junction situations, each step)


def audit_fcd(fcd: Path, network: RoadNetwork, params: ParamResolver, *, vehicles: VehicleInfo | None = None,
              collisions: Path | None = None, tls_states: Path | None = None, ego_ids: tuple[str, ...] = (),
              run_id: str = "", signal_rule: bool = True, raw_episodes: bool = False, junction_brake_min: bool = False,
              trace_class: str | None = None, on_progress: Callable[[AuditProgress], None] | None = None,
              stop: Callable[[], bool] | None = None, record_states: bool = False, spool: Path | None = None,
              on_snapshot: Callable[[WorldSnapshot], None] | None = None,
              evasive: EvasiveParams | None = None, occlusion: OcclusionParams | None = None,
              occluders: OccluderEdges | None = None) -> AuditResult:
    """Audit a whole FCD file. Collisions come from SUMO's collision-output file when given, else from
    overlapping bounding boxes of the evaluated pairs (:func:`_in_contact`). Signal states come from SUMO's
    signal-state file (``SaveTLSStates``) when given, else from the network's fixed-time programs. ``vehicles``
    defaults to SUMO's built-in vTypes (:func:`read_vehicle_info`). ``on_progress(AuditProgress)`` is called after
    every time step. ``stop()`` is asked after every time step: True ends the audit there, as if the file ended
    there (with a warning that names the step). ``signal_rule``, ``raw_episodes``, ``junction_brake_min``,
    ``trace_class``, ``record_states``, ``spool``, ``evasive``, ``occlusion``, ``occluders``: as for :class:`Auditor`
    (the vTypes' heights from ``vehicles``). ``on_snapshot(snapshot)``:
    after every audited time step (e.g. a viewer's recorder)."""
    reports = _CollisionReports(read_collisions(collisions)) if collisions is not None else None
    if vehicles is None:
        vehicles = read_vehicle_info(None, network.path)
    if tls_states is None:
        warn_without_signal_states(network.path)
    try:
        signals = SignalStates(network.path, tls_states)
    except ValueError as exc:
        raise FcdError(str(exc)) from exc
    contacts = ContactTracker()
    auditor = Auditor(network, params, run_id, trace_class=trace_class, signal_rule=signal_rule,
                      raw_episodes=raw_episodes, junction_brake_min=junction_brake_min, record_states=record_states,
                      spool=spool, evasive=evasive, occlusion=occlusion, heights=vehicles.heights,
                      occluders=occluders)
    absent = set(ego_ids)  # ego ids not seen in the file yet
    reader = FcdReader(fcd, network, vehicles, ego_ids)
    steps = 0
    # Not in the FCD's steps so far (a set: np.isin sorted every step's ids, ~3 % of acosta's audit).
    unseen = set(reports.parties().tolist()) if reports is not None else set()
    for steps, snapshot in enumerate(reader, start=1):
        if steps == 1:
            warn_late_signal_states(signals, fcd, snapshot.time)
        snapshot = replace(snapshot, tls_states=signals.states(snapshot.time))
        if absent or unseen:
            ids = snapshot.ids.tolist()
            absent.difference_update(ids)
            unseen.difference_update(ids)
        if reports is not None:
            auditor.observe(snapshot, contacts.step(reports.take_until(snapshot.time)))
        else:
            found = overlap_contacts(snapshot, auditor.observe(snapshot), network)
            auditor.record_collisions(contacts.step(found))
        if on_progress is not None:
            on_progress(AuditProgress(reader.bytes_read, snapshot.time, steps, auditor.pair_steps))
        if on_snapshot is not None:
            on_snapshot(snapshot)
        if stop is not None and stop():
            warnings.warn(f"{fcd}: stopped after time step {snapshot.time:g} s: audited up to there", stacklevel=2)
            return auditor.finish()
    if not steps:
        warnings.warn(f"{fcd}: no <timestep> in the file: nothing to audit", stacklevel=2)
    elif signals.known_until is not None and snapshot.time > signals.known_until + STEP_TIME_TOLERANCE:
        warnings.warn(f"{signals.saved_states}: the signal states break off at {signals.known_until:g} s; the time "
                      f"steps of {fcd} after it (to {snapshot.time:g} s) were audited with the states at "
                      f"{signals.known_until:g} s", stacklevel=2)
    if reports is not None:
        check_collisions_in_fcd(collisions, fcd, reports.audited(), unseen - reader.people)
        reports.warn_unused(collisions, fcd)
    if absent:
        warnings.warn(f"{fcd}: no vehicle {listed(sorted(absent))} (given as the ego): audited without it",
                      stacklevel=2)
    return auditor.finish()


def overlap_contacts(snapshot: WorldSnapshot, pairs: PairSituations, network: RoadNetwork) -> list[CollisionEvent]:
    """The evaluated ``pairs`` whose bounding boxes overlap (:func:`_in_contact`), as collision events of type
    'overlap'. The rear car of a pair going the same way (also a merge) is named the collider (SUMO's convention),
    else car a."""
    overlap = _in_contact(snapshot, pairs, network)
    a_named = pairs.a_is_rear | ~np.isin(pairs.kind, SAME_DIRECTION_CODES)
    collider = np.where(a_named, pairs.a, pairs.b)[overlap]
    victim = np.where(a_named, pairs.b, pairs.a)[overlap]
    return [CollisionEvent(snapshot.time, str(snapshot.ids[c]), str(snapshot.ids[v]), "", "", 0.0, 0.0, "overlap",
                           "", 0.0) for c, v in zip(collider, victim)]


def _in_contact(snapshot: WorldSnapshot, pairs: PairSituations, network: RoadNetwork) -> np.ndarray:
    """Per evaluated pair, whether the two bounding boxes overlap: both gaps negative for a road pair (lane frame);
    the footprints themselves (:func:`body_poses`) for a pair crossing in a junction (its gaps are distances to the
    conflict area)."""
    overlap = (pairs.lon_gap < 0.0) & (pairs.lat_gap < 0.0)
    crossing = np.flatnonzero(pairs.kind >= FIRST_INTERSECTION_CODE)
    if crossing.size:
        x, y, heading = body_poses(snapshot, network, network.lane_indices(snapshot.lane_id))
        a, b = pairs.a[crossing], pairs.b[crossing]
        overlap[crossing] = boxes_overlap(x[a], y[a], heading[a], snapshot.length[a], snapshot.width[a],
                                          x[b], y[b], heading[b], snapshot.length[b], snapshot.width[b])
    return overlap


def _numbers(step: FcdStep, name: str, where: str, *, integer: str = "", default: str | None = None
             ) -> np.ndarray:
    """Attribute ``name`` of every vehicle of a time step as finite floats (or, with ``integer``, the expected form
    of its integers, as integers), ``default`` where a vehicle lacks it (None: required); FcdError naming the
    vehicle and the value."""
    kind = int if integer else float
    exact = None if integer else step.numbers(name)
    if exact is not None:  # plain decimals: finite
        return exact
    column = step.column(name)
    if default is not None and column.count(None) == len(column):  # no vehicle has it (SUMO's signals by default)
        return np.full(len(column), kind(default))
    try:
        if default is not None and not step.has(name):
            column = tuple(default if v is None else v for v in column)
        values = np.fromiter(map(int, column), int, len(column)) if integer else np.array(column, dtype=float)
        if integer or np.isfinite(values).all():
            return values
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer beyond 64 bits
        pass
    rows = step.rows()
    bad = next(r for r in rows if not _is_number(r.get(name, default), kind))
    if bad.get(name, default) is None:
        raise FcdError(f"{where}: vehicle {shown(bad.get('id', '?'))} lacks the attribute {name!r} "
                       f"({NEEDED_ATTRIBUTES})")
    raise FcdError(f"{where}: vehicle {shown(bad.get('id', '?'))}: {name}: expected "
                   f"{integer or 'a finite number'}, got {shown(bad[name])}")


class _PreviousStep:
    """What the reader remembers of the cars of the step before, as ``_UNSEEN`` lists it (rows sorted by the cars'
    numbers in the file, :class:`.numbering.Numbering`)."""

    def __init__(self, ids: np.ndarray, values: np.ndarray):
        order = np.argsort(ids)
        self.ids, self.values = ids[order], values[order]  # [n], [n, len(_UNSEEN)]

    def of(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(whether each car was seen the step before, its values then or ``_UNSEEN``)."""
        if not len(self.ids):
            return np.zeros(len(ids), dtype=bool), np.tile(np.array(_UNSEEN, dtype=float), (len(ids), 1))
        pos = np.minimum(np.searchsorted(self.ids, ids), len(self.ids) - 1)
        seen = self.ids[pos] == ids
        return seen, np.where(seen[:, None], self.values[pos], np.array(_UNSEEN, dtype=float))


def _decimals(text: str) -> int:
    """Digits after the decimal point of a number as written (FINE_DECIMALS for an exponent form)."""
    if "e" in text or "E" in text:
        return FINE_DECIMALS
    return len(text) - text.index(".") - 1 if "." in text else 0


def _is_number(text: str | None, kind: type) -> bool:
    try:
        return text is not None and math.isfinite(kind(text)) and (kind is float or abs(kind(text)) < 2**63)
    except ValueError:
        return False
