"""The road pairs of one audit step, their gaps, safe distances and verdicts in one compiled pass (rss.md §2-§3;
issue 47).

:func:`~.situations.evaluate` puts the other car of each pair into the reference lane's frame with numpy (a few
rows need the road graph: chained edges, the two directions of a road) and hands the pairs to :func:`road_pairs`,
which does what was ~40 numpy passes over the ~30,000 pairs of a dense highway step (each a temporary array): the
bumper-to-bumper gaps, which car is left, the safe distances from the per-car terms of the
:class:`~.situations.VehicleFrame`, merges, the naming by id order and the verdicts. The formulas are the jitable
ones the numpy code uses (:func:`~.formulas.combine_same_dir`, :func:`~.formulas.combine_lateral`,
:func:`~.formulas.is_safe_distance`): one source, the same operations in the same order, so the numbers are the
numpy path's bit for bit. Units: m, m/s.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel
from .formulas import combine_lateral, combine_same_dir, is_safe_distance
from .situations import SITUATION_CODES, SituationType

OPPOSITE_CODE = SITUATION_CODES.index(SituationType.OPPOSITE_DIRECTION)
MERGE_CODE = SITUATION_CODES.index(SituationType.MERGE)
# Rows of road_pairs' outputs, in the order it returns them.
FLOAT_COLUMNS = ("lon_gap", "lat_gap", "lat_offset", "v_lon_a", "v_lon_b", "v_lat_a", "v_lat_b", "lon_d_min",
                 "lat_d_min")  # float64
INT_COLUMNS = ("a", "b", "kind")  # int64
FLAG_COLUMNS = ("a_is_rear", "a_is_left", "lon_safe", "lat_safe", "wrong_way_a", "wrong_way_b")  # bool


@kernel
def candidate_keys(cx, cy, reach, min_gap, size):
    """int64 keys i·n + j (i < j, unsorted) of the vehicle pairs whose centres (``cx``, ``cy`` [m]) are within
    both cars' worst-case ``reach``, the larger λ ``min_gap`` and both half sizes ``size`` [m] of each other.

    Sweep and prune: each car's square of half width e = reach + size + λ_max / 2 (a pair's bound never exceeds the
    sum of the two cars' e), the squares swept along the axis the cars spread most along, and only the pairs whose
    squares overlap on both axes checked. Cost grows with the cars and their near neighbours, not their square."""
    n = cx.size
    keys = np.empty(max(16, 4 * n), dtype=np.int64)
    if n < 2:
        return keys[:0]
    extent = (reach + size + 0.5 * min_gap.max()) * (1.0 + 1e-9) + 1e-6  # a little wider for rounding
    along, across = (cx, cy) if cx.max() - cx.min() >= cy.max() - cy.min() else (cy, cx)
    low = along - extent
    order = np.argsort(low, kind="mergesort")
    count = 0
    for a in range(n):
        p = order[a]
        high = along[p] + extent[p]
        for b in range(a + 1, n):
            q = order[b]
            if low[q] > high:
                break
            if abs(across[p] - across[q]) > extent[p] + extent[q]:
                continue
            i, j = min(p, q), max(p, q)
            dist = np.hypot(cx[i] - cx[j], cy[i] - cy[j])
            if dist <= reach[i] + reach[j] + np.maximum(min_gap[i], min_gap[j]) + size[i] + size[j]:
                if count == keys.size:
                    grown = np.empty(2 * keys.size, dtype=np.int64)
                    grown[:count] = keys
                    keys = grown
                keys[count] = i * n + j
                count += 1
    return keys[:count]


@kernel
def road_pairs(ref, other, kind, pos_o, d_o, v_lon_o, v_lat_o, opposite_lat_left, opposite_lat_right,
               opposite_lon_d_min, rank, lane, pos, d, v_lon, v_lat, half_lon, half_lat, reach_min, stop_max,
               lat_reach_as_left, lat_reach_as_right, min_lon_gap, lat_margin, wrong_way, lane_ends, lane_left):
    """(floats [9, m], ints [3, m], flags [6, m]; rows FLOAT_COLUMNS, INT_COLUMNS, FLAG_COLUMNS) of the road pairs
    (reference row ``ref``, other row ``other``, situation ``kind``: 0 same direction, 1 opposite) with the other
    car's position, offset and speeds in the reference lane's frame (``pos_o``, ``d_o``, ``v_lon_o``, ``v_lat_o``).
    Opposite pairs' lateral reaches and longitudinal safe distance are computed by the caller in the reference frame
    (``opposite_*``, read at those rows only). ``rank``: each vehicle's place in id order; the rest are the vehicle
    frame's arrays (per snapshot row: ``lane``, ``pos``, ..., ``wrong_way``; ``min_lon_gap`` λ, ``lat_margin`` μ)
    and the network's per-lane ``lane_ends`` and ``lane_left``."""
    m = ref.size
    floats = np.empty((9, m))
    ints = np.empty((3, m), dtype=np.int64)
    flags = np.empty((6, m), dtype=np.bool_)
    for k in range(m):
        r, o = ref[k], other[k]
        same = kind[k] != OPPOSITE_CODE
        lon_gap = np.abs(pos_o[k] - pos[r]) - half_lon[o] - half_lon[r]
        lat_gap = np.abs(d_o[k] - d[r]) - half_lat[o] - half_lat[r]
        other_left = d_o[k] > d[r]
        if same:
            lat_left_o, lat_right_o = lat_reach_as_left[o], lat_reach_as_right[o]
            lon_d_min = combine_same_dir(reach_min[o], stop_max[r], min_lon_gap[o])
        else:
            lat_left_o, lat_right_o = opposite_lat_left[k], opposite_lat_right[k]
            lon_d_min = opposite_lon_d_min[k]
        if other_left:
            lat_d_min = combine_lateral(lat_left_o, lat_reach_as_right[r], lat_margin[o], lat_margin[r])
        else:
            lat_d_min = combine_lateral(lat_reach_as_left[r], lat_right_o, lat_margin[r], lat_margin[o])
        code = kind[k]
        if same and ((lane_ends[lane[r]] and lane_left[lane[r]] == lane[o]) or
                     (lane_ends[lane[o]] and lane_left[lane[o]] == lane[r])):
            code = MERGE_CODE
        a_is_ref = rank[r] < rank[o]
        v_ref_lon = np.maximum(v_lon[r], 0.0)
        v_other_lon = np.maximum(v_lon_o[k], 0.0) if same else np.maximum(-v_lon_o[k], 0.0)
        floats[0, k], floats[1, k], floats[2, k] = lon_gap, lat_gap, np.abs(d_o[k] - d[r])
        floats[3, k] = v_ref_lon if a_is_ref else v_other_lon
        floats[4, k] = v_other_lon if a_is_ref else v_ref_lon
        floats[5, k] = v_lat[r] if a_is_ref else v_lat_o[k]
        floats[6, k] = v_lat_o[k] if a_is_ref else v_lat[r]
        floats[7, k], floats[8, k] = lon_d_min, lat_d_min
        ints[0, k], ints[1, k], ints[2, k] = (r, o, code) if a_is_ref else (o, r, code)
        flags[0, k] = (not a_is_ref) if same else a_is_ref  # opposite pairs: "a is the reference car"
        flags[1, k] = (not other_left) if a_is_ref else other_left
        flags[2, k] = is_safe_distance(lon_gap, lon_d_min)
        flags[3, k] = is_safe_distance(lat_gap, lat_d_min)
        flags[4, k] = wrong_way[r] if a_is_ref else wrong_way[o]
        flags[5, k] = wrong_way[o] if a_is_ref else wrong_way[r]
    return floats, ints, flags
