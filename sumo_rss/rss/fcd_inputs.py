"""The inputs of an offline audit beside the FCD: vType sizes, dynamics and routes from SUMO's route/vType files
(:func:`read_vehicle_info`) and SUMO's collision-output file (:func:`read_collisions`, handed out to the time steps
by :class:`CollisionReports`)."""
from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SumoRssError, cut, listed, shown
from ..sim.collisions import CollisionEvent
from ..sumo_home import vtype_attribute_names
from ..sumo_xml import MALFORMED, open_output, output_elements
from .record_checks import check_collision_record

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


class CollisionReports:
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
