"""Situations: which vehicle pairs matter at one step, in which coordinate frame, and are they safe.

Stages (each a function over index arrays, no loop over pairs):
1. :func:`candidate_pairs` — the pairs whose centres are within both cars' worst-case stopping distances at
   current speeds plus λ and their sizes (a compiled sweep over each car's reach along the axis they spread on).
2. :func:`classify` — same direction (same edge, or one edge ahead of the other along the route, or along any
   path when the route is unknown) or opposite direction (the two directions of one road, approaching).
   Intersection and merge situations (conflicting routes through a junction) are the next stage to add here.
3. :func:`evaluate` — bumper-to-bumper longitudinal and lateral gaps in the frame of a reference lane (the front
   car's lane; car ``a``'s lane for opposite pairs), speeds in that frame, the safe distances and the verdicts.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from enum import Enum
from functools import lru_cache
from typing import Any

import numpy as np

from ..angles import wrap_angle
from ..jit import jitable
from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .formulas import combine_opposite, lateral_reach, lon_reach, stopping_distance
from .params import RssParamArrays


class SituationType(str, Enum):
    """Kinds of situation; the values go into the CSVs."""

    SAME_DIRECTION = "same-direction"
    OPPOSITE_DIRECTION = "opposite-direction"
    MERGE = "merge"  # same direction, one car on a lane that ends beside the other's (an acceleration lane)
    INTERSECTION_PRIORITY = "intersection-priority"  # paths cross in a junction; the signals give one priority
    INTERSECTION_YIELD = "intersection-yield"  # ... the junction's right of way gives one priority
    INTERSECTION_SAME_PRIORITY = "intersection-same-priority"  # ... neither has priority


SITUATION_CODES = tuple(SituationType)  # index = code in arrays
SAME_DIRECTION_CODES = (0, 2)  # same direction and merge: one car follows the other
FIRST_INTERSECTION_CODE = 3
FOOTPRINT_MIN_SPEED = 0.05  # [m/s] below this a car's footprint lies along its lane (its motion has no direction)
# [rad] SUMO's angle of a car standing still is its rear-to-front direction along its path, within 1.2° of its lane's
# (measured on the shipped junctions' curves); further off, it is a lane change's leftover (body_poses).
LEFTOVER_ANGLE = np.radians(10.0)
WRONG_WAY_COS = -0.94  # a car heading within 20° of its lane's opposite direction drives against it
# Safety rules that held, as bits (what was still safe just before t_b decides the owed response).
RULE_LON, RULE_LAT = 1, 2  # roads: longitudinally / laterally safe
RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_NO_OVERLAP = 1, 2, 4  # intersections (rss.md §4)


@dataclass(frozen=True, eq=False)
class VehicleFrame:
    """Per-vehicle quantities (one row per snapshot row), in each vehicle's own lane frame.

    Every term of the safe distances that depends on one car only is here, computed once per vehicle; pairs on
    one road (parallel lanes, or lanes chained along it) combine them directly; pairs on the opposite edges of
    a two-way road recompute them in the reference frame.
    """

    lane: np.ndarray  # lane index in the network (a wrong-way car: the lane of its own edge nearest the other's)
    edge: np.ndarray  # edge index (a wrong-way car: its own edge)
    lane_pos: np.ndarray  # front bumper along ``lane``, SUMO's lane position [m]
    wrong_way: np.ndarray  # driving on the opposite edge of a two-way road (overtaking through the oncoming lane)
    cx: np.ndarray  # centre x [m]
    cy: np.ndarray  # centre y [m]
    # Its centre along its own lane as a SUMO lane position (lengths with elevation): SUMO's car covers [pos − length,
    # pos] of its lane, so its centre is half its length behind the front bumper along the lane (a car moving across
    # the lane, by the cosine of its direction of motion); the 2-D shape's projection put a car on a 50 % slope 0.24 m
    # too far back (its body, along the slope, is shorter in plan).
    pos: np.ndarray
    d: np.ndarray  # centre's offset from its lane's centre line, + = left [m]
    v_lon: np.ndarray  # speed along the lane [m/s]
    v_lat: np.ndarray  # speed across the lane, + = left [m/s]
    half_lon: np.ndarray  # half extent of the bounding box along the lane [m]
    half_lat: np.ndarray  # half extent across the lane [m]
    reach: np.ndarray  # worst case before standing still: a_acc during ρ, then b_corr (the candidate bound) [m]
    reach_min: np.ndarray  # the same with b_min (a rear car's share of d_min) [m]
    stop_max: np.ndarray  # stopping distance at b_max (a front car's share) [m]
    lat_reach_as_left: np.ndarray  # lateral reach towards a car on its right [m]
    lat_reach_as_right: np.ndarray  # lateral reach towards a car on its left [m]
    route_edges: np.ndarray  # [n, k] remaining route as edge indices, -1 padded; all -1 when unknown
    params: RssParamArrays


@dataclass(frozen=True, eq=False)
class PairSituations:
    """Every relevant pair at one step, as arrays over pairs. ``a`` and ``b`` are snapshot rows with
    ``ids[a] < ids[b]``. Lateral quantities are + = left of the reference lane."""

    a: np.ndarray
    b: np.ndarray
    kind: np.ndarray  # index into SITUATION_CODES
    a_is_rear: np.ndarray  # same direction: a is the rear car; opposite: a is the reference car
    a_is_left: np.ndarray
    lon_gap: np.ndarray  # [m], negative = overlap
    lat_gap: np.ndarray  # [m], negative = overlap
    v_lon_a: np.ndarray  # [m/s] along the road (same dir.) or towards the other car (opposite)
    v_lon_b: np.ndarray
    v_lat_a: np.ndarray  # [m/s], + = left
    v_lat_b: np.ndarray
    lon_d_min: np.ndarray  # [m]
    lat_d_min: np.ndarray  # [m]
    lon_safe: np.ndarray
    lat_safe: np.ndarray
    # Intersections: RULE_* bits that hold, priority (0 same, 1 a, 2 b), the car in front on the virtual line (0
    # neither: they overlap there or are apart; 1 a, 2 b) and the conflict area; lon_gap / lon_d_min then hold
    # the yielding car's distance to the area and what it needs to stop before it.
    rules: np.ndarray | None = None
    priority: np.ndarray | None = None
    in_front: np.ndarray | None = None
    area: np.ndarray | None = None
    # Roads: whether a / b drives in the oncoming lane of a two-way road (VehicleFrame.wrong_way).
    wrong_way_a: np.ndarray | None = None
    wrong_way_b: np.ndarray | None = None
    # Intersections: each car's d_enter [m] (front bumper to the conflict area, negative inside); NaN on roads.
    enter_a: np.ndarray | None = None
    enter_b: np.ndarray | None = None
    # Roads: how far apart the two cars' centres are across the reference lane [m] (NaN at junctions).
    lat_offset: np.ndarray | None = None

    @property
    def safe_rules(self) -> np.ndarray:
        """RULE_* bits of the safety conditions that hold."""
        if self.rules is not None:
            return self.rules
        return self.lon_safe.astype(np.int8) * RULE_LON + self.lat_safe.astype(np.int8) * RULE_LAT

    @property
    def dangerous(self) -> np.ndarray:
        return self.safe_rules == 0

    def __len__(self) -> int:
        return int(self.a.shape[0])

    def take(self, index: np.ndarray) -> PairSituations:
        """The situations at ``index``."""
        return PairSituations(**{f.name: None if getattr(self, f.name) is None else getattr(self, f.name)[index]
                                 for f in fields(self)})

    @staticmethod
    def concat(parts: list[PairSituations]) -> PairSituations:
        """One set of situations from several (road and intersection); optional fields filled per part."""
        n = [len(p) for p in parts]

        def filled(k: int, default: object, dtype: object) -> np.ndarray:
            # np.full(k, default, dtype), but an object array's elements all refer to ``default`` (np.full makes a
            # Python object per element: 6x slower for a city step's 3,000 road pairs)
            values = np.empty(k, dtype=dtype)
            values.fill(default)
            return values

        def column(name: str, default: object, dtype: object) -> np.ndarray:
            return np.concatenate([getattr(p, name) if getattr(p, name) is not None else
                                   filled(k, default, dtype) for p, k in zip(parts, n)])

        fields = {name: np.concatenate([getattr(p, name) for p in parts]) for name in (
            "a", "b", "kind", "a_is_rear", "a_is_left", "lon_gap", "lat_gap", "v_lon_a", "v_lon_b", "v_lat_a",
            "v_lat_b", "lon_d_min", "lat_d_min", "lon_safe", "lat_safe")}
        rules = np.concatenate([p.safe_rules for p in parts])
        return PairSituations(**fields, rules=rules, priority=column("priority", 0, np.int8),
                              in_front=column("in_front", 0, np.int8), area=column("area", "", object),
                              wrong_way_a=column("wrong_way_a", False, bool),
                              wrong_way_b=column("wrong_way_b", False, bool),
                              enter_a=column("enter_a", np.nan, float), enter_b=column("enter_b", np.nan, float),
                              lat_offset=column("lat_offset", np.nan, float))


@jitable
def extent_across(length: Any, width: Any, cos_rel: Any, sin_rel: Any) -> np.ndarray:
    """[m] how much of a lane's width a box (``length`` x ``width``) takes up at a heading whose cos/sin against
    the lane are ``cos_rel``/``sin_rel``: length·|sin| + width·|cos|. (Along the lane: swap length and width.)"""
    return length * np.abs(sin_rel) + width * np.abs(cos_rel)


def _half_extents(length: np.ndarray, width: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half extents [m] along and across a lane of a box rotated by ``theta`` [rad] against it."""
    c, s = np.cos(theta), np.sin(theta)
    return 0.5 * extent_across(width, length, c, s), 0.5 * extent_across(length, width, c, s)


def vehicle_frame(snapshot: WorldSnapshot, network: RoadNetwork, params: RssParamArrays,
                  route_edges: np.ndarray, candidate_params: RssParamArrays | None = None) -> VehicleFrame:
    """Per-vehicle geometry in the network and the per-car terms of the safe distances; the candidate bound
    ``reach`` with ``candidate_params`` where given (the parameters without ``hold_standing``)."""
    lane = network.lane_indices(snapshot.lane_id)
    cx, cy, _ = body_poses(snapshot, network, lane)
    # SUMO's lane position (front bumper, along the lane's own length) hints where the centre projects.
    hint = network.shapes.shape_s(lane, snapshot.lane_pos) - 0.5 * snapshot.length
    s, d, lane_heading = network.frenet(lane, cx, cy, hint)
    lane_pos = snapshot.lane_pos
    # SUMO puts a car that overtakes through the oncoming lane on the opposite edge's lane (heading against it);
    # it drives on its own edge, in the wrong lane: framed on its own edge's lane next to the other direction.
    # (SUMO's lateral speed is the car's own: + = left of its direction of travel.)
    wrong_way = against_lane(network, lane, s, lane_heading, snapshot.heading, snapshot.length)
    if wrong_way.any():
        k = np.flatnonzero(wrong_way)
        lane = lane.copy()
        lane[k] = _innermost_lane(network)[network.edge_opposite[network.lane_edge[lane[k]]]]
        s, d = s.copy(), d.copy()
        lane_heading = lane_heading.copy()
        s[k], d[k], lane_heading[k] = network.frenet(lane[k], cx[k], cy[k])
        lane_pos = lane_pos.copy()
        lane_pos[k] = network.shapes.lane_pos(lane[k], s[k]) + 0.5 * snapshot.length[k]
    # SUMO's speed is along the lane and its lateral speed across it: the lane frame's velocity as it is. (The
    # heading minus the lane direction would read phantom lateral speed on curves stored as polylines.)
    v_lon, v_lat = snapshot.speed, snapshot.lat_speed
    speed = np.hypot(v_lon, v_lat)
    # The footprint turns with the direction of motion; a car standing still lies along its lane (the direction of
    # noise-level lateral speeds, such as a placed ego's 1e-5 m/s, turned a stopped car across the road).
    # It turns no further than SUMO turned the body (its angle against the lane): a car changing lanes at a
    # standstill moves only sideways, and its footprint across the road doubled its width (DRT: a lateral gap of
    # −3.35 m for a car beside it whose body SUMO turned 18°).
    motion = np.where(speed < FOOTPRINT_MIN_SPEED, 0.0, np.arctan2(v_lat, np.maximum(v_lon, 0.0)))
    body = np.abs(wrap_angle(snapshot.heading - lane_heading))
    theta = np.sign(motion) * np.minimum(np.abs(motion), body)
    half_lon, half_lat = _half_extents(snapshot.length, snapshot.width, theta)
    forward = np.maximum(v_lon, 0.0)
    return VehicleFrame(
        lane=lane, edge=network.lane_edge[lane], lane_pos=lane_pos, wrong_way=wrong_way, cx=cx, cy=cy,
        pos=lane_pos - 0.5 * snapshot.length * np.cos(theta), d=d,
        v_lon=v_lon, v_lat=v_lat, half_lon=half_lon, half_lat=half_lat,
        reach=lon_reach(speed, params if candidate_params is None else candidate_params, params.lon_brake_min_correct),
        reach_min=lon_reach(forward, params, params.lon_brake_min),
        stop_max=stopping_distance(forward, params.lon_brake_max),
        lat_reach_as_left=lateral_reach(-v_lat, params), lat_reach_as_right=lateral_reach(v_lat, params),
        route_edges=route_edges, params=params)


def body_poses(snapshot: WorldSnapshot, network: RoadNetwork,
               lane: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every car's geometric centre (x, y) [m] and body heading [rad] (``lane``: the indices of its lanes), from
    SUMO's front bumper and angle (rear to front). A car standing still (slower than FOOTPRINT_MIN_SPEED) whose
    angle is more than LEFTOVER_ANGLE (and less than 90°) off its lane lies along its lane instead, its back its length behind the front
    bumper along the lane at the bumper's offset: sumo --lanechange.duration leaves a car that stops as a lane
    change ends at the change's angle (38° at its lane's centre: its box reached 1.5 m into the next lane)."""
    cx, cy = snapshot.centres()
    heading = snapshot.heading
    standing = np.flatnonzero(np.hypot(snapshot.speed, snapshot.lat_speed) < FOOTPRINT_MIN_SPEED)
    if standing.size:
        k = lane[standing]
        s, d, _ = network.frenet(k, snapshot.x[standing], snapshot.y[standing])
        back_x, back_y = network.shapes.point_at(k, s - snapshot.length[standing], d)
        front_x, front_y = snapshot.x[standing], snapshot.y[standing]
        along = np.arctan2(front_y - back_y, front_x - back_x)
        off = np.abs(wrap_angle(heading[standing] - along))
        turned = (off > LEFTOVER_ANGLE) & (off < 0.5 * np.pi)  # not a car against its lane (overtaking, U-turn)
        if turned.any():
            rows = standing[turned]
            cx, cy, heading = cx.copy(), cy.copy(), heading.copy()
            cx[rows], cy[rows] = 0.5 * (front_x + back_x)[turned], 0.5 * (front_y + back_y)[turned]
            heading[rows] = along[turned]
    return cx, cy, heading


def against_lane(network: RoadNetwork, lane: np.ndarray, s: np.ndarray, lane_heading: np.ndarray,
                 heading: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Whether cars drive against their lanes: on an edge of a two-way road (SUMO's lane of a car overtaking
    through the oncoming lane), heading within 20° of the lane's opposite direction (``lane_heading`` [rad] at the
    centre, ``s`` [m] along it), with the whole length along the lane. Not a long vehicle coming out of a U-turn
    onto the lane, in its correct lane: SUMO's heading points from its rear, still in the turn, to its front (up to
    ~156° against the lane for a 12 m bus)."""
    return (network.edge_opposite[network.lane_edge[lane]] >= 0) & (np.cos(heading - lane_heading) < WRONG_WAY_COS) & \
        (s >= 0.5 * length) & (s <= _shape_length(network, lane) - 0.5 * length)


def _innermost_lane(network: RoadNetwork) -> np.ndarray:
    """[edges] each edge's leftmost lane (next to the other direction of a two-way road), -1 for none."""
    order = np.lexsort((network.lane_index, network.lane_edge))
    last = order[np.r_[network.lane_edge[order][1:] != network.lane_edge[order][:-1], True]]
    innermost = np.full(len(network.edge_ids), -1, dtype=int)
    innermost[network.lane_edge[last]] = last
    return innermost


def candidate_radius(snapshot: WorldSnapshot, frame: VehicleFrame) -> float:
    """[m] the centre distance no unsafe pair exceeds at this step: twice the largest worst-case reach, the largest
    gap and twice the largest half size (length plus width)."""
    size = 0.5 * (snapshot.length + snapshot.width)
    return 2.0 * float(frame.reach.max()) + float(frame.params.min_lon_gap.max()) + 2.0 * float(size.max())


def candidate_pairs(snapshot: WorldSnapshot, frame: VehicleFrame) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), i < j, that could be unsafe: centre distance within both cars' worst-case reach plus
    λ and their sizes. Anything farther is longitudinally safe whatever the situation."""
    n = len(snapshot)
    if n < 2:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    from .road_kernel import candidate_keys  # numba: at the first step with two vehicles
    size = 0.5 * (snapshot.length + snapshot.width)
    key = candidate_keys(frame.cx, frame.cy, frame.reach, frame.params.min_lon_gap, size)
    # By i, then j (the order lexsort gives): one key per pair, sorted (int32 where it fits: twice as fast).
    key = np.sort(key.astype(np.int32) if n * n < 2 ** 31 else key).astype(np.int64)
    return key // n, key % n


def _on_route(frame: VehicleFrame, vehicle: np.ndarray, edge: np.ndarray, network: RoadNetwork) -> np.ndarray:
    """Whether ``edge`` (its exit edge, for junction-internal edges) lies on the vehicle's remaining route;
    True where the route is unknown (worst case: every successor is possible)."""
    routes = frame.route_edges[vehicle]
    unknown = np.all(routes < 0, axis=1)
    return unknown | np.any(routes == network.edge_exit[edge][:, None], axis=1)


def classify(frame: VehicleFrame, i: np.ndarray, j: np.ndarray,
             network: RoadNetwork) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For candidate pairs: (kind code or -1 if not relevant, reference row, other row).

    The reference car is the front car of a same-direction pair and car ``i`` of an opposite pair.
    """
    ei, ej = frame.edge[i], frame.edge[j]
    same_edge = ei == ej
    dist_ij, dist_ji = network.edge_distances(np.concatenate([ei, ej]), np.concatenate([ej, ei])).reshape(2, -1)
    j_ahead = ~same_edge & np.isfinite(dist_ij) & (dist_ij <= dist_ji)
    i_ahead = ~same_edge & np.isfinite(dist_ji) & (dist_ji < dist_ij)
    # Chained edges count along the rear car's remaining route (or any route where it is unknown), and into a
    # junction behind a car on an internal lane that the rear car's own lane leads to (it left that lane ahead
    # of it: both leave the lane the same way until the front car has left the junction), or whose rear is still
    # on the edge it came from, on the rear car's route (a car turning off from the next lane, its body still
    # across the end of that edge: Bologna's 0.93 m edge 77bc between two junctions, where the pair was dropped
    # one second before the two collided).
    for ahead, rear, front in ((j_ahead, i, j), (i_ahead, j, i)):
        k = np.flatnonzero(ahead)
        chained = _on_route(frame, rear[k], frame.edge[front[k]], network)
        into = np.flatnonzero(~chained & network.edge_internal[frame.edge[front[k]]])
        f = front[k[into]]
        chained[into] = _leads_to(network, frame.lane[rear[k[into]]], frame.lane[f]) | (
            (frame.pos[f] < frame.half_lon[f]) & _on_route(frame, rear[k[into]], _entry_edges(network)[frame.lane[f]],
                                                           network))
        ahead[k] = chained
    # On one edge, compare SUMO's lane positions (the lanes of a curved edge differ in shape length; cars side by
    # side on a curve have the same position).
    j_front_same_edge = same_edge & (frame.pos[j] >= frame.pos[i])
    # On the two edges of a two-way road the cars drive towards each other, also where a turnaround at its end
    # chains the edges (a route that turns there, or any route where it is unknown).
    opposite = (network.edge_opposite[ei] == ej) & (ej >= 0)
    same_dir = (same_edge | j_ahead | i_ahead) & ~opposite
    kind = np.where(same_dir, 0, np.where(opposite, 1, -1))
    j_is_ref = same_dir & (j_ahead | j_front_same_edge)
    return kind, np.where(j_is_ref, j, i), np.where(j_is_ref, i, j)


def _shape_length(network: RoadNetwork, lane: np.ndarray) -> np.ndarray:
    """[m] the length of lanes' 2-D shapes."""
    return network.shapes.cumulative[lane, -1]


@lru_cache(maxsize=8)
def _entry_edges(network: RoadNetwork) -> np.ndarray:
    """[lanes] for each internal (junction) lane, the normal edge its connection comes from; for a normal lane, its
    own edge."""
    entry = network.lane_edge.copy()
    internal = network.edge_internal[network.lane_edge]
    before = np.full(len(entry), -1)
    for k, successors in enumerate(network.lane_successors):
        for j in successors:
            if before[j] < 0:
                before[j] = k
    for k in np.flatnonzero(internal):
        lane, hops = k, 0
        while internal[lane] and before[lane] >= 0 and hops < len(entry):
            lane, hops = before[lane], hops + 1
        entry[k] = network.lane_edge[lane]
    return entry


def _leads_to(network: RoadNetwork, lanes: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Whether a car on each of ``lanes`` reaches the lane ``targets`` without changing lanes."""
    return np.isfinite(network.lane_distances(lanes, targets))


def _joined_offset(network: RoadNetwork, lanes: np.ndarray, ref_lanes: np.ndarray) -> np.ndarray:
    """[m] where a car on each of ``lanes`` ends up across the edge of ``ref_lanes`` if it keeps its lane: the
    offset of the lane it leads on to there (the nearest, where it leads to several: the first of them in lane
    order) from the reference lane; NaN where it leads to no lane of that edge (it must change lanes on the way).
    Compiled (:func:`~sumo_rss.road.reach_kernel.joined_offsets`) over the lanes' rows of the lane graph's searches
    (:meth:`RoadNetwork.downstream_lanes` per lane in numpy: ~4 % of a Bologna city audit)."""
    from ..road.reach_kernel import joined_offsets  # numba: compiled at the first call

    lanes, ref_lanes = np.asarray(lanes, dtype=np.int64), np.asarray(ref_lanes, dtype=np.int64)
    return joined_offsets(lanes, ref_lanes, *network.lane_reach.rows(lanes), network.lane_edge, network.lane_offset)


def _upstream_in_reference_frame(frame: VehicleFrame, ref: np.ndarray, other: np.ndarray,
                                 network: RoadNetwork) -> tuple[np.ndarray, np.ndarray]:
    """(lane position, d) [m] in the reference lane's frame of cars on an edge upstream of the reference car's.

    Lane-based, as ad_rss's road area: the position is the path length along the lanes (SUMO's lengths; negative
    before the reference lane's start) and d the car's offset in its own lane plus where that lane ends up across
    the reference lane. Projecting the car itself onto the reference lane's straight extension would turn every kink or
    curve between the edges into a phantom lateral offset and lateral speed (0.9 m and 0.24 m/s 110 m behind a
    0.5° kink at highway speed).
    """
    lane_o, lane_r = frame.lane[other], frame.lane[ref]
    behind = network.edge_distances(frame.edge[other], frame.edge[ref])  # start of the car's edge to the ref's
    # Along the lanes, in SUMO's lengths (no scaling by a lane's shape: on a slope it is shorter than the lane).
    pos = frame.pos[other] - behind
    # Across: the lane the car's lane leads on to (through a turn, too); where it leads to no lane of the
    # reference edge, where the end of its lane lies across the reference lane's extension.
    d_join = _joined_offset(network, lane_o, lane_r)
    unjoined = np.flatnonzero(np.isnan(d_join))
    if unjoined.size:
        lo = lane_o[unjoined]
        end = network.shapes.points[lo, network.shapes.count[lo] - 1]
        hint = network.shapes.shape_s(lane_r[unjoined], network.lane_length[lo] - behind[unjoined])
        d_join[unjoined] = network.frenet(lane_r[unjoined], end[:, 0], end[:, 1], hint)[1]
    return pos, frame.d[other] + d_join


def evaluate(snapshot: WorldSnapshot, frame: VehicleFrame, network: RoadNetwork) -> PairSituations:
    """All relevant pairs of ``snapshot`` with gaps, safe distances and verdicts (rss.md §2-§3); the per-pair
    arithmetic once the other car is in the reference lane's frame is :func:`.road_kernel.road_pairs` (compiled)."""
    i, j = candidate_pairs(snapshot, frame)
    if i.size:  # a pair farther apart along the lanes than any candidate is apart is safe: no need to look beyond
        network.require_reach(candidate_radius(snapshot, frame))
    kind, ref, other = classify(frame, i, j, network)
    relevant = kind >= 0
    kind, ref, other = kind[relevant], ref[relevant], other[relevant]

    # The other car in the reference lane's frame, lane-based wherever it is (as ad_rss's road area): its own
    # Frenet coordinates convert and its lane-relative speeds and per-car terms hold as they are. On one edge:
    # SUMO's lane positions compare directly, d shifts by the lane offsets; on an edge upstream in the same
    # direction: by the path length along the lanes and the lane its lane leads on to; on the other direction of
    # a two-way road: by the reversed path length and the measured distance between the two lanes, its speeds
    # reversed. (Projecting its velocity onto the reference lane's polyline gave it the lateral speed of every
    # kink between the two lanes' vertices: 27-76° at Monaco's bends read as up to 14.8 m/s sideways.)
    lane_r, lane_o = frame.lane[ref], frame.lane[other]
    pos_o = frame.pos[other]
    d_o = frame.d[other] + network.lane_offset[lane_o] - network.lane_offset[lane_r]
    v_lon_o, v_lat_o = frame.v_lon[other], frame.v_lat[other]
    cross = frame.edge[ref] != frame.edge[other]
    chained = np.flatnonzero(cross & (kind == 0))
    if chained.size:
        pos_o[chained], d_o[chained] = _upstream_in_reference_frame(frame, ref[chained], other[chained], network)
    oncoming = np.flatnonzero(kind == 1)
    if oncoming.size:
        oc, lo = other[oncoming], lane_o[oncoming]
        pos_o[oncoming], d_o[oncoming] = network.two_way.in_lane_frame(
            lane_r[oncoming], lo, network.lane_index[lo], frame.pos[oc], network.lane_length[lo], frame.d[oc])
        v_lon_o[oncoming], v_lat_o[oncoming] = -frame.v_lon[oc], -frame.v_lat[oc]

    same = kind == 0
    # Opposite pairs that have passed each other (bodies wholly past) are no situation any more.
    keep = same | (pos_o + frame.half_lon[other] + frame.half_lon[ref] > frame.pos[ref]) if oncoming.size else same
    if oncoming.size and not np.all(keep):
        kind, ref, other, same, pos_o, d_o, v_lon_o, v_lat_o = (
            x[keep] for x in (kind, ref, other, same, pos_o, d_o, v_lon_o, v_lat_o))
    # The opposite pairs' per-car terms of the other car, recomputed in the reference frame; a car in its correct
    # lane brakes at b_corr, one in the oncoming lane at b_min (speeds towards each other).
    opposite = np.flatnonzero(~same)
    lat_left_o, lat_right_o, lon_d_min = (np.empty(len(ref) if opposite.size else 0) for _ in range(3))
    if opposite.size:
        r, o = ref[opposite], other[opposite]
        p_r, p_o = frame.params.take(r), frame.params.take(o)
        lat_left_o[opposite] = lateral_reach(-v_lat_o[opposite], p_o)
        lat_right_o[opposite] = lateral_reach(v_lat_o[opposite], p_o)
        lon_d_min[opposite] = combine_opposite(
            lon_reach(np.maximum(frame.v_lon[r], 0.0), p_r,
                      np.where(frame.wrong_way[r], p_r.lon_brake_min, p_r.lon_brake_min_correct)),
            lon_reach(np.maximum(-v_lon_o[opposite], 0.0), p_o,
                      np.where(frame.wrong_way[o], p_o.lon_brake_min, p_o.lon_brake_min_correct)),
            p_r.min_lon_gap, p_o.min_lon_gap)
    from .road_kernel import FLAG_COLUMNS, FLOAT_COLUMNS, INT_COLUMNS, road_pairs  # numba: at the first road pair
    rank = np.empty(len(snapshot), dtype=np.int64)  # id order (a < b), compared as numbers
    rank[np.argsort(snapshot.ids, kind="stable")] = np.arange(len(snapshot))
    floats, ints, flags = road_pairs(
        ref, other, kind, pos_o, d_o, v_lon_o, v_lat_o, lat_left_o, lat_right_o, lon_d_min, rank, frame.lane,
        frame.pos, frame.d, frame.v_lon, frame.v_lat, frame.half_lon, frame.half_lat, frame.reach_min,
        frame.stop_max, frame.lat_reach_as_left, frame.lat_reach_as_right, frame.params.min_lon_gap,
        frame.params.lat_fluctuation_margin, frame.wrong_way, network.lane_ends, network.lane_left)
    return PairSituations(**dict(zip(FLOAT_COLUMNS, floats)), **dict(zip(INT_COLUMNS, ints)),
                          **dict(zip(FLAG_COLUMNS, flags)))
