"""A person on a vehicle lane (rss.md §10 (ii); the paper's §3.8): its possible paths form a wedge, and a vehicle
must stay out of it as at an intersection where the person has no priority.

The wedge: from the person's position, every direction within WEDGE_HALF_ANGLE of its heading, up to WEDGE_LENGTH_M.
In the lane frame of a vehicle on the person's edge, the part of the vehicle's lane strip (its lane's width plus
the person's) that the wedge covers is an s-interval: the conflict area. The vehicle's d_enter / d_exit run along
its lane to that interval; the person's are its nearest way into the strip and its farthest way out of it along
the wedge (negative inside). The intersection test of rss.md §4 then applies with the vehicle's priority: the person
must be able to stop before the strip; once on it, the vehicle must be able to stop before the wedge or not meet it
in time. Vehicles on other edges (an upstream edge, the other direction of a two-way road) are not paired with it,
and a shared space (where the person would have priority) is not told apart.
"""
from __future__ import annotations

import numpy as np

from ..angles import wrap_angle
from ..road.link_pairs import expand_ranges
from ..road.network import RoadNetwork
from ..sim.persons import PersonSnapshot
from .params import RssParamArrays
from .person_pairs import Side, vehicle_person_situations
from .situations import PairSituations, VehicleFrame

WEDGE_HALF_ANGLE = np.radians(45.0)  # [rad] how far a person may turn from its heading (an assumption: docs/rss.md)
WEDGE_RAYS = 9  # directions sampled across the wedge
WEDGE_LENGTH_M = 10.0  # [m] how far along each direction (7 s at 1.4 m/s)
AREA_ID = "jaywalk"  # the conflict area of every such pair ('<edge>:jaywalk' in the outputs)


def jaywalking_situations(persons: PersonSnapshot, on_road: np.ndarray, frame: VehicleFrame, ids: np.ndarray,
                          length: np.ndarray, network: RoadNetwork, params: RssParamArrays, vehicles: int
                          ) -> PairSituations | None:
    """Every (vehicle, person on its edge's road) pair whose wedge meets the vehicle's lane strip ahead of the
    vehicle's rear (rows: vehicles, then persons from ``vehicles`` on; ``params`` over both). ``on_road``: the
    persons walking on a vehicle lane; ``ids``, ``length`` [m]: the vehicles'."""
    walkers = np.flatnonzero(on_road)
    p_edge = network.find_edges(persons.edge_id[walkers])
    by_edge = np.argsort(frame.edge, kind="stable")
    pair, hit = expand_ranges(np.searchsorted(frame.edge[by_edge], p_edge, side="left"),
                              np.searchsorted(frame.edge[by_edge], p_edge, side="right"))
    if not pair.size:
        return None
    p, r = walkers[pair], by_edge[hit]
    lane = frame.lane[r]
    s_p, d_p, lane_heading = network.frenet(lane, persons.x[p], persons.y[p])
    half = 0.5 * network.lane_width[lane] + 0.5 * persons.width[p]  # [m] the strip, each side of the centre line
    # The wedge's rays in the lane frame: where each enters and leaves the strip |d| <= half, within its length.
    phi = wrap_angle(persons.heading[p] - lane_heading)[:, None] + np.linspace(-1.0, 1.0, WEDGE_RAYS) * \
        WEDGE_HALF_ANGLE
    sin, cos = np.sin(phi), np.cos(phi)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_a, t_b = (-half[:, None] - d_p[:, None]) / sin, (half[:, None] - d_p[:, None]) / sin
    across = np.abs(sin) > 1e-9
    inside = np.abs(d_p) <= half
    t_in = np.where(across, np.minimum(t_a, t_b), np.where(inside[:, None], -np.inf, np.inf))
    t_out = np.where(across, np.maximum(t_a, t_b), np.where(inside[:, None], np.inf, -np.inf))
    t_in, t_out = np.maximum(t_in, 0.0), np.minimum(t_out, WEDGE_LENGTH_M)
    meets = t_out > t_in
    s_in, s_out = s_p[:, None] + cos * t_in, s_p[:, None] + cos * t_out
    lo = np.where(meets, np.minimum(s_in, s_out), np.inf).min(axis=1)
    hi = np.where(meets, np.maximum(s_in, s_out), -np.inf).max(axis=1)
    front = network.shapes.shape_s(lane, frame.lane_pos[r])  # the vehicle's front bumper along its lane's shape
    enter_v, exit_v = lo - front, hi - front + length[r]
    # The person into and out of the strip along the wedge (its nearest way in, its farthest way out).
    enter_p = np.where(inside, -1e-3, np.where(meets, t_in, np.inf).min(axis=1))  # inside: in the area
    exit_p = np.where(meets, t_out, 0.0).max(axis=1) + persons.length[p]
    keep = np.isfinite(lo) & (exit_v > 0.0)
    if not keep.any():
        return None
    r, p, enter_v, exit_v, enter_p, exit_p = (x[keep] for x in (r, p, enter_v, exit_v, enter_p, exit_p))
    area = np.char.add(network.edge_ids[frame.edge[r]].astype(str), ":" + AREA_ID).astype(object)
    return vehicle_person_situations(
        Side(r, ids[r], np.maximum(frame.v_lon[r], 0.0), enter_v, exit_v, length[r]),
        Side(vehicles + p, persons.ids[p], persons.speed[p], enter_p, exit_p, persons.length[p]),
        np.ones(len(r), dtype=int), np.zeros(len(r), dtype=bool), params, area)
