"""The corridor's cell loops, compiled with numba (:mod:`.corridor` prepares their inputs and reads their outputs):
the agents' boxes rasterised into the occupancy grid, and the cube chain grown along the seeds. Integer cell
logic only, so the results are exactly those of the numpy formulation they replace (docs/motion.md "Cycle time").
Indices are cells of the grid [K, S, D] (time slice, s cell, d cell)."""
from __future__ import annotations

import numpy as np

from ...jit import jitable, kernel

CUBE_FIELDS = 6  # s_lo, s_hi, d_lo, d_hi, t_lo, t_hi


@kernel
def rasterise(s_lo, s_hi, d_lo, d_hi, s_cells, d_cells):
    """[K, S, D] bool: cell (k, i, j) lies in the box of an agent at slice k, i.e. ``s_lo[k, a] <= i <= s_hi[k, a]``
    and ``d_lo[k, a] <= j <= d_hi[k, a]`` for some agent a (bounds [K, n] int, clipped to the grid here)."""
    K, n = s_lo.shape
    out = np.zeros((K, s_cells, d_cells), dtype=np.bool_)
    for k in range(K):
        for a in range(n):
            i0, i1 = max(s_lo[k, a], 0), min(s_hi[k, a], s_cells - 1)
            j0, j1 = max(d_lo[k, a], 0), min(d_hi[k, a], d_cells - 1)
            for i in range(i0, i1 + 1):
                for j in range(j0, j1 + 1):
                    out[k, i, j] = True
    return out


@kernel
def cube_chain(occ, si, di, ti, times, v0, s_back, s_res, reach_accel, reach_brake, reach_time, min_back_cells,
               step_cells, min_slices):
    """The cube chain along the seeds (si, di, ti) [M] (cells; every seed inside the grid, M >= 2): a cube grown
    from seeds 0 and 1, then a new one from the last seed inside the cube before and each seed outside it, each cube
    ending at the slice of the seed that starts the next. Returns (cells [N, 6] int: s_lo, s_hi, d_lo, d_hi, t_lo,
    t_hi, the seeds a and b whose box was occupied (-1, -1: none; the cells are then incomplete))."""
    M = si.size
    cells = np.empty((M, CUBE_FIELDS), dtype=np.int64)
    if not _grown_cube(occ, si, di, ti, 0, 1, times, v0, s_back, s_res, reach_accel, reach_brake,
                       reach_time, min_back_cells, step_cells, min_slices, cells[0]):
        return cells[:0], 0, 1
    count, last_in = 1, 1
    for k in range(2, M):
        cube = cells[count - 1]
        if cube[0] <= si[k] <= cube[1] and cube[2] <= di[k] <= cube[3] and ti[k] <= cube[5]:
            last_in = k
            continue
        cube[5] = ti[last_in]
        if not _grown_cube(occ, si, di, ti, last_in, k, times, v0, s_back, s_res, reach_accel, reach_brake,
                           reach_time, min_back_cells, step_cells, min_slices, cells[count]):
            return cells[:0], last_in, k
        count += 1
        last_in = k
    cells[count - 1, 5] = ti[M - 1]
    return cells[:count], -1, -1


@jitable
def _any_in(occ, t0, t1, s0, s1, d0, d1):
    """Whether any cell of occ[t0:t1+1, s0:s1+1, d0:d1+1] is occupied."""
    for t in range(t0, t1 + 1):
        for i in range(s0, s1 + 1):
            for j in range(d0, d1 + 1):
                if occ[t, i, j]:
                    return True
    return False


@jitable
def _grown_cube(occ, si, di, ti, a, b, times, v0, s_back, s_res, reach_accel, reach_brake, reach_time,
                min_back_cells, step_cells, min_slices, box):
    """Into ``box``: the bounding box of seeds a and b, inflated 5 cells per direction and round (d first to its
    end, s capped by the kinematic reach), then +t to at least ``min_slices``; False where the seeds' box is
    occupied. A layer the box grows into must be free at every time slice of the box."""
    K, S, D = occ.shape
    box[0], box[1] = min(si[a], si[b]), max(si[a], si[b])
    box[2], box[3] = min(di[a], di[b]), max(di[a], di[b])
    box[4], box[5] = ti[a], ti[b]
    if _any_in(occ, box[4], box[5], box[0], box[1], box[2], box[3]):
        return False
    t = times[min(box[4] + 2, K - 1)]
    s_up = s_back + v0 * t + 0.5 * reach_accel * t * t + v0 * reach_time
    s_down = s_back + v0 * t - 0.5 * reach_brake * t * t - v0 * reach_time
    limits = np.empty(4, dtype=np.int64)
    limits[0] = max(min(int(np.floor(s_up / s_res)), S - 1), box[1])
    limits[1] = min(max(int(np.ceil(s_down / s_res)), min_back_cells), box[0])
    limits[2], limits[3] = D - 1, 0
    active = np.ones(4, dtype=np.bool_)  # +s, −s, +d, −d
    while active[2] or active[3]:
        for direction in range(4):
            if active[direction]:
                active[direction] = _grow(occ, box, direction, step_cells, limits[direction])
    for direction in range(2):
        if active[direction]:
            _grow(occ, box, direction, S, limits[direction])
    while box[5] - box[4] < min_slices and box[5] + 1 < K and \
            not _any_in(occ, box[5] + 1, box[5] + 1, box[0], box[1], box[2], box[3]):
        box[5] += 1
    return True


@jitable
def _grow(occ, box, direction, step, limit):
    """Grow ``box`` in ``direction`` (0 +s, 1 −s, 2 +d, 3 −d) by up to ``step`` free layers, not beyond index
    ``limit``; whether it can grow further (all ``step`` layers were there and free)."""
    if direction == 0:
        layers = min(box[1] + step, limit) - box[1]
    elif direction == 1:
        layers = box[0] - max(box[0] - step, limit)
    elif direction == 2:
        layers = min(box[3] + step, limit) - box[3]
    else:
        layers = box[2] - max(box[2] - step, limit)
    layers = max(layers, 0)
    free = 0
    while free < layers and not _layer_blocked(occ, box, direction, free):
        free += 1
    if direction == 0:
        box[1] += free
    elif direction == 1:
        box[0] -= free
    elif direction == 2:
        box[3] += free
    else:
        box[2] -= free
    return free == step and layers == step


@jitable
def _layer_blocked(occ, box, direction, m):
    """Whether layer ``m`` (0: the one next to the box) beyond the box in ``direction`` has a cell occupied at any
    time slice of the box."""
    if direction <= 1:
        i = box[1] + 1 + m if direction == 0 else box[0] - 1 - m
        return _any_in(occ, box[4], box[5], i, i, box[2], box[3])
    j = box[3] + 1 + m if direction == 2 else box[2] - 1 - m
    return _any_in(occ, box[4], box[5], box[0], box[1], j, j)
