"""Hand-placed cars on a network's lanes, as SUMO places them, and the auditor's road situations of such a snapshot."""
from __future__ import annotations

import numpy as np

from sumo_rss.road.network import RoadNetwork
from sumo_rss.road.routes import RouteTable
from sumo_rss.rss.params import RssParamArrays, preset_params
from sumo_rss.rss.situations import PairSituations, evaluate, vehicle_frame
from sumo_rss.sim.snapshot import WorldSnapshot

LENGTH, WIDTH = 4.5, 1.8  # [m] SUMO's passenger car


def lane_pose(net: RoadNetwork, lane_id: str, pos: float, length: float = LENGTH) -> tuple[float, float, float]:
    """(x, y, heading) of a car whose front bumper is at SUMO lane position ``pos`` [m] on ``lane_id``, its rear
    ``length`` behind along the lane: SUMO's angle points from the rear to the front (a chord through a kink)."""
    k = np.array([int(net.lane_indices([lane_id])[0])] * 2)
    s = net.shapes.shape_s(k, np.array([pos, pos - length]))
    x, y = net.shapes.point_at(k, s, np.zeros(2))
    return float(x[0]), float(y[0]), float(np.arctan2(y[0] - y[1], x[0] - x[1]))


def road_situations(net: RoadNetwork, cars: list[tuple], lateral: dict[str, tuple[float, float]] | None = None
                    ) -> PairSituations:
    """The road situations of cars (id, lane id, SUMO lane position of the front bumper [m], speed [m/s][, route as
    edge ids]) driving along their lanes (routes unknown where not given), ad_rss parameters; ``lateral``: per car id,
    (offset [m], lateral speed [m/s][, body turn [rad]]) to the left of its lane's centre line, its heading turned by
    its direction of motion (or by the body turn where given, as SUMO turns a car changing lanes)."""
    n = len(cars)
    lateral = lateral or {}
    offset, lat_speed = (np.array([lateral.get(c[0], (0.0, 0.0))[k] for c in cars]) for k in (0, 1))
    poses = []
    for (vid, lane, pos, speed, *_), d, u in zip(cars, offset, lat_speed):
        x, y, h = lane_pose(net, lane, pos)
        turn = lateral[vid][2] if len(lateral.get(vid, ())) > 2 else np.arctan2(u, speed)
        poses.append((x - np.sin(h) * d, y + np.cos(h) * d, h + turn))
    lanes = np.array([c[1] for c in cars])
    lane_rows = net.lane_indices(lanes)
    edges = net.edge_ids[net.lane_edge[lane_rows]]
    routes = tuple(tuple(c[4]) if len(c) > 4 else () for c in cars)
    snapshot = WorldSnapshot(
        time=0.0, ids=np.array([c[0] for c in cars]), x=np.array([p[0] for p in poses]),
        y=np.array([p[1] for p in poses]), heading=np.array([p[2] for p in poses]),
        speed=np.array([c[3] for c in cars], dtype=float), accel=np.zeros(n), lat_speed=lat_speed,
        length=np.full(n, LENGTH), width=np.full(n, WIDTH), lane_id=lanes, edge_id=edges,
        lane_index=net.lane_index[lane_rows], lane_pos=np.array([c[2] for c in cars], dtype=float), lat_pos=offset,
        vclass=np.full(n, "background"), vtype=np.full(n, "car"), signals=np.zeros(n, int),
        route_index=np.array([r.index(e) if e in r else -1 for r, e in zip(routes, edges)]),
        route_edges=routes if any(routes) else None)
    params = RssParamArrays.stack([preset_params("ad_rss", "background")] * n)
    return evaluate(snapshot, vehicle_frame(snapshot, net, params, RouteTable(net).remaining(snapshot)), net)
