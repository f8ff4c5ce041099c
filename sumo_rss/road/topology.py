"""A light index of a SUMO .net.xml: normal edges, their lanes (with the vehicle classes they permit) and the
lane-to-lane connections between edges.

Used to validate scenario routes without loading the full road model. Parsed with ``iterparse``.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path


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
    """Index of ``net_file`` (read again only when its size or modification time changed). Raises ``ValueError``
    if the file is not a SUMO network."""
    status = Path(net_file).stat()
    return _read_topology(Path(net_file).resolve(), status.st_size, status.st_mtime_ns)


@lru_cache(maxsize=16)
def _read_topology(net_file: Path, size: int, modified_ns: int) -> NetTopology:
    edges: dict[str, EdgeInfo] = {}
    lanes: dict[str, tuple[Permissions, ...]] = {}
    lane_links: dict[tuple[str, str], set[tuple[int, int]]] = {}
    current: tuple[str, list[float], list[float], list[Permissions]] | None = None
    try:
        for event, elem in ET.iterparse(net_file, events=("start", "end")):
            if event == "start" and elem.tag == "edge" and elem.get("function") != "internal":
                current = (elem.get("id", ""), [], [], [])
            elif event == "end" and elem.tag == "lane" and current is not None:
                current[1].append(float(elem.get("length", "0")))
                current[2].append(float(elem.get("speed", "13.89")))  # SUMO's default lane speed
                current[3].append(Permissions.of(elem))
            elif event == "end" and elem.tag == "edge":
                if current is not None:
                    edge_id, lengths, speeds, permissions = current
                    edges[edge_id] = EdgeInfo(edge_id, len(lengths), max(lengths, default=0.0),
                                              min(speeds, default=0.0))
                    lanes[edge_id] = tuple(permissions)
                current = None
                elem.clear()
            elif event == "end" and elem.tag == "connection":
                src, dst = elem.get("from", ""), elem.get("to", "")
                if not src.startswith(":") and not dst.startswith(":"):
                    lane_links.setdefault((src, dst), set()).add((int(elem.get("fromLane", "0")),
                                                                  int(elem.get("toLane", "0"))))
                elem.clear()
    except (ET.ParseError, ValueError) as exc:
        raise ValueError(f"{net_file}: not a readable SUMO network ({exc})") from exc
    if not edges:
        raise ValueError(f"{net_file}: no edges found; is this a SUMO .net.xml?")
    return NetTopology(edges, lanes, {k: frozenset(v) for k, v in lane_links.items()})
