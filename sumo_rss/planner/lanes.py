"""Lanes for planning: the ego's current lane and its left/right neighbours as chains of lanes along its route,
each a polyline with its own Frenet frame (epsilon.md §2.1, §2.4, §2.7)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..road.curvature import vertex_curvature
from ..road.frenet import LaneShapes
from ..road.network import RoadNetwork
from . import route_lanes

# [m/s²] lateral acceleration of the reference speed in bends (epsilon.md §2.7 has 1.2, the release's highway demo
# value: a left turn at 3 m/s where SUMO's cars take it at 9.26; docs/planner.md "Not timid")
CURVE_LAT_ACCEL = 3.0
# [m/s²] the reference speed falls towards a lower speed ahead as braking at this would: epsilon.md §3.1's comfortable
# deceleration b (the release's reference-speed window v²/1.67); 1.0 slowed the ego for a turn ~1 s too early
REFERENCE_BRAKE = 1.67
RIGHT, CURRENT, LEFT = 0, 1, 2  # chain order
CONSISTENT_LANES = 20  # lanes searched along the successors for a lane-change context (epsilon.md §2.7)


@dataclass(frozen=True, eq=False)
class LaneChains:
    """Up to three lane chains (right, current, left; None where no neighbour exists).

    ``shapes`` holds the chains that exist, ``chain_of[RIGHT|CURRENT|LEFT]`` their row in it (-1 if absent),
    ``lanes[c]`` the lane indices of chain c, ``start_s[c]`` where the ego's own lane starts along chain c [m],
    ``lane_start[c]`` where each of its lanes starts (s as in :meth:`project`) and ``lane_speed[c]`` their speed
    limits [m/s], ``curve_s[c]`` / ``curve_kappa[c]`` where chain c bends (s as in :meth:`project`) and how
    sharply (|κ| [1/m], road/curvature.py), ``width[c]`` its narrowest lane [m], ``dead_end[c]`` whether chain c's
    last lane ends for good (no successor, e.g. an acceleration lane) rather than being cut at the planning range.
    ``route_end``: where the ego's own lane leaves its route if it stays on it (s as in :meth:`project`; inf: it
    follows the route to its end), ``changes``: the lane changes it must still make to follow its route (on this
    edge, + = left; and in all: :func:`.route_lanes.lane_changes_needed`).
    A neighbour chain starts beside the first lane along the ego's chain that has such a neighbour, so the
    motorway beside an on-ramp is known before the ego reaches it.
    """

    shapes: LaneShapes
    chain_of: np.ndarray  # [3]
    lanes: tuple[tuple[int, ...], ...]
    start_s: np.ndarray
    lane_start: tuple[np.ndarray, ...]
    lane_speed: tuple[np.ndarray, ...]
    curve_s: tuple[np.ndarray, ...]
    curve_kappa: tuple[np.ndarray, ...]
    width: np.ndarray
    dead_end: np.ndarray
    route_end: float = np.inf
    changes: tuple[int, int] = (0, 0)

    def exists(self, which: int) -> bool:
        return bool(self.chain_of[which] >= 0)

    def project(self, which: int, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(s, d) of points on chain ``which``; s measured from the start of the ego's own lane [m]."""
        row = int(self.chain_of[which])
        s, d, _ = self.shapes.project(np.full(len(np.atleast_1d(x)), row), np.atleast_1d(x), np.atleast_1d(y))
        return s - self.start_s[row], d

    def speed_cap(self, which: int, s_from: float, length: float, desired: float) -> float:
        """min(desired, speed limits, √(a_lat/|κ|)) over [s_from, s_from + length] of chain ``which`` (s as in
        :meth:`project`) [m/s]: the lanes' limits and the curvature ahead of s_from, not behind it."""
        row = int(self.chain_of[which])
        s, kappa = self.curve_s[row], self.curve_kappa[row]
        window = (s >= s_from - 1.0) & (s <= s_from + length)
        v_curve = np.sqrt(CURVE_LAT_ACCEL / np.maximum(kappa[window], 1e-9)).min(initial=np.inf)
        return float(min(desired, self.speed_limit(which, s_from, length), v_curve))

    def reference_speed(self, which: int, s_from: float, desired: float, brake: float = REFERENCE_BRAKE) -> float:
        """The speed [m/s] from which the ego at ``s_from`` on chain ``which`` can still slow down at ``brake``
        [m/s²] to every lower speed ahead: a bend's √(a_lat/|κ|) at the bend, a lane's speed limit where the lane
        starts (the limit of the lane it is on holds at once), at most ``desired``."""
        return float(self.reference_profile(which, np.array([s_from], dtype=float), desired, brake)[0])

    def reference_profile(self, which: int, s_from: np.ndarray, desired: float, brake: float = REFERENCE_BRAKE,
                          bends: bool = True) -> np.ndarray:
        """:meth:`reference_speed` [m/s] at every position ``s_from`` [m] ([m] array, s as in :meth:`project`);
        without ``bends`` only the lanes' limits count (the speed from which the ego can still slow down to every
        lower limit by the time its front bumper reaches that lane, where ``s_from`` is its front bumper)."""
        row = int(self.chain_of[which])
        reach = desired * desired / (2.0 * brake) + 1.0  # beyond this no lower speed ahead matters
        at = np.asarray(s_from, dtype=float)[:, None]
        starts, limits = self.lane_start[row], self.lane_speed[row]
        ends = np.append(starts[1:], np.inf)
        here = np.where((starts <= at) & (ends > at), limits, np.inf).min(axis=1, initial=np.inf)
        # Lower speeds ahead: the bends within reach (and 1 m behind), the lanes that start within reach.
        bend_s, kappa = (self.curve_s[row], self.curve_kappa[row]) if bends else (np.zeros(0), np.zeros(0))
        where = np.concatenate([bend_s, starts])
        speed = np.concatenate([np.sqrt(CURVE_LAT_ACCEL / np.maximum(kappa, 1e-9)), limits])
        is_bend = np.arange(where.size) < bend_s.size
        within = np.where(is_bend, where >= at - 1.0, where > at) & (where <= at + reach)
        envelope = np.sqrt(speed ** 2 + 2.0 * brake * np.maximum(where - at, 0.0))
        return np.minimum(np.minimum(desired, here), np.where(within, envelope, np.inf).min(axis=1, initial=np.inf))

    def speed_limit(self, which: int, s_from: float, horizon: float) -> float:
        """The lowest speed limit [m/s] of chain ``which``'s lanes over [s_from, s_from + horizon] (inf: none)."""
        row = int(self.chain_of[which])
        starts = self.lane_start[row]
        ends = np.append(starts[1:], self.shapes.cumulative[row, int(self.shapes.count[row]) - 1] - self.start_s[row])
        in_window = (starts < s_from + horizon) & (ends > s_from)
        return float(self.lane_speed[row][in_window].min(initial=np.inf))


def lane_chains(network: RoadNetwork, lane: int, route: np.ndarray, forward: float = 250.0,
                backward: float = 160.0) -> LaneChains:
    """Chains through the ego's lane and its neighbours, ``forward`` m ahead along the route (any successor where
    the route says nothing) and ``backward`` m behind. A neighbour's chain ends where its lane leaves the route (a
    turn lane beside the ego's): carried on through that turn, its offset from the ego's chain would be
    meaningless (a right-turn lane beside a left turn read 37 m across, and cars in it turned into the ego's way
    in the forward simulation)."""
    predecessors: dict[int, list[int]] = {}
    for k, succ in enumerate(network.lane_successors):
        for j in succ:
            predecessors.setdefault(j, []).append(k)
    route_set = set(int(e) for e in route if e >= 0)
    own_ahead = _walk(network, lane, network.lane_successors, route_set, forward, own=True)
    starts = [_first_neighbour(network.lane_right, own_ahead), lane, _first_neighbour(network.lane_left, own_ahead)]
    chains, chain_of, start_s, lane_start, lane_speed, curve_s, curve_kappa, widths, polylines, dead_end = \
        [], np.full(3, -1), [], [], [], [], [], [], [], []
    for which, first in enumerate(starts):
        if first < 0:
            continue
        ahead = own_ahead if which == CURRENT else \
            _walk(network, first, network.lane_successors, route_set, forward, own=True, route_only=bool(route_set))
        behind = _walk(network, first, predecessors, route_set, backward, own=False)[::-1]
        chain = tuple(behind + ahead)
        pts: list[np.ndarray] = []
        for k in chain:
            shape = network.shapes.points[k, : network.shapes.count[k]]
            pts.extend(shape if not pts else shape[1:])
        # s is measured from the start of the ego's own lane: project it onto this chain.
        offset = float(sum(network.shapes.cumulative[j, network.shapes.count[j] - 1] for j in behind))
        chain_of[which] = len(chains)
        chains.append(chain)
        start_s.append(offset)
        lengths = network.shapes.cumulative[list(chain), network.shapes.count[list(chain)] - 1]
        lane_start.append(np.concatenate([[0.0], np.cumsum(lengths[:-1])]) - offset)
        lane_speed.append(network.lane_speed[list(chain)].astype(float))
        widths.append(float(network.lane_width[list(chain)].min()))
        polylines.append(np.asarray(pts, dtype=float))
        dead_end.append(bool(network.lane_ends[chain[-1]]))
    shapes = LaneShapes.from_polylines(polylines)
    for row, offset in enumerate(start_s):
        n = int(shapes.count[row])
        bend_s, kappa = vertex_curvature(shapes.points[row, :n], shapes.cumulative[row, :n])
        curve_s.append(bend_s - offset)
        curve_kappa.append(kappa)
    on_route = tuple(int(e) for e in route if e >= 0)
    return LaneChains(shapes, chain_of, tuple(chains), np.array(start_s), tuple(lane_start), tuple(lane_speed),
                      tuple(curve_s), tuple(curve_kappa), np.array(widths), np.array(dead_end, dtype=bool),
                      route_lanes.route_end(network, lane, on_route) if on_route else np.inf,
                      route_lanes.lane_changes_needed(network, lane, on_route) if on_route else (0, 0))


def lanes_consistent_with(network: RoadNetwork, chain: tuple[int, ...] | list[int], limit: int = CONSISTENT_LANES
                          ) -> frozenset[int]:
    """The lanes a car that started on ``chain``'s first lane is still "on" without having changed lanes
    (epsilon.md §2.7): the chain and a breadth-first search over the successors of its first lane, up to
    ``limit`` lanes. A lane-change context completes once the ego's lane is none of these."""
    found, queue = [chain[0]], [chain[0]]
    while queue and len(found) < limit:
        for nxt in network.lane_successors[queue.pop(0)]:
            if nxt not in found and len(found) < limit:
                found.append(nxt)
                queue.append(nxt)
    return frozenset(found) | frozenset(chain)


def _first_neighbour(neighbour: np.ndarray, lanes: list[int]) -> int:
    """The neighbour (left or right) of the first lane in ``lanes`` that has one, else -1."""
    return next((int(neighbour[k]) for k in lanes if neighbour[k] >= 0), -1)


def _walk(network: RoadNetwork, lane: int, graph: object, route: set[int], length: float, *,
          own: bool, route_only: bool = False) -> list[int]:
    """Lanes from ``lane`` (included when ``own``) along ``graph`` until ``length`` m, preferring lanes whose
    edge (or the edge a junction lane leads into) is on the route; with ``route_only``, ending where none is."""
    out = [lane] if own else []
    total, current = 0.0 if own else 0.0, lane
    seen = {lane}
    while total < length:
        options = [k for k in graph.get(current, ()) if k not in seen] if isinstance(graph, dict) else \
            [k for k in graph[current] if k not in seen]
        if not options:
            break
        on_route = [k for k in options if int(network.edge_exit[network.lane_edge[k]]) in route]
        if route_only and not on_route:
            break
        current = (on_route or options)[0]
        seen.add(current)
        out.append(current)
        total += float(network.lane_length[current])
    return out
