"""Inputs of the intention estimator (epsilon.md port decision 9): an agent's past trajectory and its candidate
centrelines, both in the agent's frame (origin at its front bumper, x along its heading, y to its left).

Each past trajectory point is (x, y, right blinker, left blinker): the turn indicators are part of what an
observer sees of a vehicle's past (SUMO sets them before turns and lane changes; epsilon.md §7 allows reading
signals), and the rule-based belief ignores them.

A **candidate** is a lane path the agent may follow: it starts on the agent's lane (``keep``) or on a neighbour
on the same edge (``left`` / ``right``) and goes on through every successor, so a junction approach yields one
candidate per turn. Each is sampled at ``LANE_POINTS`` arc positions from ``LANE_BEHIND`` behind the agent to
``LANE_AHEAD`` ahead; every point carries (x, y, beyond-the-end flag), so the net sees where a lane stops (an
acceleration lane). Candidates that coincide over the sampled range are one candidate. Pure numpy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...angles import wrap_angle
from ...road.network import RoadNetwork

LANE_POINTS = 70
LANE_BEHIND, LANE_AHEAD = 10.0, 128.0  # [m] sampled range of a centreline around the agent
LANE_ARCS = np.linspace(-LANE_BEHIND, LANE_AHEAD, LANE_POINTS)  # [m] 2 m apart
HISTORY_STEPS = 11  # past positions, oldest first, the last one is now (0, 0)
HISTORY_DT = 0.2  # [s] between past positions → 2 s of history
HISTORY_FEATURES = 4  # x, y [m] in the agent frame, right blinker, left blinker (0/1)
BLINKER_RIGHT, BLINKER_LEFT = 1, 2  # SUMO's signal bits (VEH_SIGNAL_BLINKER_RIGHT / _LEFT)
MAX_CANDIDATES = 6
SAME_PATH_M = 0.5  # [m] candidates closer than this everywhere are one
KEEP, LEFT, RIGHT = 0, 1, 2  # lateral class of a candidate (cfb.INTENTIONS order)


@dataclass(frozen=True, eq=False)
class Candidates:
    """Candidate centrelines of n agents, padded to ``MAX_CANDIDATES``."""

    lanes: np.ndarray  # [n, C, LANE_POINTS, 3] x, y [m] in the agent frame, 1.0 where beyond the path's end
    mask: np.ndarray  # [n, C] bool: a real candidate
    lateral: np.ndarray  # [n, C] int KEEP / LEFT / RIGHT (0 where padded)
    world: np.ndarray  # [n, C, LANE_POINTS, 2] the same points in world coordinates [m] (for labelling)
    to_lane_end: np.ndarray  # [n] [m] ahead to where the agent's own lane ends for good (inf: it goes on)

    def branching(self) -> np.ndarray:
        """[n] bool: where the intention network applies (:func:`lanes_branch`)."""
        return lanes_branch(self.lateral, self.mask, self.to_lane_end)


def lanes_branch(lateral: np.ndarray, mask: np.ndarray, to_lane_end: np.ndarray) -> np.ndarray:
    """[n] bool: the agent's own lane has several ways ahead in range (a junction approach) or ends (an
    acceleration lane); ``lateral``/``mask`` [n, C] and ``to_lane_end`` [n] as in :class:`Candidates`. The
    network is trained on these samples only, and used on them only."""
    return (np.sum(mask & (lateral == KEEP), axis=1) > 1) | np.isfinite(to_lane_end)


def network_branches(network: RoadNetwork) -> bool:
    """Whether any lane of ``network`` has several successors or ends (an acceleration lane): otherwise no agent's
    lane ever branches (:func:`lanes_branch`) and the intention network is never asked."""
    return bool(np.any(network.lane_ends)) or any(len(successors) > 1 for successors in network.lane_successors)


def to_agent_frame(px: np.ndarray, py: np.ndarray, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Points (px, py) [m], shaped [n, ...], in the frames of n agents at (x, y, heading) → [n, ..., 2]."""
    extra = (slice(None),) + (None,) * (np.ndim(px) - 1)
    dx, dy = px - np.asarray(x)[extra], py - np.asarray(y)[extra]
    c, s = np.cos(heading)[extra], np.sin(heading)[extra]
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


class CandidateFinder:
    """Candidate centrelines on one network. Lane paths are enumerated once per start lane and kept in one padded
    table, so the candidates of many agents are sampled, ordered and de-duplicated in a few numpy passes."""

    def __init__(self, network: RoadNetwork):
        self.network = network
        self._paths: dict[int, list[tuple[np.ndarray, np.ndarray, bool]]] = {}
        self._path_ids: dict[int, np.ndarray] = {}
        self._polylines: list[tuple[np.ndarray, np.ndarray]] = []
        self._table: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None  # points, cum, count, ends
        self._ends: list[bool] = []

    def start_lanes(self, lane: int) -> list[tuple[int, int]]:
        """(start lane, lateral class) of an agent on ``lane``: its own lane, then the neighbours on its edge."""
        net = self.network
        starts = [(lane, KEEP)]
        if not net.edge_internal[net.lane_edge[lane]]:
            starts += [(int(net.lane_left[lane]), LEFT), (int(net.lane_right[lane]), RIGHT)]
        return [(k, cls) for k, cls in starts if k >= 0]

    def paths(self, lane: int) -> list[tuple[np.ndarray, np.ndarray, bool]]:
        """(polyline [m, 2], cumulative arc length [m], whether it stops at a lane end) of every lane path from the
        start of ``lane`` that reaches ``LANE_AHEAD`` beyond the lane's end or stops where the lane graph stops.
        A lane end is a lane that stops while its edge goes on (an acceleration lane), not the network's end."""
        if lane not in self._paths:
            net = self.network
            reach = float(net.lane_length[lane]) + LANE_AHEAD
            found: list[tuple[np.ndarray, np.ndarray, bool]] = []
            stack: list[tuple[tuple[int, ...], float]] = [((lane,), float(net.lane_length[lane]))]
            while stack:
                path, length = stack.pop()
                successors = net.lane_successors[path[-1]]
                if length >= reach or not successors:
                    found.append(self._polyline(path) + (not successors and bool(net.lane_ends[path[-1]]),))
                    continue
                for nxt in sorted(successors, reverse=True):
                    stack.append((path + (nxt,), length + float(net.lane_length[nxt])))
            self._paths[lane] = found
        return self._paths[lane]

    def _polyline(self, path: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        shapes = self.network.shapes
        parts = [shapes.points[k, :shapes.count[k]] for k in path]
        points = np.concatenate([parts[0]] + [p[1:] if np.allclose(p[0], q[-1]) else p
                                              for q, p in zip(parts[:-1], parts[1:])])
        seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
        keep = np.concatenate([[True], seg > 1e-9])
        points = points[keep]
        return points, np.concatenate([[0.0], np.cumsum(seg[seg > 1e-9])])

    def _ids(self, lane: int) -> np.ndarray:
        """Rows of ``lane``'s paths in the padded path table (added, and the table re-padded, on first use)."""
        if lane not in self._path_ids:
            first = len(self._polylines)
            for points, cum, ends in self.paths(lane):
                self._polylines.append((points, cum))
                self._ends.append(ends)
            self._path_ids[lane] = np.arange(first, len(self._polylines))
            width = max(len(c) for _, c in self._polylines)
            points = np.zeros((len(self._polylines), width, 2))
            cum = np.full((len(self._polylines), width), np.inf)  # padding never counts as passed
            for row, (p, c) in enumerate(self._polylines):
                points[row, :len(c)], cum[row, :len(c)] = p, c
            count = np.array([len(c) for _, c in self._polylines])
            self._table = (points, cum, count, np.array(self._ends))
        return self._path_ids[lane]

    def candidates(self, lane: np.ndarray, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> Candidates:
        """Candidates of agents on lanes ``lane`` (indices) at front-bumper positions (x, y) [m], ``heading`` [rad].
        Order per agent: keep, left, right; within a class the straightest first."""
        lane, x, y, heading = (np.atleast_1d(np.asarray(a)) for a in (lane, x, y, heading))
        n = lane.shape[0]
        pairs = [(i, k, cls) for i, k0 in enumerate(lane.tolist()) for k, cls in self.start_lanes(int(k0))]
        pair_agent, pair_lane, pair_class = (np.array(col, dtype=int) for col in zip(*pairs))
        s0, _, _ = self.network.frenet(pair_lane, x[pair_agent], y[pair_agent])
        ids = [self._ids(k) for k in pair_lane.tolist()]
        item_pair = np.repeat(np.arange(len(pairs)), [len(r) for r in ids])
        item_path = np.concatenate(ids)
        points, cum_all, count_all, ends_all = self._table
        agent, cls = pair_agent[item_pair], pair_class[item_pair]
        cum, count = cum_all[item_path], count_all[item_path]
        arcs = s0[item_pair, None] + LANE_ARCS[None, :]  # [m, P]
        seg = np.clip((cum[:, None, :] <= arcs[:, :, None]).sum(axis=2) - 1, 0, count[:, None] - 2)
        rows = item_path[:, None]
        a, b = points[rows, seg], points[rows, seg + 1]
        t = (arcs - cum_all[rows, seg]) / (cum_all[rows, seg + 1] - cum_all[rows, seg])
        xy = a + t[..., None] * (b - a)  # [m, P, 2], straight on beyond either end
        length = cum_all[item_path, count - 1]
        beyond = (arcs > length[:, None]).astype(float)
        d_end, d_start = xy[:, -1] - xy[:, -2], xy[:, 1] - xy[:, 0]
        turn = np.abs(wrap_angle(np.arctan2(d_end[:, 1], d_end[:, 0]) - np.arctan2(d_start[:, 1], d_start[:, 0])))
        to_end = np.full(n, np.inf)
        stops = ends_all[item_path] & (cls == KEEP)
        np.minimum.at(to_end, agent[stops], length[stops] - s0[item_pair[stops]])

        order = np.lexsort((np.arange(agent.size), np.round(turn, 6), cls, agent))
        agent, cls, xy, beyond = agent[order], cls[order], xy[order], beyond[order]
        rank = np.arange(agent.size) - np.searchsorted(agent, agent)  # position within the agent's items
        width = int(rank.max()) + 1
        grid = np.full((n, width), -1)
        grid[agent, rank] = np.arange(agent.size)
        valid = grid >= 0
        g_xy, g_cls = xy[np.maximum(grid, 0)], np.where(valid, cls[np.maximum(grid, 0)], -1)
        apart = np.max(np.linalg.norm(g_xy[:, :, None] - g_xy[:, None, :], axis=-1), axis=-1)  # [n, K, K]
        same = (apart < SAME_PATH_M) & (g_cls[:, :, None] == g_cls[:, None, :]) & valid[:, :, None]
        duplicate = np.any(np.tril(same, k=-1), axis=2)  # an earlier candidate of the same class coincides
        kept = valid & ~duplicate
        slot = np.cumsum(kept, axis=1) - 1
        kept &= slot < MAX_CANDIDATES
        ag, col = np.nonzero(kept)
        src = grid[ag, col]
        world = np.zeros((n, MAX_CANDIDATES, LANE_POINTS, 2))
        past_end = np.zeros((n, MAX_CANDIDATES, LANE_POINTS))
        mask = np.zeros((n, MAX_CANDIDATES), dtype=bool)
        lateral = np.zeros((n, MAX_CANDIDATES), dtype=int)
        dst = slot[ag, col]
        world[ag, dst], past_end[ag, dst], mask[ag, dst], lateral[ag, dst] = xy[src], beyond[src], True, cls[src]
        local = to_agent_frame(world[..., 0], world[..., 1], x, y, heading) * mask[:, :, None, None]
        return Candidates(np.concatenate([local, past_end[..., None]], axis=-1), mask, lateral, world, to_end)


def history_in_agent_frame(past_x: np.ndarray, past_y: np.ndarray, past_signals: np.ndarray, x: np.ndarray,
                           y: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """[n, HISTORY_STEPS, HISTORY_FEATURES] past positions [m] and blinkers from ``past_x``/``past_y``/
    ``past_signals`` (SUMO signal bits), each [n, HISTORY_STEPS], oldest first."""
    xy = to_agent_frame(np.asarray(past_x, dtype=float), np.asarray(past_y, dtype=float), x, y, heading)
    bits = np.asarray(past_signals, dtype=int)
    return np.concatenate([xy, ((bits & BLINKER_RIGHT) > 0)[..., None], ((bits & BLINKER_LEFT) > 0)[..., None]],
                          axis=-1)


def distance_to_candidates(world: np.ndarray, mask: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """[n, C] distance [m] from each agent's point (px, py) to each of its candidate polylines (inf if padded)."""
    a, b = world[:, :, :-1], world[:, :, 1:]  # [n, C, P-1, 2]
    p = np.stack([px, py], axis=-1)[:, None, None, :]
    ab = b - a
    t = np.clip(np.einsum("ncpj,ncpj->ncp", p - a, ab) / np.maximum(np.einsum("ncpj,ncpj->ncp", ab, ab), 1e-12),
                0.0, 1.0)
    foot = a + t[..., None] * ab
    dist = np.min(np.linalg.norm(p - foot, axis=-1), axis=2)
    return np.where(mask, dist, np.inf)
