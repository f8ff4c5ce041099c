"""The road as the viewer draws it, read from a SUMO ``.net.xml`` (or ``.net.xml.gz``): every lane's shape and width
(internal junction lanes, crossings and walking areas too), the junction shapes, the dashed lines between the lanes
of an edge, and a bar at the end of every signalised lane per link (coloured by the signal's state).

Only geometry: read with ElementTree in one pass (the road model of ``road/`` is not needed to draw).
"""
from __future__ import annotations

import gzip
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SumoRssError

DEFAULT_LANE_WIDTH = 3.2  # [m] SUMO's default where a lane has no width attribute
# How a lane is drawn (index = code in ``NetGeometry.lane_kind``).
LANE_KINDS = ("road", "junction", "sidewalk", "bicycle", "crossing", "walkingarea", "rail")
_PEDESTRIAN, _BICYCLE = frozenset({"pedestrian"}), frozenset({"bicycle"})
_RAIL = frozenset({"rail", "rail_urban", "rail_electric", "rail_fast", "tram", "subway", "cable_car"})
SIGNAL_BAR_M = 0.5  # [m] how far before its lane's end a signal bar is drawn


@dataclass(frozen=True, eq=False)
class Polylines:
    """Polylines (or polygons) as one point array: line ``k`` is ``points[start[k]:start[k + 1]]`` [m]."""

    points: np.ndarray  # float64 [n, 2]
    start: np.ndarray  # int64 [lines + 1]

    @classmethod
    def of(cls, lines: list[np.ndarray]) -> Polylines:
        sizes = [len(line) for line in lines]
        points = np.concatenate(lines) if lines else np.zeros((0, 2))
        return cls(points.reshape(-1, 2), np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64))

    def __len__(self) -> int:
        return len(self.start) - 1


@dataclass(frozen=True, eq=False)
class NetGeometry:
    """What the viewer draws of a network. Lanes: ``lanes`` (centre lines), ``lane_width`` [m], ``lane_kind``
    (index into LANE_KINDS); ``junctions`` (polygons); ``markings`` (lane separators, drawn dashed); signal bars:
    ``bars`` (two points each: across its lane at the stop line), ``bar_signal`` (index into ``signal_ids``) and
    ``bar_link`` (the link index in that signal's state string)."""

    lanes: Polylines
    lane_width: np.ndarray
    lane_kind: np.ndarray
    junctions: Polylines
    markings: Polylines
    bars: np.ndarray  # [bars, 2, 2]
    bar_signal: np.ndarray
    bar_link: np.ndarray
    signal_ids: tuple[str, ...]

    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of everything drawn [m]."""
        points = np.concatenate([self.lanes.points, self.junctions.points])
        if not len(points):
            return 0.0, 0.0, 1.0, 1.0
        low, high = points.min(axis=0), points.max(axis=0)
        return float(low[0]), float(low[1]), float(high[0]), float(high[1])


def read_geometry(path: Path) -> NetGeometry:
    """The drawable geometry of the net ``path``; SumoRssError naming the file where it is not a SUMO network."""
    lanes, widths, kinds, junctions, markings = [], [], [], [], []
    lane_shapes: dict[str, tuple[np.ndarray, float]] = {}
    links: dict[str, list[tuple[str, int]]] = {}  # incoming lane → (signal, link index), in the net's order
    try:
        with (gzip.open(path) if path.suffix == ".gz" else path.open("rb")) as fh:
            for _, element in ET.iterparse(fh):
                if element.tag == "edge":
                    _read_edge(element, lanes, widths, kinds, markings, lane_shapes)
                    element.clear()
                elif element.tag == "junction":
                    if element.get("type") != "internal" and element.get("shape"):
                        junctions.append(_shape(element.get("shape", ""), path))
                    element.clear()
                elif element.tag == "connection":
                    if element.get("tl") and element.get("linkIndex") is not None:
                        lane = f"{element.get('from')}_{element.get('fromLane')}"
                        links.setdefault(lane, []).append((element.get("tl", ""), int(element.get("linkIndex", 0))))
    except (OSError, ET.ParseError, EOFError) as exc:
        raise SumoRssError(f"{path}: not a SUMO network file ({exc})") from None
    if not lanes:
        raise SumoRssError(f"{path}: expected a SUMO network (.net.xml) with lanes, found none")
    bars, bar_signal, bar_link, signal_ids = _signal_bars(links, lane_shapes)
    return NetGeometry(Polylines.of(lanes), np.array(widths), np.array(kinds, dtype=np.uint8), Polylines.of(junctions),
                       Polylines.of(markings), bars, bar_signal, bar_link, signal_ids)


def _read_edge(edge: ET.Element, lanes: list, widths: list, kinds: list, markings: list,
               lane_shapes: dict[str, tuple[np.ndarray, float]]) -> None:
    function = edge.get("function", "normal")
    edge_lanes = edge.findall("lane")
    for index, lane in enumerate(edge_lanes):
        shape = _shape(lane.get("shape", ""), lane.get("id", "?"))
        width = float(lane.get("width", DEFAULT_LANE_WIDTH))
        lanes.append(shape)
        widths.append(width)
        kind = _lane_kind(function, lane.get("allow"))
        kinds.append(LANE_KINDS.index(kind))
        lane_shapes[lane.get("id", "")] = (shape, width)
        if function == "normal" and kind == "road" and index + 1 < len(edge_lanes) and len(shape) >= 2:
            markings.append(offset_polyline(shape, width / 2.0))  # its left border: the next lane is beside it


def _lane_kind(function: str, allow: str | None) -> str:
    if function in ("crossing", "walkingarea"):
        return function
    classes = frozenset((allow or "").split())
    if classes and classes <= _PEDESTRIAN:
        return "sidewalk"
    if classes and classes <= _BICYCLE | _PEDESTRIAN:
        return "bicycle"
    if classes and classes <= _RAIL:
        return "rail"
    return "junction" if function == "internal" else "road"


def _shape(text: str, where: object) -> np.ndarray:
    try:
        points = np.array([[float(v) for v in p.split(",")[:2]] for p in text.split()], dtype=float)
    except ValueError:
        raise SumoRssError(f"{where}: shape: expected 'x,y x,y ...' [m], got {text[:60]!r}") from None
    return points.reshape(-1, 2)


def offset_polyline(points: np.ndarray, distance: float) -> np.ndarray:
    """``points`` moved ``distance`` [m] to the left of their direction (+ = left), each by the mean normal of its
    two segments (a joint of two segments moves along their bisector)."""
    seg = np.diff(points, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    seg = seg / np.where(length > 0.0, length, 1.0)[:, None]
    normal = np.column_stack([-seg[:, 1], seg[:, 0]])
    at_point = np.vstack([normal[:1], normal[:-1] + normal[1:], normal[-1:]])
    norm = np.hypot(at_point[:, 0], at_point[:, 1])
    at_point = at_point / np.where(norm > 0.0, norm, 1.0)[:, None]
    return points + distance * at_point


def _signal_bars(links: dict[str, list[tuple[str, int]]], lane_shapes: dict[str, tuple[np.ndarray, float]]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """One bar per signalised link: the lane's width split among its links, right to left as SUMO draws them,
    SIGNAL_BAR_M before the lane's end."""
    signal_ids = tuple(sorted({tl for lane_links in links.values() for tl, _ in lane_links}))
    bars, bar_signal, bar_link = [], [], []
    for lane, lane_links in links.items():
        if lane not in lane_shapes or len(lane_shapes[lane][0]) < 2:
            continue
        shape, width = lane_shapes[lane]
        end, before = shape[-1], shape[-2]
        direction = (end - before) / max(float(np.hypot(*(end - before))), 1e-9)
        left = np.array([-direction[1], direction[0]])
        stop = end - SIGNAL_BAR_M * direction
        share = width / len(lane_links)
        for k, (tl, link) in enumerate(lane_links):
            right_side = -width / 2.0 + k * share
            bars.append([stop + right_side * left, stop + (right_side + share) * left])
            bar_signal.append(signal_ids.index(tl))
            bar_link.append(link)
    return (np.array(bars, dtype=float).reshape(-1, 2, 2), np.array(bar_signal, dtype=np.int32),
            np.array(bar_link, dtype=np.int32), signal_ids)
