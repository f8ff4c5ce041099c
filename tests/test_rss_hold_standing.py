"""``hold_standing`` (CARLA's convention, docs/rss.md): a car standing still is not assumed to accelerate during its
response time. Two cars queued 2.5 m apart on hw0 (4.5 m long), both standing, under ad_rss (ρ 1 s, a_acc 3.5,
b_min 4 m/s²): plain ad_rss gives the rear car 1.75 m during ρ plus 3.5²/8 = 1.53 m of braking, d_min 3.28 m, so
the queue is dangerous; held, d_min is 0 and the queue is safe. Once the rear car moves it has its a_acc again."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.road.network import RoadNetwork
from sumo_rss.road.routes import RouteTable
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.situations import evaluate, vehicle_frame
from sumo_rss.sim.snapshot import WorldSnapshot

LENGTH = 4.5  # [m]


def _queue(net: RoadNetwork, rear_speed: float) -> WorldSnapshot:
    """Front bumpers at 100 m and 93 m along hw0_1 (a 2.5 m gap), the front car standing."""
    k = int(net.lane_indices(["hw0_1"])[0])
    start, direction = net.shapes.points[k, 0], net.shapes.points[k, 1] - net.shapes.points[k, 0]
    u = direction / np.linalg.norm(direction)
    s = np.array([100.0, 100.0 - LENGTH - 2.5])
    xy = start + s[:, None] * u
    zero = np.zeros(2)
    return WorldSnapshot(time=0.0, ids=np.array(["front", "rear"]), x=xy[:, 0], y=xy[:, 1],
                         heading=np.full(2, np.arctan2(u[1], u[0])), speed=np.array([0.0, rear_speed]), accel=zero,
                         lat_speed=zero, length=np.full(2, LENGTH), width=np.full(2, 1.8),
                         lane_id=np.array(["hw0_1"] * 2), edge_id=np.array(["hw0"] * 2), lane_index=np.ones(2, int),
                         lane_pos=s, lat_pos=zero, vclass=np.array(["background"] * 2), vtype=np.array(["car"] * 2),
                         signals=np.zeros(2, int), route_index=np.zeros(2, int),
                         route_edges=(("hw0", "hw1", "hw2"),) * 2)


def _pairs(net: RoadNetwork, hold: bool, rear_speed: float):
    snapshot = _queue(net, rear_speed)
    params = ParamResolver("ad_rss", hold_standing=hold).arrays(snapshot)
    return evaluate(snapshot, vehicle_frame(snapshot, net, params, RouteTable(net).remaining(snapshot)), net)


@pytest.mark.parametrize("hold, rear_speed, d_min", [
    (False, 0.0, 1.75 + 3.5 ** 2 / 8.0),
    (True, 0.01, 0.01 + 1.75 + 3.51 ** 2 / 8.0),  # moving: accelerating during ρ again
])
def test_a_queue_is_dangerous_where_the_rear_car_may_accelerate(hold, rear_speed, d_min):
    pairs = _pairs(RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml"), hold, rear_speed)
    assert pairs.lon_gap[0] == pytest.approx(2.5, abs=1e-9)
    assert pairs.lon_d_min[0] == pytest.approx(d_min, abs=1e-9)
    assert not pairs.lon_safe[0] and not pairs.lat_safe[0]


def test_a_standing_queue_is_safe_when_standing_cars_are_held():
    """Both reaches are 0: the cars are too far apart to be a candidate pair at all (safe whatever the
    situation)."""
    pairs = _pairs(RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml"), True, 0.0)
    assert pairs.a.size == 0
