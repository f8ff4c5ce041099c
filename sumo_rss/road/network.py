"""RoadNetwork: the static road model of a SUMO .net.xml (lanes, edges, lane graph, geometry).

Read with :mod:`.net_file`, then held as numpy arrays indexed by lane and edge number, so the auditor maps the lane
ids of a whole snapshot to indices and looks up geometry and topology without Python loops. Distances along the
edge and lane graphs are searched per source within a horizon, on first need (:class:`.reach.GraphReach`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .frenet import LaneShapes
from .model_cache import cached
from .net_file import read_net
from .reach import GraphReach
from .two_way import TwoWayRoads, two_way_roads


class UnknownLaneError(ValueError):
    """Lane ids that are not in the network."""


@dataclass(frozen=True, eq=False)
class RoadNetwork:
    """Lanes (internal junction lanes included) and edges of one SUMO network.

    Per lane k: ``lane_ids[k]``, ``lane_edge[k]`` (edge index), ``lane_index[k]`` (0 = rightmost),
    ``lane_length[k]``, ``lane_width[k]`` [m], ``lane_speed[k]`` [m/s], ``lane_offset[k]`` (centre's offset from the edge's right border,
    [m]), ``lane_left[k]`` / ``lane_right[k]`` (neighbour lane index or -1), ``lane_successors[k]``.
    Per edge e: ``edge_ids[e]``, ``edge_internal[e]``, ``edge_opposite[e]`` (the other direction of a two-way
    road: an edge between the same nodes in the other direction that runs beside e, :mod:`.two_way`; or -1),
    ``edge_successors[e]`` (along the lanes vehicles drive: no sidewalks, walking areas or crossings) and
    ``edge_exit[e]``: e itself for a normal edge, the normal edge an internal (junction) edge leads to otherwise.
    ``edge_reach`` / ``lane_reach``: shortest distances [m] from the start of an edge (lane) to the start of another
    along the lane graph, within a horizon beyond its end (:meth:`edge_distances`, :meth:`lane_distances`). Lengths
    and positions along lanes are SUMO's (which include elevation); ``shapes`` converts them to and from the 2-D
    centre lines.
    """

    path: Path
    lane_ids: np.ndarray
    lane_edge: np.ndarray
    lane_index: np.ndarray
    lane_length: np.ndarray
    lane_width: np.ndarray
    lane_speed: np.ndarray  # [m/s] speed limit
    lane_offset: np.ndarray
    lane_left: np.ndarray
    lane_right: np.ndarray
    lane_successors: tuple[tuple[int, ...], ...]
    lane_ends: np.ndarray  # a normal lane without successors on an edge that goes on other than by a turnaround
    # (e.g. an acceleration lane)
    shapes: LaneShapes
    two_way: TwoWayRoads  # the lane frames of two-way roads (two_way.py)
    edge_ids: np.ndarray
    edge_internal: np.ndarray
    edge_opposite: np.ndarray
    edge_length: np.ndarray
    edge_successors: tuple[tuple[int, ...], ...]
    edge_exit: np.ndarray
    edge_reach: GraphReach
    lane_reach: GraphReach
    _lane_lookup: dict[str, int]  # lane id → index
    _edge_lookup: dict[str, int]

    @classmethod
    def from_file(cls, path: str | Path) -> RoadNetwork:
        """The road model of the network file ``path``: from the road model cache (:mod:`.model_cache`) when it
        holds one of this file's content, else built (:meth:`build`) and stored there."""
        path = Path(path)
        return replace(cached(path, "network", lambda: cls.build(path)), path=path)

    @classmethod
    def build(cls, path: str | Path) -> RoadNetwork:
        """The road model of the network file ``path``, read and built (no cache)."""
        path = Path(path)
        net = read_net(path)
        edges = sorted(net.getEdges(withInternal=True), key=lambda e: e.getID())
        edge_index = {e.getID(): i for i, e in enumerate(edges)}
        lanes = [lane for e in edges for lane in e.getLanes()]
        if not lanes:
            raise ValueError(f"{path}: expected a SUMO network (.net.xml) with lanes, found none")
        lane_idx = {lane.getID(): k for k, lane in enumerate(lanes)}

        offsets = np.zeros(len(lanes))
        left = np.full(len(lanes), -1)
        right = np.full(len(lanes), -1)
        for e in edges:
            edge_lanes = e.getLanes()
            border = 0.0
            for i, lane in enumerate(edge_lanes):
                k = lane_idx[lane.getID()]
                offsets[k] = border + lane.getWidth() / 2.0
                border += lane.getWidth()
                if i > 0:
                    right[k] = lane_idx[edge_lanes[i - 1].getID()]
                if i + 1 < len(edge_lanes):
                    left[k] = lane_idx[edge_lanes[i + 1].getID()]

        successors, onward = [], []  # onward: the lane has a successor other than a turnaround
        for lane in lanes:
            nxt = []
            for c in lane.getOutgoing():
                via = c.getViaLaneID()
                nxt.append(lane_idx[via] if via else lane_idx[c.getToLane().getID()])
            successors.append(tuple(sorted(set(nxt))))
            onward.append(any(c.getDirection() != "t" for c in lane.getOutgoing()))

        edge_length = np.array([max(lane.getLength() for lane in e.getLanes()) for e in edges])
        lane_edge = np.array([edge_index[lane.getEdge().getID()] for lane in lanes])
        lane_length = np.array([lane.getLength() for lane in lanes])
        # Distances between edges follow the lanes vehicles drive: not sidewalks, walking areas and crossings (a
        # junction's walking area is often the shortest way from a sidewalk to the next edge: DRT's 945141561 read
        # 2.70 m through it for a 3.59 m internal lane).
        walkway = np.array([lane.getPermissions() <= {"pedestrian"} for lane in lanes])
        edge_succ = [set() for _ in edges]
        for k, nxt in enumerate(successors):
            if not walkway[k]:
                edge_succ[lane_edge[k]].update(int(lane_edge[j]) for j in nxt if not walkway[j])
        edge_successors = tuple(tuple(sorted(nxt)) for nxt in edge_succ)
        lane_ids = np.array([lane.getID() for lane in lanes], dtype=str)
        shapes = LaneShapes.from_polylines(_centre_lines(lanes, successors), lane_length)
        lane_index = np.array([lane.getIndex() for lane in lanes])
        two_way = two_way_roads(_reversed_edge_pairs(edges), [[lane_idx[lane.getID()] for lane in e.getLanes()]
                                                              for e in edges],
                                shapes, np.array([lane.getWidth() for lane in lanes]), lane_index, len(edges))
        # A lane ends (an acceleration lane, a lane drop) where it leads nowhere while its edge goes on. A turnaround
        # does not make the edge go on: netconvert connects only the leftmost lane of a dead end to the opposite
        # edge, and its other lanes do not end there (each pair of cars beside each other would be a merge).
        edge_goes_on = np.zeros(len(edges), dtype=bool)
        edge_goes_on[lane_edge[np.flatnonzero(onward)]] = True
        lane_ends = np.array([not successors[k] and e.getFunction() != "internal" and edge_goes_on[lane_edge[k]]
                              for k, e in enumerate(lane.getEdge() for lane in lanes)])
        return cls(
            path=path, lane_ids=lane_ids, lane_edge=lane_edge,
            lane_index=lane_index,
            lane_length=lane_length,
            lane_width=np.array([lane.getWidth() for lane in lanes]),
            lane_speed=np.array([lane.getSpeed() for lane in lanes]),
            lane_offset=offsets, lane_left=left, lane_right=right, lane_successors=tuple(successors),
            lane_ends=lane_ends,
            shapes=shapes, two_way=two_way,
            edge_ids=np.array([e.getID() for e in edges], dtype=str),
            edge_internal=np.array([e.getFunction() == "internal" for e in edges]),
            edge_opposite=two_way.edge_opposite, edge_length=edge_length, edge_successors=edge_successors,
            edge_exit=_edge_exits(edge_successors, [e.getFunction() == "internal" for e in edges]),
            edge_reach=GraphReach(edge_successors, edge_length), lane_reach=GraphReach(successors, lane_length),
            _lane_lookup=lane_idx, _edge_lookup=edge_index)

    def edge_indices(self, edge_ids: list[str] | tuple[str, ...]) -> np.ndarray:
        """Indices of edge ids (e.g. a route); raises ``KeyError`` for an unknown id."""
        return np.array([self._edge_lookup[e] for e in edge_ids], dtype=int)

    def find_edges(self, edge_ids: np.ndarray) -> np.ndarray:
        """Indices of ``edge_ids`` (vectorised), -1 for an id not in the network."""
        names = edge_ids.tolist() if isinstance(edge_ids, np.ndarray) else list(edge_ids)
        return np.fromiter((self._edge_lookup.get(str(e), -1) for e in names), dtype=np.int64, count=len(names))

    def lane_indices(self, lane_ids: np.ndarray) -> np.ndarray:
        """Indices of ``lane_ids`` (vectorised); raises :class:`UnknownLaneError` naming the unknown ids."""
        names = lane_ids.tolist() if isinstance(lane_ids, np.ndarray) else list(lane_ids)
        try:
            return np.fromiter(map(self._lane_lookup.__getitem__, names), dtype=np.int64, count=len(names))
        except KeyError:
            unknown = sorted({str(k) for k in names} - self._lane_lookup.keys())
            raise UnknownLaneError(f"lanes not in {self.path.name}: {', '.join(unknown)}") from None

    def require_reach(self, horizon: float) -> None:
        """Make :meth:`edge_distances` and :meth:`lane_distances` reach exactly ``horizon`` [m] beyond the end of
        the edge (lane) they start from."""
        self.edge_reach.require(horizon)
        self.lane_reach.require(horizon)

    def edge_distances(self, source: np.ndarray, target: np.ndarray) -> np.ndarray:
        """[m] shortest distance from the start of each edge ``source`` to the start of edge ``target`` along the
        lane graph (0 for the edge itself); inf where ``target`` starts farther than the reach horizon beyond the end
        of ``source`` (:meth:`require_reach`), or is not reached at all."""
        return self.edge_reach.between(source, target)

    def lane_distances(self, source: np.ndarray, target: np.ndarray) -> np.ndarray:
        """[m] as :meth:`edge_distances` for lanes: the distance a car on lane ``source`` drives, following lane
        successors without changing lanes, from its start to the start of lane ``target``."""
        return self.lane_reach.between(source, target)

    def downstream_lanes(self, lane: int) -> np.ndarray:
        """The lanes (sorted indices) a car on ``lane`` reaches by following successors, without changing lanes,
        that start within the reach horizon beyond the end of ``lane`` (``lane`` itself included)."""
        return self.lane_reach.row(lane)[0]

    def frenet(self, lane: np.ndarray, x: np.ndarray, y: np.ndarray,
               s_hint: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s, d, lane heading) of points in the frame of lanes ``lane`` (indices, or lane ids such as 'hw0_1');
        see LaneShapes.project. An edge is named by one of its lanes: d is measured from that lane's centre."""
        lane = np.asarray(lane)
        if lane.dtype.kind in "USO":
            lane = self.lane_indices(lane)
        return self.shapes.project(lane, x, y, s_hint)


def _reversed_edge_pairs(edges: list) -> list[tuple[int, int]]:
    """Every pair of normal edges (indices into ``edges``) between the same two nodes in opposite directions, once."""
    by_nodes: dict[tuple[str, str], list[int]] = {}
    for i, e in enumerate(edges):
        if e.getFunction() != "internal":
            by_nodes.setdefault((e.getFromNode().getID(), e.getToNode().getID()), []).append(i)
    return [(i, j) for (a, b), forward in by_nodes.items() if a < b for i in forward
            for j in by_nodes.get((b, a), [])]


def _centre_lines(lanes: list, successors: list[tuple[int, ...]]) -> list[np.ndarray]:
    """Every lane's centre line, (x, y, z) [m]. A lane whose shape has no length (netconvert writes the internal
    lane of a junction that only joins two edges as one point twice, with length 0.10 m) becomes a level straight
    line of its length, in the direction in which the lane it leads to starts, else in which one leading to it ends,
    else +x."""
    shapes = [np.array(lane.getShape3D(), dtype=float) for lane in lanes]
    predecessors: dict[int, int] = {}
    for k, nxt in enumerate(successors):
        for j in nxt:
            predecessors.setdefault(j, k)
    lines = list(shapes)
    for k, shape in enumerate(shapes):
        if np.any(np.diff(shape[:, :2], axis=0)):
            continue
        candidates = [_first_direction(shapes[j]) for j in successors[k]]
        if k in predecessors:
            backwards = _first_direction(shapes[predecessors[k]][::-1])
            candidates.append(None if backwards is None else -backwards)
        direction = next((d for d in candidates if d is not None), np.array([1.0, 0.0]))
        lines[k] = np.array([shape[0], shape[0] + lanes[k].getLength() * np.append(direction, 0.0)])
    return lines


def _first_direction(line: np.ndarray) -> np.ndarray | None:
    """The unit direction of the first step of ``line`` that has a length (None: it has none)."""
    steps = np.diff(line[:, :2], axis=0)
    steps = steps[np.any(steps != 0.0, axis=1)]
    return steps[0] / np.linalg.norm(steps[0]) if len(steps) else None


def _edge_exits(successors: tuple[tuple[int, ...], ...], internal: list[bool]) -> np.ndarray:
    """For each edge, the first normal edge reached by following successors (itself if normal)."""
    exits = np.arange(len(successors))
    for e in range(len(successors)):
        current, seen = e, set()
        while internal[current] and successors[current] and current not in seen:
            seen.add(current)
            current = min(successors[current])
        exits[e] = current
    return exits
