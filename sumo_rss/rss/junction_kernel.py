"""The junction pairs of one audit step, compiled with numba (rss.md §4; issue 47 item 3).

:func:`~.intersection.intersection_situations` finds the step's entries (a car on a link, at a position along
the link's path) with numpy and hands them to :func:`junction_pairs`, which does the per-pair work in one call:
the entry pairs whose links share a conflict area (through each link's conflicting links, never every two entries),
each named by id order, their distances to the area and from it, the priority the signals or the junction give,
the three conditions of :func:`~.intersection.intersection_safety` and the situation's margin. The formulas are the
jitable ones the numpy code uses (:func:`~.intersection.stop_and_front`, :func:`~.formulas.time_to_cover`,
:func:`~.intersection.no_time_overlap`): one source. Per step numpy paid ~500 calls over a few dozen elements
each; the kernel is one call. Units: m, s, m/s.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel, rss_row
from .formulas import time_to_cover
from .intersection import (KIND_SAME, KIND_SIGNAL, KIND_YIELD, PRIORITY_A, PRIORITY_B, PRIORITY_SAME, no_time_overlap,
                           stop_and_front)
from .situations import RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_NO_OVERLAP

# Rows of junction_pairs' outputs, in the types PairSituations holds them (no conversion per step).
FLOAT_COLUMNS = ("lon_gap", "v_lon_a", "v_lon_b", "lon_d_min", "enter_a", "enter_b")  # float64
INT_COLUMNS = ("a", "b", "kind", "pair")  # int64
FLAG_COLUMNS = ("a_is_rear", "safe")  # bool
CODE_COLUMNS = ("rules", "priority", "in_front")  # int8


@kernel
def entries(lane, lane_pos, next_edge, route_edges, levels, horizon, lane_link, lane_link_offset, lane_links,
            link_to_edge, link_to_lane, link_length, lane_length, lane_edge):
    """Vehicles' entries into junction links: (vehicle row, link, front bumper position along the link's path [m],
    negative before its start). A vehicle on an internal lane (``lane``, its position ``lane_pos`` [m]) is on that
    lane's link; one on an approach lane within ``horizon`` [m] of its end takes the link to its route's next edge
    ``next_edge`` (every link from its lane where that is unknown, -1; an empty ``next_edge``: the edge after the
    lane's on the vehicle's ``route_edges``, as :func:`~.intersection.next_route_edge` gives it). Then, up to
    ``levels`` times, the links at the next junction along each entry's route (``route_edges`` [n, k], -1 padded),
    from the lane its link leads into, where the route is known and the link starts within ``horizon`` of the front
    bumper: where edges between junctions are short (a roundabout's 20 m) a car is in its conflicts at the next
    junction before it reaches the edge leading there. In order: the vehicles inside, the approaching ones (by row,
    then their lane's links), then each further level by the entry it follows. The rest are the junction model's and
    the network's arrays."""
    n, width = lane.size, lane_links.shape[1]
    rows = np.empty(n * (1 + width), dtype=np.int64)
    links = np.empty(rows.size, dtype=np.int64)
    pos = np.empty(rows.size)
    m = 0
    for i in range(n):
        if lane_link[lane[i]] >= 0:
            rows[m], links[m], pos[m] = i, lane_link[lane[i]], lane_link_offset[lane[i]] + lane_pos[i]
            m += 1
    for i in range(n):
        to_end = lane_length[lane[i]] - lane_pos[i]
        if to_end > horizon:
            continue
        after = next_edge[i] if next_edge.size else _next_on_route(route_edges, i, lane_edge[lane[i]])
        for c in range(width):
            k = lane_links[lane[i], c]
            if k >= 0 and (after < 0 or link_to_edge[k] == after):
                rows[m], links[m], pos[m] = i, k, -to_end
                m += 1
    first = 0
    for _ in range(levels):
        size = m + (m - first) * width  # at most every link from each entry's next lane
        if size > rows.size:
            rows, links, pos = _grown(rows, size), _grown(links, size), _grown(pos, size)
        last = m
        for e in range(first, last):
            onto = link_to_lane[links[e]]
            start = (link_length[links[e]] - pos[e]) + lane_length[onto]  # [m] to the start of the next link
            after = _next_on_route(route_edges, rows[e], lane_edge[onto])
            for c in range(width):
                k = lane_links[onto, c]
                if k >= 0 and after >= 0 and start <= horizon and link_to_edge[k] == after:
                    rows[m], links[m], pos[m] = rows[e], k, -start
                    m += 1
        if m == last:
            break
        first = last
    return rows[:m], links[:m], pos[:m]


@kernel
def _next_on_route(route_edges, row, edge):
    """The edge after ``edge`` on row ``row``'s route (its first occurrence), -1 if unknown."""
    for c in range(route_edges.shape[1] - 1):
        if route_edges[row, c] == edge:
            return route_edges[row, c + 1]
    return -1


@kernel
def next_route_edges(route_edges, edge):
    """[n] the edge after ``edge[i]`` on row i's remaining route (its first occurrence), -1 where unknown: what
    :func:`~.intersection.next_route_edge` gives (numpy's [n, route length] comparison and argmax: ~0.1 ms a step
    for a city's 450 cars)."""
    out = np.empty(edge.size, dtype=np.int64)
    for i in range(edge.size):
        out[i] = _next_on_route(route_edges, i, edge[i])
    return out


@kernel
def _grown(values, size):
    """``values`` copied into a longer array of ``size`` (the rest uninitialised)."""
    out = np.empty(size, dtype=values.dtype)
    for k in range(values.size):
        out[k] = values[k]
    return out


@kernel
def conflicting_entries(links, indptr, other):
    """(i, j, k): every two entries i < j whose links share a conflict area, in (i, j) order, and the number of
    their link pair (links[i], links[j]) (``indptr``, ``other``: :class:`~..road.link_pairs.LinkPairList`'s).
    Found through each entry's conflicting links and the entries on those: the work grows with the pairs that
    conflict, not with the square of the entries. They are found in i order; two counting passes (by j, then into
    each i's block) put each block in j order without a sort (an argsort of the pairs was half the function)."""
    e = links.size
    by_link = np.argsort(links, kind="mergesort")
    on_link = links[by_link]
    block = np.zeros(e + 1, dtype=np.int64)  # block[i + 1]: pairs of entry i, then where i's block starts
    for i in range(e):
        for k in range(indptr[links[i]], indptr[links[i] + 1]):
            lo, hi = np.searchsorted(on_link, other[k], "left"), np.searchsorted(on_link, other[k], "right")
            for m in range(lo, hi):
                block[i + 1] += by_link[m] > i
    for i in range(e):
        block[i + 1] += block[i]
    found = np.empty((3, block[e]), dtype=np.int64)
    of_j = np.zeros(e + 1, dtype=np.int64)  # of_j[j + 1]: pairs with second entry j, then where j's run starts
    n = 0
    for i in range(e):
        for k in range(indptr[links[i]], indptr[links[i] + 1]):
            lo, hi = np.searchsorted(on_link, other[k], "left"), np.searchsorted(on_link, other[k], "right")
            for m in range(lo, hi):
                if by_link[m] > i:
                    found[0, n], found[1, n], found[2, n] = i, by_link[m], k
                    of_j[by_link[m] + 1] += 1
                    n += 1
    for j in range(e):
        of_j[j + 1] += of_j[j]
    by_j = np.empty(n, dtype=np.int64)  # the pairs in j order (in i order within each j)
    for t in range(n):
        by_j[of_j[found[1, t]]] = t
        of_j[found[1, t]] += 1
    out = np.empty((3, n), dtype=np.int64)
    for t in by_j:  # into each i's block, in j order
        i = found[0, t]
        out[0, block[i]], out[1, block[i]], out[2, block[i]] = i, found[1, t], found[2, t]
        block[i] += 1
    return out


@kernel
def junction_pairs(rows, links, pos, id_rank, indptr, other, reverse, start, end, static_priority, area,
                   area_crossing, link_tls_index, ranks, length, v_forward, rss_table):
    """Every pair of entries (vehicle ``rows``, ``links``, front bumper ``pos`` along the link's path [m]) of two
    vehicles whose links share a conflict area that neither has left, named by id order (``id_rank``: each
    vehicle's rank among the step's ids), evaluated. The conflict pairs' tables (``indptr`` ... ``area``) are
    :class:`~..road.junctions.ConflictPairs`'; ``ranks``: the links' signal ranks; per vehicle ``length`` [m],
    ``v_forward`` (speed along the lane, floored at 0) [m/s] and ``rss_table`` [n, fields]. Returns [FLOAT_COLUMNS, m]
    floats, [INT_COLUMNS, m] int64 (``pair``: the number of a's link pair, for its area's id), [FLAG_COLUMNS, m]
    bools and [CODE_COLUMNS, m] int8."""
    found = conflicting_entries(links, indptr, other)
    floats = np.empty((len(FLOAT_COLUMNS), found.shape[1]))
    ints = np.empty((len(INT_COLUMNS), found.shape[1]), dtype=np.int64)
    flags = np.empty((len(FLAG_COLUMNS), found.shape[1]), dtype=np.bool_)
    codes = np.empty((len(CODE_COLUMNS), found.shape[1]), dtype=np.int8)
    n = 0
    for t in range(found.shape[1]):
        i, j, k = found[0, t], found[1, t], found[2, t]
        if rows[i] == rows[j]:
            continue
        swap = id_rank[rows[i]] > id_rank[rows[j]]
        ea, eb = (j, i) if swap else (i, j)
        ka = reverse[k] if swap else k
        kb = reverse[ka]
        ra, rb, la, lb = rows[ea], rows[eb], links[ea], links[eb]
        enter_a, exit_a = start[ka] - pos[ea], end[ka] - pos[ea] + length[ra]
        enter_b, exit_b = start[kb] - pos[eb], end[kb] - pos[eb] + length[rb]
        if not (exit_a > 0.0 and exit_b > 0.0):  # a car that has left the area is in no conflict there any more
            continue
        # Priority (link_priority): the signals where both links are signalised with different ranks, else the
        # junction's static priority (none where a signal's state is unknown).
        rank_a, rank_b = ranks[la], ranks[lb]
        by_signal = rank_a >= 0 and rank_b >= 0 and rank_a != rank_b
        unknown = (link_tls_index[la] >= 0 and rank_a < 0) or (link_tls_index[lb] >= 0 and rank_b < 0)
        static = 0 if unknown else static_priority[ka]
        if by_signal:
            priority = PRIORITY_A if rank_a > rank_b else PRIORITY_B
        else:
            priority = PRIORITY_A if static > 0 else (PRIORITY_B if static < 0 else PRIORITY_SAME)
        v_a, v_b = v_forward[ra], v_forward[rb]
        p_a, p_b = rss_row(rss_table, ra), rss_row(rss_table, rb)
        able, in_front, a_front, b_front, need_a, need_b = stop_and_front(
            v_a, enter_a, length[ra], p_a, v_b, enter_b, length[rb], p_b, priority, area_crossing[area[ka]])
        no_overlap = no_time_overlap(
            time_to_cover(v_a, max(enter_a, 0.0), p_a.response_time, p_a.lon_accel_max, -p_a.lon_brake_min,
                          p_a.max_speed_on_accel),
            time_to_cover(v_b, max(enter_b, 0.0), p_b.response_time, p_b.lon_accel_max, -p_b.lon_brake_min,
                          p_b.max_speed_on_accel),
            time_to_cover(v_a, exit_a, p_a.response_time, -p_a.lon_brake_max, -p_a.lon_brake_max,
                          p_a.max_speed_on_accel),
            time_to_cover(v_b, exit_b, p_b.response_time, -p_b.lon_brake_max, -p_b.lon_brake_max,
                          p_b.max_speed_on_accel))
        # Margin of the yielding car (with equal priority, of the one deeper in trouble).
        a_yields = priority == PRIORITY_B or (priority == PRIORITY_SAME and enter_a - need_a <= enter_b - need_b)
        floats[0, n] = enter_a if a_yields else enter_b
        floats[1, n], floats[2, n] = v_a, v_b
        floats[3, n] = need_a if a_yields else need_b
        floats[4, n], floats[5, n] = enter_a, enter_b
        ints[0, n], ints[1, n] = ra, rb
        ints[2, n] = KIND_SIGNAL if by_signal else (KIND_YIELD if priority != PRIORITY_SAME else KIND_SAME)
        ints[3, n] = ka
        flags[0, n] = not a_front
        flags[1, n] = able or in_front or no_overlap
        codes[0, n] = able * RULE_ABLE_TO_STOP + in_front * RULE_IN_FRONT + no_overlap * RULE_NO_OVERLAP
        codes[1, n] = priority
        codes[2, n] = 1 if a_front else (2 if b_front else 0)
        n += 1
    return floats[:, :n], ints[:, :n], flags[:, :n], codes[:, :n]
