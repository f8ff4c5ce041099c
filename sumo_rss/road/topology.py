"""A light index of a SUMO .net.xml: normal edges, their lanes and the edge-to-edge connections.

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
class NetTopology:
    edges: dict[str, EdgeInfo]
    successors: dict[str, frozenset[str]]

    def connected(self, from_edge: str, to_edge: str) -> bool:
        return to_edge in self.successors.get(from_edge, frozenset())


@lru_cache(maxsize=16)
def read_topology(net_file: Path) -> NetTopology:
    """Index of ``net_file`` (cached per path). Raises ``ValueError`` if the file is not a SUMO network."""
    edges: dict[str, EdgeInfo] = {}
    successors: dict[str, set[str]] = {}
    current: tuple[str, list[float]] | None = None
    try:
        for event, elem in ET.iterparse(net_file, events=("start", "end")):
            if event == "start" and elem.tag == "edge" and elem.get("function") != "internal":
                current = (elem.get("id", ""), [], [])
            elif event == "end" and elem.tag == "lane" and current is not None:
                current[1].append(float(elem.get("length", "0")))
                current[2].append(float(elem.get("speed", "13.89")))  # SUMO's default lane speed
            elif event == "end" and elem.tag == "edge":
                if current is not None:
                    edge_id, lengths, speeds = current
                    edges[edge_id] = EdgeInfo(edge_id, len(lengths), max(lengths, default=0.0),
                                              min(speeds, default=0.0))
                current = None
                elem.clear()
            elif event == "end" and elem.tag == "connection":
                src, dst = elem.get("from", ""), elem.get("to", "")
                if not src.startswith(":") and not dst.startswith(":"):
                    successors.setdefault(src, set()).add(dst)
                elem.clear()
    except ET.ParseError as exc:
        raise ValueError(f"{net_file}: not a readable SUMO network ({exc})") from exc
    if not edges:
        raise ValueError(f"{net_file}: no edges found; is this a SUMO .net.xml?")
    return NetTopology(edges, {k: frozenset(v) for k, v in successors.items()})
