"""Pedestrian crossings of a network and where vehicle links pass over them (rss.md §10 (i)).

A SUMO crossing is an edge ``:<junction>_c<k>`` of function ``crossing`` with one lane that persons walk in either
direction; its link (the connection from a walking area onto it) has a junction index, and at a signal a state
character. A vehicle link of the same junction that SUMO marks as its foe and whose strip overlaps the crossing's
strip meets it in a *crossing area*: an s-interval along the vehicle link's path and one along the crossing.
Right of way is SUMO's junction logic (``<request response=...>``): at a zebra (``priority="1"``) the vehicle link
yields to the crossing, at an unprioritised crossing the crossing yields; at signals the link states decide.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .frenet import LaneShapes
from .junctions import RANK_OF_BYTE, JunctionModel, path_polyline
from .link_pairs import expand_ranges
from .model_cache import cached
from .net_file import read_net
from .network import RoadNetwork
from .strip_overlap import strip_overlaps


@dataclass(frozen=True, eq=False)
class CrossingModel:
    """The crossings (C of them) and their crossing areas with vehicle links (K), as arrays; the areas are sorted
    by vehicle link."""

    edge_ids: np.ndarray  # [C] str: the crossing edge (what an FCD names a person's edge)
    lane: np.ndarray  # [C] its lane (network lane index)
    tls: np.ndarray  # [C] object: the signal of its link, '' if unsignalised
    tls_index: np.ndarray  # [C] index of its link in the signal's state, -1 if unsignalised
    link: np.ndarray  # [K] the vehicle link (index into JunctionModel.links)
    crossing: np.ndarray  # [K] the crossing (index into the arrays above)
    link_start: np.ndarray  # [K] start of the area along the vehicle link's path [m]
    link_end: np.ndarray  # [K] its end [m]
    cross_start: np.ndarray  # [K] start of the area along the crossing lane [m]
    cross_end: np.ndarray  # [K] its end [m]
    static_priority: np.ndarray  # [K] +1: the vehicle has priority, -1: the person, 0: same (SUMO's request)
    area_id: np.ndarray  # [K] object: '<junction>:<vehicle link index>x<crossing edge>'
    # Sorted ids of the edges where persons walk off the road: walking areas, crossings and edges with a sidewalk (a
    # lane for pedestrians only); a person on any other edge walks on a vehicle lane.
    walkway_edges: np.ndarray

    def __len__(self) -> int:
        return int(self.link.shape[0])

    def areas_of_links(self, links: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(owner, k): every crossing area k of each of ``links`` (owner: the position in ``links``)."""
        return expand_ranges(np.searchsorted(self.link, links, side="left"),
                             np.searchsorted(self.link, links, side="right"))

    def signal_ranks(self, tls_states: dict[str, str] | None) -> np.ndarray:
        """[C] rank of every crossing's current signal (G 2, g 1, anything else 0); -1 if unsignalised or unknown."""
        out = np.full(len(self.edge_ids), -1, dtype=int)
        k = np.flatnonzero(self.tls_index >= 0)
        if not tls_states or not k.size:
            return out
        names, number = np.unique(self.tls[k].astype(str), return_inverse=True)
        states = [tls_states.get(name, "") for name in names.tolist()]  # unknown: as long as no index
        length = np.array([len(state) for state in states], dtype=int)
        chars = np.frombuffer("".join(states).encode("ascii", "replace"), dtype=np.uint8)
        known = self.tls_index[k] < length[number]
        at = (np.cumsum(length) - length)[number[known]] + self.tls_index[k[known]]
        out[k[known]] = RANK_OF_BYTE[chars[at]]
        return out

    @classmethod
    def from_file(cls, path: str | Path, network: RoadNetwork, junctions: JunctionModel) -> CrossingModel:
        """The crossing model of the network file ``path``, from the road model cache when it holds one of this
        file's content, else built and stored there."""
        return cached(Path(path), "crossings", lambda: cls.build(path, network, junctions), keep=True)

    @classmethod
    def build(cls, path: str | Path, network: RoadNetwork, junctions: JunctionModel) -> CrossingModel:
        """The crossing model of the network file ``path`` (no cache)."""
        net = read_net(path)
        lane_idx = {lane_id: k for k, lane_id in enumerate(network.lane_ids.tolist())}
        crossings = []  # (edge id, lane, junction, junction index, tls, tls index)
        for node in net.getNodes():
            for edge in node.getIncoming():
                if edge.getFunction() != "walkingarea":
                    continue
                for connection in (c for lane in edge.getLanes() for c in lane.getOutgoing()):
                    to_lane = connection.getToLane()
                    if to_lane.getEdge().getFunction() == "crossing":
                        tls = connection.getTLSID() or ""
                        crossings.append((to_lane.getEdge().getID(), lane_idx[to_lane.getID()], node.getID(),
                                          connection.getJunctionIndex(), tls,
                                          connection.getTLLinkIndex() if tls else -1))
        crossings.sort()
        walkways = sorted({edge.getID() for edge in net.getEdges() if edge.getFunction() in ("walkingarea", "crossing")
                           or any(lane.getPermissions() <= {"pedestrian"} for lane in edge.getLanes())})
        nodes = {node.getID(): node for node in net.getNodes()}
        vehicle_links: dict[str, list[int]] = {}
        for k, link in enumerate(junctions.links):
            vehicle_links.setdefault(link.junction, []).append(k)
        pairs = []  # (vehicle link, crossing, static priority)
        for c, (_, _, junction, index, _, _) in enumerate(crossings):
            node = nodes[junction]
            n = len(node._foes)
            for k in vehicle_links.get(junction, []):
                v = junctions.links[k].index
                if index < 0 or node._foes[v][n - 1 - index] != "1":
                    continue
                vehicle_yields = node._prohibits[v][n - 1 - index] == "1"
                person_yields = node._prohibits[index][n - 1 - v] == "1"
                pairs.append((k, c, int(person_yields) - int(vehicle_yields)))
        paths = [path_polyline(link.path, network) for link in junctions.links]
        paths += [network.shapes.points[lane, : network.shapes.count[lane]] for _, lane, *_ in crossings]
        widths = np.concatenate([[float(network.lane_width[link.path[0]]) for link in junctions.links],
                                 [float(network.lane_width[lane]) for _, lane, *_ in crossings]])
        link = np.array([k for k, _, _ in pairs], dtype=int)
        crossing = np.array([c for _, c, _ in pairs], dtype=int)
        across = len(junctions.links) + crossing
        start, end = strip_overlaps(paths, widths, np.concatenate([link, across]), np.concatenate([across, link]))
        m = len(pairs)
        keep = ~(np.isnan(start[:m]) | np.isnan(start[m:]))
        order = np.flatnonzero(keep)[np.argsort(link[keep], kind="stable")]
        ids = [f"{junctions.links[k].junction}:{junctions.links[k].index}x{crossings[c][0]}"
               for k, c in zip(link[order].tolist(), crossing[order].tolist())]
        return cls(np.array([c[0] for c in crossings], dtype=str), np.array([c[1] for c in crossings], dtype=int),
                   np.array([c[4] for c in crossings], dtype=object), np.array([c[5] for c in crossings], dtype=int),
                   link[order], crossing[order], start[:m][order], end[:m][order], start[m:][order], end[m:][order],
                   np.array([p for _, _, p in pairs], dtype=np.int8)[order] if pairs else np.zeros(0, np.int8),
                   np.array(ids, dtype=object), np.array(walkways, dtype=str))


@dataclass(frozen=True, eq=False)
class CrossingEntries:
    """Where persons step onto the crossings, two per crossing (its start: walking forward along its lane; its end:
    backward), with a spatial index of the points."""

    crossing: np.ndarray  # [2C]
    forward: np.ndarray  # [2C] bool
    point: np.ndarray  # [2C, 2] (x, y) [m]
    along: np.ndarray  # [2C] the direction a person walks the crossing from there [rad]
    length: np.ndarray  # [2C] the crossing's centre line [m]
    tree: cKDTree | None  # of ``point``; None without crossings

    @classmethod
    def of(cls, model: CrossingModel, shapes: LaneShapes) -> CrossingEntries:
        last = shapes.count[model.lane] - 1
        crossing = np.repeat(np.arange(len(model.lane)), 2)
        forward = np.tile([True, False], len(model.lane))
        lane, end = model.lane[crossing], last[crossing]
        length = shapes.cumulative[lane, end]
        point = np.where(forward[:, None], shapes.points[lane, 0], shapes.points[lane, end])
        along = shapes.heading_at(lane, np.where(forward, 0.0, length)) + np.where(forward, 0.0, np.pi)
        return cls(crossing, forward, point, along, length, cKDTree(point) if len(point) else None)
