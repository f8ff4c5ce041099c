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
from sumo_rss.rss.auditor import Auditor, ParamResolver
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
    """The pairs as the auditor evaluates them: candidates found as if no car stood."""
    snapshot = _queue(net, rear_speed)
    resolver = ParamResolver("ad_rss", hold_standing=hold)
    frame = vehicle_frame(snapshot, net, resolver.arrays(snapshot), RouteTable(net).remaining(snapshot),
                          resolver.arrays(snapshot, held=False))
    return evaluate(snapshot, frame, net)


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
    """Held, the rear car's d_min is 0 (λ = 0): the queue is safe. It is still a candidate pair (candidates are
    found as if no car stood), so what held at the step before one of the cars moves off is known."""
    pairs = _pairs(RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml"), True, 0.0)
    assert pairs.a.size == 1 and pairs.lon_d_min[0] == 0.0 and pairs.lon_safe[0]


def test_a_standing_pair_that_becomes_dangerous_owes_what_was_safe_before():
    """x stands in lane 1 (front bumper at 500 m), y in lane 0 (492 m), 5 m cars 1.8 m wide: 3 m apart along the
    road (held d_min 0) and 1.7 m across (d_min 2·(0.2²/1.6 + 0.1) + 0.1 = 0.35 m): both safe. y moves off at
    0.35 m/s with 1.2 m/s sideways towards x: along, d_min = 0.35 + 1.75 + 3.85²/8 = 3.95 m > 3.90 m; across,
    2.75 m > −0.17 m: dangerous. Both were safe before t_b, so both cars owe both responses (rss.md §5). With
    the candidates found at reach 0 the pair was not evaluated the step before (centres 8.7 m apart) and was taken
    as having been laterally unsafe: the longitudinal response alone."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    lane_y = {0: -8.75, 1: -5.25}

    def snapshot(t: float, y_front: float, y_lat: float, v: float, v_lat: float, accel: float) -> WorldSnapshot:
        s, lane = np.array([500.0, y_front]), np.array([1, 0])
        lat = np.array([0.0, y_lat])
        return WorldSnapshot(
            time=t, ids=np.array(["x", "y"]), x=s, y=np.array([lane_y[1], lane_y[0]]) + lat, heading=np.zeros(2),
            speed=np.array([0.0, v]), accel=np.array([0.0, accel]), lat_speed=np.array([0.0, v_lat]),
            length=np.full(2, 5.0), width=np.full(2, 1.8), lane_id=np.array(["hw0_1", "hw0_0"]),
            edge_id=np.array(["hw0"] * 2), lane_index=lane, lane_pos=s, lat_pos=lat,
            vclass=np.array(["background"] * 2), vtype=np.array(["car"] * 2), signals=np.zeros(2, int),
            route_index=np.zeros(2, int), route_edges=(("hw0", "hw1", "hw2"),) * 2)

    auditor = Auditor(net, ParamResolver("ad_rss", hold_standing=True), signal_rule=False)
    for step in (snapshot(0.0, 492.0, 0.0, 0.0, 0.0, 0.0), snapshot(0.1, 492.035, 0.12, 0.35, 1.2, 3.5),
                 snapshot(0.2, 492.07, 0.24, 0.35, 1.2, 0.0)):
        auditor.observe(step)
    (episode,) = auditor.finish().episodes.itertuples()
    assert (episode.t_b_s, episode.trigger, episode.owed_a, episode.owed_b) == \
        (0.1, "both", "lon:brake-at-most-max+lat:brake", "lon:brake-min+lat:brake")
