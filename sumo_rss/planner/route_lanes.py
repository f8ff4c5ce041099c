"""Which lanes keep the ego on its route (epsilon.md §2.7 / §4.1: the lane change that navigation recommends), as
SUMO's "best lanes": how many lane changes, and to which side, the ego on a lane still has to make to follow its
route to its end, and where its lane leaves the route if it stays on it. Lane changes are made within an edge;
a lane leads into the next route edge through its junction lanes. Units: m."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..road.network import RoadNetwork

UNREACHABLE = 10**6  # lane changes: the route's end cannot be reached from this lane
ROUTE_END_HORIZON = 3000.0  # [m] where a lane leaves the route is looked for this far ahead


def _normal_successors(network: RoadNetwork, lane: int) -> tuple[int, ...]:
    """The lanes of normal edges that ``lane`` leads into (through junction lanes)."""
    out, queue, seen = [], list(network.lane_successors[lane]), set()
    while queue:
        k = queue.pop()
        if k in seen:
            continue
        seen.add(k)
        if network.edge_internal[network.lane_edge[k]]:
            queue.extend(network.lane_successors[k])
        else:
            out.append(k)
    return tuple(sorted(out))


def _edge_lanes(network: RoadNetwork, edge: int) -> np.ndarray:
    """The lanes of ``edge`` by their index (0 = rightmost)."""
    lanes = np.flatnonzero(network.lane_edge == edge)
    return lanes[np.argsort(network.lane_index[lanes])]


def lane_changes_needed(network: RoadNetwork, lane: int, route: tuple[int, ...]) -> tuple[int, int]:
    """(on this edge, in all): the lane changes the ego on ``lane`` must make on its edge (+ to the left, - to the
    right) so that it can follow ``route`` (edge indices from the ego's edge on) to its end with the fewest changes
    in all, making them as early as that allows, and how many changes that is in all (later edges included);
    (0, 0) where its lane follows the route, or where the route's end cannot be reached at all."""
    return _changes(network, int(lane), tuple(int(e) for e in route))


@lru_cache(maxsize=256)
def _changes(network: RoadNetwork, lane: int, route: tuple[int, ...]) -> tuple[int, int]:
    edge = int(network.lane_edge[lane])
    if edge not in route:
        return 0, 0
    route = route[route.index(edge):]
    cost = {int(k): 0 for k in _edge_lanes(network, route[-1])}  # lanes of the last edge: changes still to make
    here, total = 0, 0
    for i in range(len(route) - 2, -1, -1):
        nxt = route[i + 1]
        lanes = _edge_lanes(network, route[i])
        onward = np.array([min((cost[k] for k in _normal_successors(network, int(m))
                                if network.lane_edge[k] == nxt and k in cost), default=UNREACHABLE)
                           for m in lanes])
        options = np.abs(np.arange(lanes.size)[None, :] - np.arange(lanes.size)[:, None]) + onward[None, :]
        cost = {int(k): int(options[j].min()) for j, k in enumerate(lanes)}
        if i == 0:
            j = int(np.flatnonzero(lanes == lane)[0])
            total = int(options[j].min())
            if total >= UNREACHABLE:
                return 0, 0
            best = np.flatnonzero(options[j] == total)
            here = int(best[np.argmin(onward[best])]) - j  # of equally many changes, the ones made here first
    return here, total


def route_end(network: RoadNetwork, lane: int, route: tuple[int, ...]) -> float:
    """[m] from the start of ``lane`` to where it leaves ``route`` (edge indices) if the ego stays on it, following
    the successors that stay on the route longest; inf where it follows the route to its end (or beyond
    ROUTE_END_HORIZON)."""
    route = tuple(int(e) for e in route)
    edge = int(network.lane_edge[lane])
    if edge not in route:
        return np.inf
    travelled, current, position = 0.0, int(lane), route.index(edge)
    while travelled < ROUTE_END_HORIZON:
        length = float(network.lane_length[current])
        if position == len(route) - 1:
            return np.inf
        onward = [k for k in _normal_successors(network, current) if network.lane_edge[k] == route[position + 1]]
        if not onward:
            return travelled + length
        travelled += length + _junction_length(network, current, onward[0])
        current = min(onward, key=lambda k: _changes(network, k, route[position + 1:])[1])
        position += 1
    return np.inf


def _junction_length(network: RoadNetwork, lane: int, target: int) -> float:
    """[m] along the junction lanes from the end of ``lane`` to the start of ``target`` (0 if directly joined)."""
    for k in network.lane_successors[lane]:
        if k == target:
            return 0.0
        if network.edge_internal[network.lane_edge[k]]:
            rest = _junction_length(network, k, target)
            if np.isfinite(rest):
                return float(network.lane_length[k]) + rest
    return np.inf
