"""Situations: which vehicle pairs matter at one step, in which coordinate frame, and are they safe.

Stages (each a function over index arrays, no loop over pairs):
1. :func:`candidate_pairs` — a cKDTree query with a radius no relevant pair can exceed (twice the largest
   worst-case stopping distance at current speeds plus vehicle sizes), then a per-pair bound.
2. :func:`classify` — same direction (same edge, or one edge ahead of the other along the route, or along any
   path when the route is unknown) or opposite direction (the two directions of one road, approaching).
   Intersection and merge situations (conflicting routes through a junction) are the next stage to add here.
3. :func:`evaluate` — bumper-to-bumper longitudinal and lateral gaps in the frame of a reference lane (the front
   car's lane; car ``a``'s lane for opposite pairs), speeds in that frame, the safe distances and the verdicts.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy.spatial import cKDTree

from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .formulas import (is_safe_distance, lat_safe_distance, lon_safe_distance_opposite, lon_safe_distance_same_dir,
                       worst_case_stopping_distance)
from .params import PARAM_NAMES, RssParamArrays


class SituationType(str, Enum):
    """Kinds of situation; the values go into the CSVs."""

    SAME_DIRECTION = "same-direction"
    OPPOSITE_DIRECTION = "opposite-direction"


SITUATION_CODES = (SituationType.SAME_DIRECTION, SituationType.OPPOSITE_DIRECTION)  # index = code in arrays


@dataclass(frozen=True, eq=False)
class VehicleFrame:
    """Per-vehicle quantities every stage needs (one row per snapshot row)."""

    lane: np.ndarray  # lane index in the network
    edge: np.ndarray  # edge index
    cx: np.ndarray  # centre x [m]
    cy: np.ndarray  # centre y [m]
    s: np.ndarray  # centre's s along its own lane [m]
    d: np.ndarray  # centre's offset from its lane's centre line, + = left [m]
    rel_heading: np.ndarray  # heading relative to its lane [rad]
    speed: np.ndarray  # total speed [m/s] along ``heading``
    reach: np.ndarray  # worst-case distance covered before standing still (a_acc during ρ, then b_corr) [m]
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

    @property
    def dangerous(self) -> np.ndarray:
        return ~self.lon_safe & ~self.lat_safe

    def __len__(self) -> int:
        return int(self.a.shape[0])


def _wrap(angle: np.ndarray) -> np.ndarray:
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def vehicle_frame(snapshot: WorldSnapshot, network: RoadNetwork, params: RssParamArrays,
                  route_edges: np.ndarray) -> VehicleFrame:
    """Per-vehicle geometry in the network: lanes, centres, Frenet coordinates, worst-case reach."""
    lane = network.lane_indices(snapshot.lane_id)
    cx = snapshot.x - 0.5 * snapshot.length * np.cos(snapshot.heading)
    cy = snapshot.y - 0.5 * snapshot.length * np.sin(snapshot.heading)
    s, d, lane_heading = network.frenet(lane, cx, cy)
    speed = np.hypot(snapshot.speed, snapshot.lat_speed)
    reach = worst_case_stopping_distance(speed, params.lon_accel_max, params.response_time,
                                         params.max_speed_on_accel, params.lon_brake_min_correct)
    return VehicleFrame(lane, network.lane_edge[lane], cx, cy, s, d, _wrap(snapshot.heading - lane_heading), speed,
                        reach, route_edges, params)


def candidate_pairs(snapshot: WorldSnapshot, frame: VehicleFrame) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), i < j, that could be unsafe: centre distance within both cars' worst-case reach plus
    λ and their sizes. Anything farther is longitudinally safe whatever the situation."""
    n = len(snapshot)
    if n < 2:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    size = 0.5 * (snapshot.length + snapshot.width)
    gap = frame.params.min_lon_gap
    radius = 2.0 * float(frame.reach.max()) + float(gap.max()) + 2.0 * float(size.max())
    tree = cKDTree(np.column_stack([frame.cx, frame.cy]))
    pairs = tree.query_pairs(radius, output_type="ndarray")
    if pairs.size == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    i, j = pairs[:, 0], pairs[:, 1]
    dist = np.hypot(frame.cx[i] - frame.cx[j], frame.cy[i] - frame.cy[j])
    keep = dist <= frame.reach[i] + frame.reach[j] + np.maximum(gap[i], gap[j]) + size[i] + size[j]
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order]


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
    dist_ij = network.edge_distance[ei, ej]
    dist_ji = network.edge_distance[ej, ei]
    j_ahead = ~same_edge & np.isfinite(dist_ij) & (dist_ij <= dist_ji) & _on_route(frame, i, ej, network)
    i_ahead = ~same_edge & np.isfinite(dist_ji) & (dist_ji < dist_ij) & _on_route(frame, j, ei, network)
    # On one edge, compare positions scaled to a common length (lanes of a curved edge differ in length).
    scale = network.edge_length[ei] / network.lane_length[frame.lane[i]]
    scale_j = network.edge_length[ej] / network.lane_length[frame.lane[j]]
    j_front_same_edge = same_edge & (frame.s[j] * scale_j >= frame.s[i] * scale)
    same_dir = same_edge | j_ahead | i_ahead
    opposite = ~same_dir & (network.edge_opposite[ei] == ej) & (ej >= 0)
    kind = np.where(same_dir, 0, np.where(opposite, 1, -1))
    j_is_ref = (same_dir & (j_ahead | j_front_same_edge))
    ref = np.where(j_is_ref, j, i)
    other = np.where(j_is_ref, i, j)
    return kind, ref, other


def other_in_reference_frame(frame: VehicleFrame, ref: np.ndarray, other: np.ndarray, heading: np.ndarray,
                             network: RoadNetwork) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s, d, heading relative to the lane) of the other car's centre in the reference car's lane frame.

    On one edge the lanes are parallel offset curves, so the other car's own Frenet coordinates convert exactly
    (s scaled by the lane lengths, d shifted by the lane offsets); across edges its centre is projected.
    """
    lane_r, lane_o = frame.lane[ref], frame.lane[other]
    s_o = frame.s[other] * network.lane_length[lane_r] / network.lane_length[lane_o]
    d_o = frame.d[other] + network.lane_offset[lane_o] - network.lane_offset[lane_r]
    theta_o = frame.rel_heading[other].copy()
    cross = np.flatnonzero(frame.edge[ref] != frame.edge[other])
    if cross.size:
        s_x, d_x, foot_heading = network.frenet(lane_r[cross], frame.cx[other[cross]], frame.cy[other[cross]])
        s_o[cross], d_o[cross] = s_x, d_x
        theta_o[cross] = _wrap(heading[other[cross]] - foot_heading)
    return s_o, d_o, theta_o


def evaluate(snapshot: WorldSnapshot, frame: VehicleFrame, network: RoadNetwork) -> PairSituations:
    """All relevant pairs of ``snapshot`` with gaps, safe distances and verdicts (rss.md §2-§3)."""
    i, j = candidate_pairs(snapshot, frame)
    kind, ref, other = classify(frame, i, j, network)
    relevant = kind >= 0
    kind, ref, other = kind[relevant], ref[relevant], other[relevant]

    s_o, d_o, theta_o = other_in_reference_frame(frame, ref, other, snapshot.heading, network)
    theta_r = frame.rel_heading[ref]
    s_r, d_r = frame.s[ref], frame.d[ref]

    def half_extents(row: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        half_l, half_w = 0.5 * snapshot.length[row], 0.5 * snapshot.width[row]
        c, s = np.abs(np.cos(theta)), np.abs(np.sin(theta))
        return half_l * c + half_w * s, half_l * s + half_w * c

    lon_o, lat_o = half_extents(other, theta_o)
    lon_r, lat_r = half_extents(ref, theta_r)
    lon_gap = np.abs(s_o - s_r) - lon_o - lon_r
    lat_gap = np.abs(d_o - d_r) - lat_o - lat_r
    v_lon_o, v_lat_o = frame.speed[other] * np.cos(theta_o), frame.speed[other] * np.sin(theta_o)
    v_lon_r, v_lat_r = frame.speed[ref] * np.cos(theta_r), frame.speed[ref] * np.sin(theta_r)

    same = kind == 0
    # Opposite pairs that have passed each other are no situation any more.
    keep = same | (s_o > s_r)
    kind, ref, other, same, lon_gap, lat_gap, d_o, d_r, v_lon_o, v_lat_o, v_lon_r, v_lat_r = (
        x[keep] for x in (kind, ref, other, same, lon_gap, lat_gap, d_o, d_r, v_lon_o, v_lat_o, v_lon_r, v_lat_r))

    params = frame.params
    p_ref, p_other = params.take(ref), params.take(other)
    # Same direction: the reference is the front car. Opposite: speeds towards each other.
    v_ref_lon = np.maximum(v_lon_r, 0.0)
    v_other_lon = np.where(same, np.maximum(v_lon_o, 0.0), np.maximum(-v_lon_o, 0.0))
    lon_same = lon_safe_distance_same_dir(v_other_lon, v_ref_lon, p_other, p_ref)
    lon_opp = lon_safe_distance_opposite(v_ref_lon, v_other_lon, p_ref, p_other, both_correct=True)
    lon_d_min = np.where(same, lon_same, lon_opp)

    other_left = d_o > d_r
    v_lat_left = np.where(other_left, v_lat_o, v_lat_r)
    v_lat_right = np.where(other_left, v_lat_r, v_lat_o)
    p_left = _select(other_left, p_other, p_ref)
    p_right = _select(other_left, p_ref, p_other)
    lat_d_min = lat_safe_distance(v_lat_left, v_lat_right, p_left, p_right)

    # Name the pair by id order: a < b.
    a_is_ref = snapshot.ids[ref] < snapshot.ids[other]
    a = np.where(a_is_ref, ref, other)
    b = np.where(a_is_ref, other, ref)
    a_is_rear = np.where(same, ~a_is_ref, a_is_ref)  # opposite pairs: "a is the reference car"
    a_is_left = np.where(a_is_ref, ~other_left, other_left)
    return PairSituations(
        a=a, b=b, kind=kind, a_is_rear=a_is_rear, a_is_left=a_is_left, lon_gap=lon_gap, lat_gap=lat_gap,
        v_lon_a=np.where(a_is_ref, v_ref_lon, v_other_lon), v_lon_b=np.where(a_is_ref, v_other_lon, v_ref_lon),
        v_lat_a=np.where(a_is_ref, v_lat_r, v_lat_o), v_lat_b=np.where(a_is_ref, v_lat_o, v_lat_r),
        lon_d_min=lon_d_min, lat_d_min=lat_d_min,
        lon_safe=is_safe_distance(lon_gap, lon_d_min), lat_safe=is_safe_distance(lat_gap, lat_d_min))


def _select(mask: np.ndarray, if_true: RssParamArrays, if_false: RssParamArrays) -> RssParamArrays:
    return RssParamArrays(*(np.where(mask, getattr(if_true, n), getattr(if_false, n)) for n in PARAM_NAMES))
