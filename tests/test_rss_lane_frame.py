"""Pairs across chained edges are judged in a lane-based frame: a car driving straight along its own lane has no
lateral speed and no lateral offset towards a car ahead on the next edge, however the road bends between them
(highway: hw0 is straight, hw1 a 875 m curve, hw2 straight again; lanes 3.5 m wide, cars 4.5 m x 1.8 m)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sumo_rss.road.network import RoadNetwork
from sumo_rss.road.routes import RouteTable
from sumo_rss.rss.params import RssParamArrays, preset_params
from sumo_rss.rss.situations import evaluate, vehicle_frame
from sumo_rss.sim.snapshot import WorldSnapshot

NETWORKS = Path(__file__).resolve().parents[1] / "networks"
LENGTH, WIDTH = 4.5, 1.8  # [m]


def _front_bumper(net: RoadNetwork, lane_id: str, s: float) -> tuple[float, float, float]:
    """(x, y, heading) of the point ``s`` [m] along a lane's centre line."""
    k = int(net.lane_indices([lane_id])[0])
    count = int(net.shapes.count[k])
    points, cum = net.shapes.points[k, :count], net.shapes.cumulative[k, :count]
    seg = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, count - 2))
    direction = points[seg + 1] - points[seg]
    x, y = points[seg] + direction * (s - cum[seg]) / np.linalg.norm(direction)
    return float(x), float(y), float(np.arctan2(direction[1], direction[0]))


def _pair(net: RoadNetwork, cars: list[tuple[str, str, float, float]]):
    """Evaluate two cars (id, lane, front-bumper s [m], speed [m/s]) driving straight along their lanes."""
    poses = [_front_bumper(net, lane, s) for _, lane, s, _ in cars]
    n = len(cars)
    zero = np.zeros(n)
    lanes = np.array([c[1] for c in cars])
    snapshot = WorldSnapshot(
        time=0.0, ids=np.array([c[0] for c in cars]), x=np.array([p[0] for p in poses]),
        y=np.array([p[1] for p in poses]), heading=np.array([p[2] for p in poses]),
        speed=np.array([c[3] for c in cars]), accel=zero, lat_speed=zero, length=np.full(n, LENGTH),
        width=np.full(n, WIDTH), lane_id=lanes, edge_id=np.array([lane.rsplit("_", 1)[0] for lane in lanes]),
        lane_index=np.array([int(lane.rsplit("_", 1)[1]) for lane in lanes]), lane_pos=np.array([c[2] for c in cars]),
        lat_pos=zero, vclass=np.array(["background"] * n), vtype=np.array(["car"] * n), signals=np.zeros(n, int),
        route_index=np.array([["hw0", "hw1", "hw2"].index(lane.rsplit("_", 1)[0]) for lane in lanes]),
        route_edges=(("hw0", "hw1", "hw2"),) * n)
    params = RssParamArrays.stack([preset_params("ad_rss", "background")] * n)
    frame = vehicle_frame(snapshot, net, params, RouteTable(net).remaining(snapshot))
    return evaluate(snapshot, frame, net)


@pytest.mark.parametrize("rear_lane, front_lane, lateral_gap", [
    ("hw1_1", "hw2_1", -WIDTH),  # one lane: the bodies overlap laterally by a car's width
    ("hw1_0", "hw2_1", 3.5 - WIDTH),  # neighbouring lanes: one lane width between the centres
])
def test_a_car_deep_in_the_curve_is_placed_along_the_lanes_not_on_the_straight_extension(
        rear_lane, front_lane, lateral_gap):
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    # 120 m before the end of the curve, the rear car heads ~6° away from hw2's direction.
    length_hw1 = float(net.lane_length[net.lane_indices([rear_lane])[0]])
    pairs = _pair(net, [("rear", rear_lane, length_hw1 - 120.0, 30.0), ("front", front_lane, 30.0, 30.0)])
    assert len(pairs) == 1 and pairs.kind[0] == 0  # same direction
    assert pairs.v_lat_a[0] == 0.0 and pairs.v_lat_b[0] == 0.0
    assert pairs.lat_gap[0] == pytest.approx(lateral_gap, abs=0.05)
    # Along the lanes: 120 m to the end of hw1, the junction's internal lane, 30 m into hw2, minus a car length.
    hw1_to_hw2 = float(net.edge_distance[net.edge_indices(["hw1"])[0], net.edge_indices(["hw2"])[0]])
    internal = hw1_to_hw2 - float(net.edge_length[net.edge_indices(["hw1"])[0]])
    assert pairs.lon_gap[0] == pytest.approx(120.0 + internal + 30.0 - LENGTH, abs=0.5)
