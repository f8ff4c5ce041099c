"""A light index of a SUMO .net.xml: normal edges, their lanes (with the vehicle classes they permit) and the
lane-to-lane connections between edges.

Used to validate scenario routes without loading the full road model, and to check the whole file once
(:mod:`~sumo_rss.road.net_check`) before the road model is built from it. Parsed with ``iterparse``, once per
content of the file: the index is kept in the road model cache (:mod:`.model_cache`) with the other models.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from ..sumo_xml import MALFORMED, open_output
from .model_cache import cached
from .net_check import NetChecker, NetworkError


@dataclass(frozen=True)
class EdgeInfo:
    """A normal (non-internal) edge: lane count, length of its lanes [m] and the lowest speed limit of its lanes
    [m/s]."""

    id: str
    num_lanes: int
    length: float
    speed: float


@dataclass(frozen=True)
class Permissions:
    """The vehicle classes a lane permits, as SUMO's ``allow`` / ``disallow`` lane attributes say (neither: all)."""

    allow: frozenset[str] | None = None
    disallow: frozenset[str] = frozenset()

    @classmethod
    def of(cls, lane: ET.Element) -> Permissions:
        allow, disallow = lane.get("allow"), lane.get("disallow")
        return cls(None if allow is None else frozenset(allow.split()), frozenset((disallow or "").split()))

    def permits(self, vclass: str) -> bool:
        if vclass == "ignoring":  # SUMO's class that may drive anywhere
            return True
        if self.allow is not None:
            return bool({vclass, "all"} & self.allow)
        return not {vclass, "all"} & self.disallow


@dataclass(frozen=True)
class NetTopology:
    edges: dict[str, EdgeInfo]
    lanes: dict[str, tuple[Permissions, ...]]  # by edge, by lane index
    lane_links: dict[tuple[str, str], frozenset[tuple[int, int]]]  # (from, to) edge → (from, to) lane indices
    signals: dict[str, int] = field(default_factory=dict)  # signal id → links it controls (its states' length)

    def connected(self, from_edge: str, to_edge: str, vclass: str | None = None) -> bool:
        """Whether ``to_edge`` follows ``from_edge``, for ``vclass`` (None: for any class) through a connection
        whose lanes both permit it."""
        if vclass is None:
            return (from_edge, to_edge) in self.lane_links
        start, end = self.lanes[from_edge], self.lanes[to_edge]
        return any(start[i].permits(vclass) and end[j].permits(vclass)
                   for i, j in self.lane_links.get((from_edge, to_edge), ()))

    def permitted_lanes(self, edge: str, vclass: str) -> list[int]:
        """The indices of the lanes of ``edge`` that ``vclass`` may use."""
        return [i for i, lane in enumerate(self.lanes[edge]) if lane.permits(vclass)]


def read_topology(net_file: Path) -> NetTopology:
    """Index of ``net_file`` (read again only when its size or modification time changed; ``*.net.xml.gz`` as
    SUMO reads it). Raises ``ValueError`` naming the file, element and attribute if the file is not a SUMO network
    that the road model can use."""
    status = Path(net_file).stat()
    return _read_topology(Path(net_file).resolve(), status.st_size, status.st_mtime_ns)


@lru_cache(maxsize=16)
def _read_topology(net_file: Path, size: int, modified_ns: int) -> NetTopology:
    # From the road model cache where this file's content was read (and checked) before: a city network's parse
    # is seconds (MoST: 1.8 s of CPU), at every audit's start.
    return cached(net_file, "topology", lambda: _parse_topology(net_file))


def _parse_topology(net_file: Path) -> NetTopology:
    edges: dict[str, EdgeInfo] = {}
    lanes: dict[str, tuple[Permissions, ...]] = {}
    lane_links: dict[tuple[str, str], set[tuple[int, int]]] = {}
    signals: dict[str, int] = {}
    check = NetChecker(net_file)
    try:
        with open_output(net_file) as source:
            context = ET.iterparse(source, events=("start", "end"))
            _, root = next(context)
            if root.tag != "net":
                raise NetworkError(f"{net_file}: not a SUMO network (root element <{root.tag}>, expected <net>)")
            for event, elem in context:
                if event != "end":
                    continue
                if elem.tag == "edge":
                    check.edge(elem)
                    if elem.get("function") != "internal":
                        edge_lanes = elem.findall("lane")
                        edge_id = elem.get("id", "")
                        edges[edge_id] = EdgeInfo(edge_id, len(edge_lanes),
                                                  max((float(lane.get("length", "0")) for lane in edge_lanes),
                                                      default=0.0),
                                                  min((float(lane.get("speed", "0")) for lane in edge_lanes),
                                                      default=0.0))
                        lanes[edge_id] = tuple(Permissions.of(lane) for lane in edge_lanes)
                    elem.clear()
                elif elem.tag == "connection":
                    check.connection(elem)
                    src, dst = elem.get("from", ""), elem.get("to", "")
                    if not src.startswith(":") and not dst.startswith(":"):
                        lane_links.setdefault((src, dst), set()).add((int(elem.get("fromLane", "0")),
                                                                      int(elem.get("toLane", "0"))))
                    elem.clear()
                elif elem.tag == "junction":
                    check.junction(elem)
                    elem.clear()
                elif elem.tag == "tlLogic":
                    signals[check.text(elem, "id")] = check.signal(elem)
                    elem.clear()
        check.finish()
    except NetworkError:
        raise
    except (*MALFORMED, StopIteration) as exc:
        raise NetworkError(f"{net_file}: not a readable SUMO network ({exc or 'an empty file'})") from exc
    if not edges:
        raise NetworkError(f"{net_file}: no edges found; is this a SUMO .net.xml?")
    return NetTopology(edges, lanes, {k: frozenset(v) for k, v in lane_links.items()}, signals)
