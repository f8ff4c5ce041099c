"""Checks of a SUMO network's elements as they are read (one pass, :func:`~sumo_rss.road.topology.read_topology`):
what the road model and sumolib take from them must be there and be numbers, so that a damaged or hand-edited
``.net.xml`` is an error naming the file, the element and the attribute, never a traceback or a silently wrong
geometry (a lane without a shape has no centre line)."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import shown

SIGNAL_STATE_CHARACTERS = "ruyYgGoOs"  # SUMO's phase states (data/xsd/types/base.xsd, phaseType)
MAX_COORDINATE_M = 1e8  # [m] farther from the origin than any projected map (UTM northings are below 1e7 m)


class NetworkError(ValueError):
    """A network file that the road model cannot use; the message names the file, the element and the field."""


@dataclass
class NetChecker:
    """Collects what later elements refer to (lanes by id, lane counts by edge) while a network is read."""

    path: Path
    lanes: set[str] = field(default_factory=set)
    lane_counts: dict[str, int] = field(default_factory=dict)  # edge id → lanes
    _connections: list[tuple[str, str, str, str, str]] = field(default_factory=list)  # from, to, lanes, via

    def fail(self, elem: ET.Element, name: str, expected: str) -> NetworkError:
        what = f"<{elem.tag} id={shown(elem.get('id'))}>" if elem.get("id") is not None else f"<{elem.tag}>"
        if elem.tag == "connection":
            what = f"<connection from={shown(elem.get('from'))} to={shown(elem.get('to'))}>"
        got = elem.get(name)
        return NetworkError(f"{self.path}: {what}: {name}: expected {expected}, got "
                            f"{'nothing' if got is None else shown(got)}")

    def number(self, elem: ET.Element, name: str, *, minimum: float = -math.inf, default: str | None = None,
               above: bool = False) -> float:
        """Attribute ``name`` as a finite number >= ``minimum`` (> with ``above``)."""
        text = elem.get(name, default)
        try:
            value = float(text) if text is not None else math.nan
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < minimum or (above and value == minimum):
            bound = "" if minimum == -math.inf else f" {'>' if above else '>='} {minimum:g}"
            raise self.fail(elem, name, f"a finite number{bound}")
        return value

    def integer(self, elem: ET.Element, name: str, *, minimum: int = 0) -> int:
        text = elem.get(name, "")
        digits = text[1:] if text.startswith("-") else text
        if not (digits.isascii() and digits.isdigit()) or int(text) < minimum:
            raise self.fail(elem, name, f"an integer >= {minimum}")
        return int(text)

    def text(self, elem: ET.Element, name: str) -> str:
        value = elem.get(name)
        if not value:
            raise self.fail(elem, name, "a non-empty id")
        return value

    def shape(self, elem: ET.Element) -> None:
        """A lane's ``shape``: at least two points ``x,y`` or ``x,y,z`` of finite numbers [m] within
        MAX_COORDINATE_M of the origin."""
        text = elem.get("shape", "")
        points = text.count(" ") + 1 if text.strip() else 0
        try:
            values = [float(value) for value in text.replace(",", " ").split()]
        except ValueError:
            values = [math.nan]
        if points < 2 or len(text.split()) != points or not 2 * points <= len(values) <= 3 * points or \
                text.count(",") != len(values) - points or not max(map(abs, values)) <= MAX_COORDINATE_M:
            raise self.fail(elem, "shape", "at least two points 'x,y' (or 'x,y,z') of finite numbers [m], as "
                                           "netconvert writes them")

    def edge(self, elem: ET.Element) -> None:
        """An ``<edge>`` whose lanes have been read."""
        edge_id = self.text(elem, "id")
        if elem.get("function", "normal") == "normal":  # internal edges, crossings and walking areas have no nodes
            self.text(elem, "from")
            self.text(elem, "to")
        lanes = elem.findall("lane")
        if not lanes:
            raise self.fail(elem, "lane", "at least one <lane> element")
        for lane in lanes:
            self.lane(lane)
        self.lane_counts[edge_id] = len(lanes)

    def lane(self, elem: ET.Element) -> None:
        self.lanes.add(self.text(elem, "id"))
        self.integer(elem, "index")
        self.number(elem, "speed", minimum=0.0, above=True)
        self.number(elem, "length", minimum=0.0)
        self.number(elem, "width", minimum=0.0, above=True, default="3.2")
        self.shape(elem)

    def junction(self, elem: ET.Element) -> None:
        self.text(elem, "id")
        if elem.get("type") != "internal":
            self.text(elem, "type")
            self.number(elem, "x")
            self.number(elem, "y")
            if elem.get("incLanes") is None:
                raise self.fail(elem, "incLanes", "the incoming lanes (may be empty)")

    def connection(self, elem: ET.Element) -> None:
        """A ``<connection>``: checked against the edges and lanes once the whole file is read (:meth:`finish`)."""
        source, target = self.text(elem, "from"), self.text(elem, "to")
        from_lane, to_lane = self.integer(elem, "fromLane"), self.integer(elem, "toLane")
        if elem.get("tl"):
            self.integer(elem, "linkIndex", minimum=-1)
        self._connections.append((source, target, str(from_lane), str(to_lane), elem.get("via", "")))

    def signal(self, elem: ET.Element) -> int:
        """A ``<tlLogic>`` with its phases: durations >= 0 adding up to a cycle > 0, states of one length of SUMO's
        characters. Returns that length: the links the signal controls."""
        self.text(elem, "id")
        phases = elem.findall("phase")
        durations = [self.number(phase, "duration", minimum=0.0) for phase in phases]
        if not sum(durations) > 0.0:
            raise self.fail(elem, "phase", "phases whose durations add up to a cycle > 0 s")
        length = len(phases[0].get("state") or "")
        for number, phase in enumerate(phases, start=1):
            state = phase.get("state") or ""
            if not state or len(state) != length or not set(state) <= set(SIGNAL_STATE_CHARACTERS):
                raise NetworkError(f"{self.path}: <tlLogic id={shown(elem.get('id'))}>: phase {number}: state: "
                                   f"expected {length or 'one or more'} of the characters {SIGNAL_STATE_CHARACTERS} "
                                   f"(one per link), got {shown(state)}")
        return length

    def finish(self) -> None:
        """Every connection joins lanes that exist."""
        for source, target, from_lane, to_lane, via in self._connections:
            for edge, lane in ((source, from_lane), (target, to_lane)):
                if edge not in self.lane_counts:
                    raise NetworkError(f"{self.path}: <connection from={shown(source)} to={shown(target)}>: edge "
                                       f"{shown(edge)} is not in the network")
                if int(lane) >= self.lane_counts[edge]:
                    raise NetworkError(f"{self.path}: <connection from={shown(source)} to={shown(target)}>: lane "
                                       f"{lane} of {shown(edge)}, which has {self.lane_counts[edge]} lane(s)")
            if via and via not in self.lanes:
                raise NetworkError(f"{self.path}: <connection from={shown(source)} to={shown(target)}>: via: "
                                   f"expected a lane of the network, got {shown(via)}")
