"""RSS safety of two cars whose paths meet in a conflict area (rss.md §4; paper Def. 16-18; ad_rss's checker).

Each car is described by its speed, d_enter (front bumper to the start of the area, negative once inside) and
d_exit (rear bumper to the end of the area: how far until it has fully left) along its own path. The pair is
safe if any of three conditions holds:

1. *able to stop*: every car without priority (both, with equal priority) can stop before the area, braking at
   b_min after accelerating during ρ: D(v) + λ < d_enter;
2. *in front*: on a virtual line through the area, one car is wholly ahead of the other (its rear bumper before
   the other's front bumper) by more than the same-direction safe distance;
3. *no time overlap*: one car's earliest arrival (accelerating during ρ, then braking at b_min) comes after the
   other's latest exit (braking at b_max from now), or neither can arrive at all.

Formulas follow ad_rss 5.0.0 number for number, with four deliberate differences (docs/rss.md): with equal
priority condition 1 needs *both* cars able to stop (ad_rss accepts either), each car's own speed cap is used in
condition 3 (ad_rss applies the ego's cap to both), a car that has fully left the conflict area is out of the
situation (:func:`intersection_situations`), and where the paths cross (rather than merge or diverge) condition 2
asks the car behind to be able to stop before the area. All functions broadcast over numpy arrays.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..jit import jitable, select
from ..road.junctions import JunctionModel
from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .formulas import is_safe_distance, lon_reach, lon_safe_distance_same_dir, time_to_cover
from .junction_exits import with_leaving
from .params import PARAM_NAMES, RssParamArrays
from .situations import SITUATION_CODES, PairSituations, SituationType, VehicleFrame

TIME_PRECISION = 1e-3  # [s] arrival must follow exit by more than this (ad_rss's Duration tolerance)
JUNCTIONS_AHEAD = 3  # further junctions along a route (after the next) that a vehicle within the horizon takes part in
KIND_SIGNAL = SITUATION_CODES.index(SituationType.INTERSECTION_PRIORITY)
KIND_YIELD = SITUATION_CODES.index(SituationType.INTERSECTION_YIELD)
KIND_SAME = SITUATION_CODES.index(SituationType.INTERSECTION_SAME_PRIORITY)
PRIORITY_SAME, PRIORITY_A, PRIORITY_B = 0, 1, 2
_NO_EDGES, _NO_ROUTES = np.zeros(0, dtype=np.int64), np.zeros((0, 0), dtype=np.int64)  # the kernel's "none given"


@dataclass(frozen=True, eq=False)
class IntersectionSafety:
    """Which of the three conditions hold, per pair (arrays of bool)."""

    able_to_stop: np.ndarray
    in_front: np.ndarray
    no_time_overlap: np.ndarray
    a_in_front: np.ndarray  # a's rear bumper is ahead of b's front bumper on the virtual line
    b_in_front: np.ndarray
    need_a: np.ndarray  # [m] what a needs to stop before the area: D(v) + λ
    need_b: np.ndarray

    @property
    def safe(self) -> np.ndarray:
        return self.able_to_stop | self.in_front | self.no_time_overlap


def intersection_safety(v_a: Any, enter_a: Any, exit_a: Any, length_a: Any, p_a: Any,
                        v_b: Any, enter_b: Any, exit_b: Any, length_b: Any, p_b: Any,
                        priority: Any, crossing: Any = False) -> IntersectionSafety:
    """Evaluate the three conditions. Speeds ≥ 0 [m/s]; distances and lengths [m]; ``priority`` PRIORITY_*.
    ``crossing``: the two paths cross in the area (False: ad_rss's virtual line throughout). There the car in front
    is an obstacle across the other's path, not a leader along it: the one behind it on the virtual line is at a
    safe distance only if it can stop both behind the front car on the line and before the area, against a
    standing front car (the virtual line alone measured a left-turner standing 7.4 m into the area as 7.4 m further
    ahead of the oncoming car than it was; the area alone would let a car with priority that could stop before it
    be the one 'behind' a car running its yield, which is not in front of it). The formulas are
    :func:`stop_and_front`, :func:`~.formulas.time_to_cover` and :func:`no_time_overlap`, which the auditor's
    compiled junction kernel (:mod:`.junction_kernel`) calls per pair."""
    enter_a, enter_b = np.asarray(enter_a, dtype=float), np.asarray(enter_b, dtype=float)
    able, in_front, a_front, b_front, need_a, need_b = stop_and_front(
        v_a, enter_a, length_a, p_a, v_b, enter_b, length_b, p_b, np.asarray(priority), np.asarray(crossing, dtype=bool))
    # The four crossing times in one call.
    arrive_a, arrive_b, leave_a, leave_b = time_to_cover(*_side_by_side(
        (v_a, v_b, v_a, v_b), (np.maximum(enter_a, 0.0), np.maximum(enter_b, 0.0), exit_a, exit_b),
        (p_a.response_time, p_b.response_time, p_a.response_time, p_b.response_time),
        (p_a.lon_accel_max, p_b.lon_accel_max, -np.asarray(p_a.lon_brake_max), -np.asarray(p_b.lon_brake_max)),
        (-np.asarray(p_a.lon_brake_min), -np.asarray(p_b.lon_brake_min), -np.asarray(p_a.lon_brake_max),
         -np.asarray(p_b.lon_brake_max)),
        (p_a.max_speed_on_accel, p_b.max_speed_on_accel, p_a.max_speed_on_accel, p_b.max_speed_on_accel)))
    return IntersectionSafety(able, in_front, no_time_overlap(arrive_a, arrive_b, leave_a, leave_b), a_front, b_front,
                              need_a, need_b)


@jitable
def stop_and_front(v_a: Any, enter_a: Any, length_a: Any, p_a: Any, v_b: Any, enter_b: Any, length_b: Any,
                   p_b: Any, priority: Any, crossing: Any) -> tuple:
    """Conditions 1 and 2 of :func:`intersection_safety` (same arguments): (able to stop, in front, a wholly in
    front of b, b wholly in front of a, what a needs to stop before the area D(v) + λ [m], what b needs [m])."""
    # 1. Able to stop before the area (a car inside can not).
    need_a = lon_reach(v_a, p_a, p_a.lon_brake_min) + p_a.min_lon_gap
    need_b = lon_reach(v_b, p_b, p_b.lon_brake_min) + p_b.min_lon_gap
    stop_a = is_safe_distance(np.maximum(enter_a, 0.0), need_a)
    stop_b = is_safe_distance(np.maximum(enter_b, 0.0), need_b)
    able = select(priority == PRIORITY_A, stop_b, select(priority == PRIORITY_B, stop_a, stop_a & stop_b))
    # 2. One wholly in front of the other on the virtual line, at a safe same-direction distance.
    a_front = enter_b > enter_a + length_a
    b_front = enter_a > enter_b + length_b
    gap = select(a_front, enter_b - enter_a - length_a, enter_a - enter_b - length_b)  # along the virtual line
    # Where the paths cross, also short of the area: the front car may stand in it across the rear car's path.
    gap = select(crossing, np.minimum(gap, np.maximum(select(a_front, enter_b, enter_a), 0.0)), gap)
    v_a_lead, v_b_lead = select(crossing, 0.0, v_a), select(crossing, 0.0, v_b)
    d_min = select(a_front, lon_safe_distance_same_dir(v_b, v_a_lead, p_b, p_a),
                   lon_safe_distance_same_dir(v_a, v_b_lead, p_a, p_b))
    in_front = (a_front | b_front) & is_safe_distance(gap, d_min)
    return able, in_front, a_front, b_front, need_a, need_b


@jitable
def no_time_overlap(arrive_a: Any, arrive_b: Any, leave_a: Any, leave_b: Any) -> np.ndarray:
    """Condition 3: one car's earliest arrival [s] comes after the other's latest exit [s], or neither can
    arrive."""
    return (arrive_a > leave_b + TIME_PRECISION) | (arrive_b > leave_a + TIME_PRECISION) | \
        (np.isinf(arrive_a) & np.isinf(arrive_b))


def _side_by_side(*groups: tuple[Any, ...]) -> list[np.ndarray]:
    """Each group of four values broadcast to the shape of all of them and laid side by side along a new first
    axis ([4, ...]): one call of an element-wise function then evaluates all four (numpy's cost per call, not per
    element, is what a step of a few dozen pairs pays)."""
    shapes = {np.shape(x) for group in groups for x in group}
    shape = shapes.pop() if len(shapes) == 1 else np.broadcast_shapes(*shapes)
    return [np.concatenate([np.asarray(x, dtype=float).reshape(-1) if np.shape(x) == shape else
                            np.broadcast_to(np.asarray(x, dtype=float), shape).reshape(-1) for x in group]
                           ).reshape((4,) + shape) for group in groups]


def next_route_edge(route_edges: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """The route edge after each vehicle's current edge (``route_edges``: [n, k] the remaining routes, -1 padded),
    -1 where unknown (no route, or not on it); compiled (:func:`.junction_kernel.next_route_edges`)."""
    from .junction_kernel import next_route_edges  # numba: only where junctions are

    return next_route_edges(np.asarray(route_edges, dtype=np.int64), np.asarray(edge, dtype=np.int64))


def area_distances(junctions: JunctionModel, link: Any, foe: Any, pos: Any, length: Any
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(d_enter, d_exit) [m] of a car on ``link`` to its conflict area with ``foe``'s link: from its front bumper
    at ``pos`` along the link's path to the area's start (negative once inside), and from its rear bumper
    (``length`` behind) to the area's end."""
    return junctions.area_start[link, foe] - pos, junctions.area_end[link, foe] - pos + length


def link_priority(junctions: JunctionModel, ranks: np.ndarray, la: Any, lb: Any, static: Any = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(PRIORITY_* of link ``la`` against link ``lb``, whether the signals decided it), given the links' signal
    ``ranks`` (:meth:`JunctionModel.signal_ranks`). The signals decide where both links are signalised and their
    ranks differ, else the junction (its ``static`` priority of la against lb where known, as
    ``JunctionModel.static_priority`` gives it); a signalised link whose state is unknown (offline, actuated program)
    gives no priority either way."""
    rank_a, rank_b = ranks[la], ranks[lb]
    by_signal = (rank_a >= 0) & (rank_b >= 0) & (rank_a != rank_b)
    unknown = ((junctions.link_tls_index[la] >= 0) & (rank_a < 0)) | \
        ((junctions.link_tls_index[lb] >= 0) & (rank_b < 0))
    static = np.where(unknown, 0, junctions.static_priority[la, lb] if static is None else static)
    priority = np.where(by_signal, np.where(rank_a > rank_b, PRIORITY_A, PRIORITY_B),
                        np.where(static > 0, PRIORITY_A, np.where(static < 0, PRIORITY_B, PRIORITY_SAME)))
    return priority, by_signal


def junction_entries(lane: np.ndarray, lane_pos: np.ndarray, next_edge: np.ndarray | None, network: RoadNetwork,
                     junctions: JunctionModel, horizon: float, levels: int = 0,
                     route_edges: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vehicles' entries into junction links: (vehicle row, link, front bumper position along the link's path [m],
    negative before its start). A vehicle on an internal lane is on that lane's link; one on an approach lane within
    ``horizon`` [m] of its end takes the link to its route's next edge ``next_edge`` (every link from its lane where
    that is unknown, -1; None: :func:`next_route_edge` of ``route_edges``, found in the kernel). With ``levels`` and
    the vehicles' ``route_edges``: also the entries at up to ``levels`` further junctions along each known route
    whose links start within ``horizon`` (:func:`.junction_kernel.entries`, compiled)."""
    from .junction_kernel import entries  # numba: only where junctions are

    return entries(lane, lane_pos, _NO_EDGES if next_edge is None else next_edge,
                   _NO_ROUTES if route_edges is None else route_edges,
                   levels, float(horizon), junctions.lane_link, junctions.lane_link_offset, junctions.lane_links,
                   junctions.link_to_edge, junctions.link_to_lane, junctions.link_length, network.lane_length,
                   network.lane_edge)


def intersection_situations(snapshot: WorldSnapshot, frame: VehicleFrame, network: RoadNetwork,
                            junctions: JunctionModel, horizon: float) -> PairSituations:
    """Every pair of vehicles whose links through a junction share a conflict area, one situation per pair and
    area (the auditor keeps the most critical per pair). Vehicles within ``horizon`` [m] of a junction take part:
    on an approach lane with the link to their route's next edge (every link from their lane when the route is
    unknown), already on the link's internal lanes, or leaving it with the rear bumper still on them
    (:mod:`.junction_exits`)."""
    rows, links, pos = with_leaving(junction_entries(frame.lane, frame.lane_pos, None, network, junctions, horizon,
                                                     JUNCTIONS_AHEAD, frame.route_edges),
                                    snapshot, frame.lane, frame.lane_pos, network, junctions)
    from .junction_kernel import junction_pairs  # numba: only where junctions are

    table, pairs = junctions.conflict_pairs, junctions.conflict_pairs.pairs
    id_rank = np.empty(len(snapshot.ids), dtype=np.int64)
    id_rank[np.argsort(snapshot.ids, kind="stable")] = np.arange(len(snapshot.ids))
    floats, ints, flags, codes = junction_pairs(
        rows, links, pos, id_rank, pairs.indptr, pairs.other, pairs.reverse, table.start, table.end,
        table.static_priority, table.area, junctions.area_crossing, junctions.link_tls_index,
        junctions.signal_ranks(snapshot.tls_states), snapshot.length, np.maximum(frame.v_lon, 0.0),
        param_table(frame.params))
    n = ints.shape[1]
    if not n:  # most steps of a city: nothing to evaluate
        return _no_situations()
    (lon_gap, v_lon_a, v_lon_b, lon_d_min, enter_a, enter_b), (a, b, kind, pair) = floats, ints
    nan, no = np.full(n, np.nan), np.zeros(n, dtype=bool)
    return PairSituations(
        a=a, b=b, kind=kind, a_is_rear=flags[0], a_is_left=no, lon_gap=lon_gap, lat_gap=nan, v_lon_a=v_lon_a,
        v_lon_b=v_lon_b, v_lat_a=np.zeros(n), v_lat_b=np.zeros(n), lon_d_min=lon_d_min, lat_d_min=nan,
        lon_safe=flags[1], lat_safe=no, rules=codes[0], priority=codes[1], in_front=codes[2],
        area=table.area_id[pair], enter_a=enter_a, enter_b=enter_b)


def param_table(params: RssParamArrays) -> np.ndarray:
    """[n, fields] the vehicles' RSS parameters in PARAM_NAMES' order, as the junction kernel reads them (one copy
    of the fields laid row by row; the transposed view, not a contiguous copy)."""
    return np.array([getattr(params, name) for name in PARAM_NAMES], dtype=float).T



def _no_situations() -> PairSituations:
    """No junction situation (the arrays' types as :func:`intersection_situations` gives them)."""
    none, flags, codes = np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0, dtype=np.int8)
    rows = np.zeros(0, dtype=int)
    return PairSituations(a=rows, b=rows, kind=rows, a_is_rear=flags, a_is_left=flags, lon_gap=none, lat_gap=none,
                          v_lon_a=none, v_lon_b=none, v_lat_a=none, v_lat_b=none, lon_d_min=none, lat_d_min=none,
                          lon_safe=flags, lat_safe=flags, rules=codes, priority=codes, in_front=codes,
                          area=np.zeros(0, dtype=object), enter_a=none, enter_b=none)
