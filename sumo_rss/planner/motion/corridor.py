"""Spatio-temporal semantic corridor (epsilon.md §6.3-§6.5, with the port's fixes).

An occupancy grid over (t, s, d) in the planning frame holds where the ego's *centre* may not be:
- every agent's simulated box at each sample time, inflated by the half extents of the ego's footprint (its body
  turned by its planned heading, bounded axis-aligned in the frame) and a margin, rasterised conservatively: a
  cell is occupied when any part of it touches the inflated box;
- static semantics in every time slice: the road edges (the ego's whole unturned body, along s and across d,
  must stay on the union of the lanes that exist where it is, so a lane that ends or a gap between carriageways is
  off-road) and a stop line (an upper bound on s).
Seeds are the ego's initial state and its forward-simulated states; cubes grow from pairs of seeds (5 cells per
direction and round, s capped by kinematic reach, then +t to at least 2 slices) and chain with shared time
boundaries. Failure raises :class:`MotionFailure` with the reason. Units: m, s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lanes import CURRENT
from ..road_frame import GRID_STEP, RoadFrame
from .corridor_kernel import cube_chain, rasterise
from .ssc_qp import MotionFailure


@dataclass(frozen=True)
class CorridorSettings:
    """Grid and inflation settings (epsilon.md §6.3, §6.5); the time slices are the forward simulation's."""

    s_cells: int = 250
    s_res: float = 1.0  # [m]
    s_back: float = 20.0  # [m] grid start behind the ego
    d_cells: int = 71
    d_res: float = 0.2  # [m]
    margin: float = 0.1  # [m] added around every agent's inflated box
    step_cells: int = 5  # cells per direction and inflation round
    min_slices: int = 2  # a cube lasts at least this many time slices when free
    min_horizon: float = 2.0  # [s] the corridor may end early at a blocked seed, not before this
    reach_accel: float = 3.0  # [m/s²] kinematic s cap ahead: s0 + v0·t + ½·a·t² + v0·reach_time
    reach_brake: float = 6.0  # [m/s²] and behind: s0 + v0·t − ½·b·t² − v0·reach_time
    reach_time: float = 1.0  # [s]
    min_back_cells: int = 10  # cubes never reach further back than this many cells from the grid start

    @property
    def d_min(self) -> float:
        return -0.5 * (self.d_cells - 1) * self.d_res


@dataclass(frozen=True, eq=False)
class Corridor:
    """Cubes j = 0..N−1: time span [knots[j], knots[j+1]] (relative to the plan's start) and position bounds
    ``bounds[j, dim] = (low, high)`` (dim 0 = s, 1 = d) for the ego's centre; ``cells[j]`` = the index cube
    (s_lo, s_hi, d_lo, d_hi, t_lo, t_hi)."""

    knots: np.ndarray  # [N+1]
    bounds: np.ndarray  # [N, 2, 2]
    cells: np.ndarray  # [N, 6] int

    def contains(self, t: np.ndarray, s: np.ndarray, d: np.ndarray, tol: float = 1e-6) -> np.ndarray:
        """Whether each (t, s, d) lies in the cube whose time span holds t."""
        j = np.clip(np.searchsorted(self.knots, t, side="right") - 1, 0, len(self.bounds) - 1)
        b = self.bounds[j]
        return (s >= b[:, 0, 0] - tol) & (s <= b[:, 0, 1] + tol) & (d >= b[:, 1, 0] - tol) & (d <= b[:, 1, 1] + tol)


@dataclass(frozen=True, eq=False)
class Grid:
    """The occupancy grid of one cycle: ``occupied[k, i, j]`` for time slice k (at ``times[k]``), s cell i, d cell
    j; cell centres at ``s_origin + i·s_res`` and ``d_min + j·d_res``."""

    occupied: np.ndarray  # [K, S, D] bool
    times: np.ndarray  # [K]
    s_origin: float
    settings: CorridorSettings

    def s_index(self, s: np.ndarray) -> np.ndarray:
        return _cell_index(s, self.s_origin, self.settings.s_res)

    def d_index(self, d: np.ndarray) -> np.ndarray:
        return _cell_index(d, self.settings.d_min, self.settings.d_res)


def _cell_index(value: np.ndarray | float, origin: float, res: float) -> np.ndarray:
    """The cell whose centre (``origin + index·res``) is nearest to ``value`` [m]."""
    return np.rint((np.asarray(value) - origin) / res).astype(int)


def _half_extent_cells(extent: float, res: float) -> int:
    """How many cells of ``res`` [m] half of ``extent`` [m] spans (a whole number of cells is not rounded up)."""
    return int(np.ceil(0.5 * extent / res - 1e-9))


class RoadLayer:
    """The static cells of one planning frame for one ego size, over the frame's whole length on a grid aligned to
    whole multiples of ``s_res``: where a centre anywhere in the cell would put the ego's (unturned) body off the
    road. The body must be on the road at every cell edge it spans (a lane starts and ends between two edges, and
    the body reaches the edge beyond). Built once per frame; each cycle takes a window."""

    def __init__(self, frame: RoadFrame, ego_length: float, ego_width: float, settings: CorridorSettings):
        c = settings
        self.first = int(np.floor(frame.s0 / c.s_res)) - c.s_cells
        last = int(np.ceil((frame.s0 + GRID_STEP * (frame.centre.shape[1] - 1)) / c.s_res)) + c.s_cells
        # Edge e is the lower edge of cell first + e; a body centred in cell i spans the edges i − r .. i + 1 + r.
        r = _half_extent_cells(ego_length, c.s_res)
        edges = c.s_res * (np.arange(self.first - r, last + r + 2) - 0.5)
        off = np.concatenate([np.zeros((1, c.d_cells), dtype=int),
                              np.cumsum(_body_off_road(frame, edges, ego_width, c), axis=0)])
        self.off_road = off[2 * r + 2:] - off[:-2 * r - 2] > 0  # [cells, D]

    def window(self, first: int, cells: int) -> np.ndarray:
        """[cells, D]: rows for s indices first .. first + cells − 1 (off-road beyond the frame)."""
        i = np.arange(first, first + cells) - self.first
        inside = (i >= 0) & (i < self.off_road.shape[0])
        return np.where(inside[:, None], self.off_road[np.clip(i, 0, self.off_road.shape[0] - 1)], True)


def occupancy(road: RoadLayer, times: np.ndarray, ego_s: float, ego_length: float, ego_width: float,
              agents: tuple[np.ndarray, ...], stop_s: float, settings: CorridorSettings,
              ego_heading: np.ndarray | None = None, ego_d: float | None = None) -> Grid:
    """The grid around the ego (its centre at frame s ``ego_s``, d ``ego_d``): ``agents`` = (s, d, heading) arrays
    [K, n] at ``times`` plus (length, width) [n]; the ego's centre may not pass ``stop_s``. ``ego_heading`` [K]
    [rad] (relative to the frame; default 0): the ego's planned heading at each sample. Agents are kept clear of
    the bounding box of its body turned by the largest heading of that sample and its neighbours (a car turned by
    0.44 rad while merging reaches 1.87 m sideways, not 0.95 m); the road edges take its body unturned, and where
    it is over an edge now they hold it no further in than it is (:func:`_edge_moved_to`)."""
    c = settings
    first = int(np.floor((ego_s - c.s_back) / c.s_res))
    origin = first * c.s_res
    s_centres = origin + c.s_res * np.arange(c.s_cells)
    off_road = road.window(first, c.s_cells)
    if ego_d is not None:
        off_road = _edge_moved_to(off_road, int(_cell_index(ego_s, origin, c.s_res)),
                                  int(_cell_index(ego_d, c.d_min, c.d_res)), _half_extent_cells(ego_width, c.d_res))
    static = off_road | (s_centres + 0.5 * c.s_res > stop_s)[:, None]
    s, d, heading, length, width = agents
    if not s.size:
        return Grid(np.broadcast_to(static, (times.size,) + static.shape).copy(), times, origin, c)
    turned = np.zeros(times.size) if ego_heading is None else np.abs(np.asarray(ego_heading, dtype=float))
    cos_e, sin_e = np.cos(turned), np.sin(turned)
    reach_s = _around(0.5 * (ego_length * cos_e + ego_width * sin_e))[:, None]  # [K, 1] the ego's half extents
    reach_d = _around(0.5 * (ego_length * sin_e + ego_width * cos_e))[:, None]
    cos, sin = np.abs(np.cos(heading)), np.abs(np.sin(heading))
    half_s = 0.5 * (length * cos + width * sin) + reach_s + c.margin
    half_d = 0.5 * (length * sin + width * cos) + reach_d + c.margin
    s_lo, s_hi = _cells_touching(s - half_s, s + half_s, origin, c.s_res)
    d_lo, d_hi = _cells_touching(d - half_d, d + half_d, c.d_min, c.d_res)
    dynamic = rasterise(s_lo, s_hi, d_lo, d_hi, c.s_cells, c.d_cells)  # each box: its s and d intervals' product
    dynamic |= static[None]
    return Grid(dynamic, times, origin, c)


def _edge_moved_to(off_road: np.ndarray, row: int, col: int, max_shift: int) -> np.ndarray:
    """``off_road`` [S, D] with the road's edges on one side moved out by as many d cells as the ego's centre cell
    ``(row, col)`` lies beyond the nearest free cell of its row, when it does by at most ``max_shift`` cells (else
    unchanged): an ego whose body is over an edge now (a lane change finished where the lane it left had ended,
    the body half-way into the junction beyond it) may plan from where it is and back onto the road, never further
    out. Without this its own cell is blocked, every corridor fails at the start and the backup holds it standing
    there for good. Farther than ``max_shift`` (half the ego's width: its centre is off the road too, or its cell
    is off-road because its lane ends just ahead and the nearest road is another lane) the edges stay: moving them
    would open a strip along the whole window, past the lane's end."""
    S, D = off_road.shape
    if not (0 <= row < S and 0 <= col < D) or not off_road[row, col]:
        return off_road
    free = np.flatnonzero(~off_road[row])
    if not free.size:
        return off_road
    shift = int(free[np.argmin(np.abs(free - col))]) - col  # > 0: the road is at higher d than the ego
    if abs(shift) > max_shift:
        return off_road
    # A cell becomes free where a free cell lies within |shift| cells of it on the road's side.
    j = np.arange(D)
    low, high = (j, np.minimum(j + shift, D - 1)) if shift > 0 else (np.maximum(j + shift, 0), j)
    return _count_in_windows(~off_road, low, high) == 0


def _count_in_windows(mask: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """[rows, W]: per row of ``mask`` [rows, D], how many of its columns ``low[w]`` .. ``high[w]`` (inclusive) are
    True."""
    counts = np.concatenate([np.zeros((mask.shape[0], 1), dtype=int), np.cumsum(mask, axis=1)], axis=1)
    return counts[:, high + 1] - counts[:, low]


def _around(extent: np.ndarray) -> np.ndarray:
    """[K] the largest of each sample's ``extent`` and its neighbours' (the plan between samples turns from one
    to the next)."""
    padded = np.concatenate([extent[:1], extent, extent[-1:]])
    return np.maximum(np.maximum(padded[:-2], padded[1:-1]), padded[2:])


def _cells_touching(low: np.ndarray, high: np.ndarray, origin: float, res: float) -> tuple[np.ndarray, np.ndarray]:
    """First and last index of the cells (centres origin + i·res, width res) that touch [low, high]."""
    return (np.ceil((low - origin) / res - 0.5).astype(int), np.floor((high - origin) / res + 0.5).astype(int))


def _body_off_road(frame: RoadFrame, s_edges: np.ndarray, ego_width: float, c: CorridorSettings) -> np.ndarray:
    """[E, D]: at each s of ``s_edges``, whether a centre anywhere in d cell j puts the body (``ego_width`` wide)
    off the union of the lanes that exist there."""
    centres = frame.centres_at(s_edges)  # [3, E]
    # A lane is there from where its chain starts to where it ends; the current chain goes on beyond the end of
    # the ego's route unless its lane ends for good (the car leaves the network there, as SUMO removes it), and
    # before the start of the network (a car that has just entered it has its rear behind its first lane's start).
    lower, upper = frame.extent[:, 0].copy(), np.minimum(frame.extent[:, 1], frame.end_s)
    lower[CURRENT], upper[CURRENT] = -np.inf, frame.end_s[CURRENT]
    present = frame.exists[:, None] & (s_edges >= lower[:, None]) & (s_edges <= upper[:, None])
    half = 0.5 * frame.lane_width[:, None]
    edges = c.d_min - 0.5 * c.d_res + c.d_res * np.arange(c.d_cells + 1)  # [D+1] d-cell boundaries
    tol = 0.01  # [m] lanes that touch leave no gap
    on_road = np.any(present[..., None] & (edges >= (centres - half - tol)[..., None]) &
                     (edges <= (centres + half + tol)[..., None]), axis=0)  # [E, D+1]
    covered = on_road[:, :-1] & on_road[:, 1:]  # [E, D] the whole d cell is road
    # The body of a centre anywhere in cell j spans the cells touching [d_j − res/2 − w/2, d_j + res/2 + w/2].
    reach = _half_extent_cells(ego_width, c.d_res)
    j = np.arange(c.d_cells)
    first, last = np.maximum(j - reach, 0), np.minimum(j + reach, c.d_cells - 1)
    inside_grid = (j - reach >= 0) & (j + reach <= c.d_cells - 1)
    return ~((_count_in_windows(~covered, first, last) == 0) & inside_grid)


def build_corridor(grid: Grid, seeds_s: np.ndarray, seeds_d: np.ndarray, v0: float) -> Corridor:
    """The cube chain along the seeds (seed k at slice k; seed 0 is the ego's initial state); raises
    :class:`MotionFailure` ('corridor_seeds', 'corridor_blocked', 'corridor_start')."""
    c = grid.settings
    K, S, D = grid.occupied.shape
    si, di = grid.s_index(seeds_s), grid.d_index(seeds_d)
    ti = np.arange(seeds_s.size)
    inside = (si >= 0) & (si < S) & (di >= 0) & (di < D) & (ti < K)
    if not inside[0]:
        raise MotionFailure("corridor_start", "the ego is outside the grid")
    keep = inside & (np.arange(ti.size) > 0)
    keep[0] = True
    # The corridor ends before the first later seed in an occupied cell when it still spans min_horizon: the
    # behaviour trajectory's tail may cross cells the conservative grid blocks (a lane beyond the frame's three)
    # while the start is what the ego executes before it plans again.
    blocked = np.flatnonzero(keep & grid.occupied[np.minimum(ti, K - 1), np.clip(si, 0, S - 1), np.clip(di, 0, D - 1)])
    blocked = blocked[blocked > 0]
    if blocked.size and grid.times[ti[np.flatnonzero(keep[:blocked[0]])[-1]]] >= c.min_horizon:
        keep[blocked[0]:] = False
    si, di, ti = si[keep], di[keep], ti[keep]
    if si.size < 2:
        raise MotionFailure("corridor_seeds", "fewer than two seeds inside the grid")
    cells, a, b = cube_chain(grid.occupied, si, di, ti, grid.times, float(v0), c.s_back, c.s_res, c.reach_accel,
                             c.reach_brake, c.reach_time, c.min_back_cells, c.step_cells, c.min_slices)
    if a >= 0:
        raise MotionFailure("corridor_blocked", f"seeds {a}-{b} at t = {grid.times[ti[b]]:.1f} s are not free")
    knots = np.concatenate([grid.times[cells[:, 4]], grid.times[cells[-1:, 5]]])
    bounds = np.stack([
        np.stack([grid.s_origin + c.s_res * (cells[:, 0] - 0.5), grid.s_origin + c.s_res * (cells[:, 1] + 0.5)], -1),
        np.stack([c.d_min + c.d_res * (cells[:, 2] - 0.5), c.d_min + c.d_res * (cells[:, 3] + 0.5)], -1)], axis=1)
    return Corridor(knots, bounds, cells)
