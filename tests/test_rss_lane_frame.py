"""Pairs across chained edges are judged in a lane-based frame: a car driving straight along its own lane has no
lateral speed and no lateral offset towards a car ahead on the next edge, however the road bends between them
(highway: hw0 is straight, hw1 a 875 m curve, hw2 straight again; lanes 3.5 m wide, cars 4.5 m x 1.8 m), also
through a turn at a junction, and positions along a curved edge are SUMO's lane positions."""
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


def _front_bumper(net: RoadNetwork, lane_id: str, pos: float) -> tuple[float, float, float]:
    """(x, y, heading) of SUMO's lane position ``pos`` [m] on a lane: as SUMO places it, ``pos`` scaled from the
    lane's length (the edge's) to its shape's (the lanes of the curved hw1 differ: 876.07 / 874.61 / 873.14 m)."""
    k = int(net.lane_indices([lane_id])[0])
    count = int(net.shapes.count[k])
    points, cum = net.shapes.points[k, :count], net.shapes.cumulative[k, :count]
    s = pos * cum[-1] / net.lane_length[k]
    seg = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, count - 2))
    direction = points[seg + 1] - points[seg]
    x, y = points[seg] + direction * (s - cum[seg]) / np.linalg.norm(direction)
    return float(x), float(y), float(np.arctan2(direction[1], direction[0]))


def _pair(net: RoadNetwork, cars: list[tuple], routes: bool = True, lateral: tuple[tuple[float, float], ...] = ()):
    """Evaluate cars (id, lane, SUMO lane position of the front bumper [m], speed [m/s][, route]) driving straight
    along their lanes (route: hw0-hw1-hw2 unless given; ``routes=False``: routes unknown); ``lateral``: per car,
    (offset [m], speed [m/s]) to the left of its lane's centre line (default none)."""
    n = len(cars)
    zero = np.zeros(n)
    offset, lat_speed = (np.array(v, dtype=float) for v in zip(*lateral)) if lateral else (zero, zero)
    poses = [_front_bumper(net, c[1], c[2]) for c in cars]
    poses = [(x - np.sin(h) * d, y + np.cos(h) * d, h + np.arctan2(u, c[3]))
             for (x, y, h), d, u, c in zip(poses, offset, lat_speed, cars)]
    lanes = np.array([c[1] for c in cars])
    edges = [lane.rsplit("_", 1)[0] for lane in lanes]
    route = [c[4] if len(c) > 4 else ("hw0", "hw1", "hw2") for c in cars]
    snapshot = WorldSnapshot(
        time=0.0, ids=np.array([c[0] for c in cars]), x=np.array([p[0] for p in poses]),
        y=np.array([p[1] for p in poses]), heading=np.array([p[2] for p in poses]),
        speed=np.array([c[3] for c in cars]), accel=zero, lat_speed=lat_speed, length=np.full(n, LENGTH),
        width=np.full(n, WIDTH), lane_id=lanes, edge_id=np.array(edges),
        lane_index=np.array([int(lane.rsplit("_", 1)[1]) for lane in lanes]), lane_pos=np.array([c[2] for c in cars]),
        lat_pos=offset, vclass=np.array(["background"] * n), vtype=np.array(["car"] * n), signals=np.zeros(n, int),
        route_index=np.array([r.index(e) if e in r else -1 for r, e in zip(route, edges)]),
        route_edges=tuple(route) if routes else None)
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
    hw1_to_hw2 = float(net.edge_distances(net.edge_indices(["hw1"]), net.edge_indices(["hw2"]))[0])
    internal = hw1_to_hw2 - float(net.edge_length[net.edge_indices(["hw1"])[0]])
    assert pairs.lon_gap[0] == pytest.approx(120.0 + internal + 30.0 - LENGTH, abs=0.5)


def test_cars_side_by_side_on_the_curve_overlap_fully():
    """SUMO places lane position 800 of the three hw1 lanes side by side (shape distances 801.34 / 799.99 /
    798.65 m): each pair overlaps by a whole car length (it read -3.16 / -1.82 m from the shapes' lengths)."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    pairs = _pair(net, [("a", "hw1_0", 800.0, 30.0), ("b", "hw1_1", 800.0, 30.0), ("c", "hw1_2", 800.0, 30.0)])
    assert pairs.lon_gap.tolist() == pytest.approx([-LENGTH] * 3, abs=0.01)


INTERSECTION_TLS = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"


@pytest.mark.parametrize("rear_lane, front_lane, route", [
    ("N_in_1", "E_out_1", ("N_in", "E_out")),  # a left turn: the rear car's lane leads on to the front car's
    ("N_in_0", "W_out_0", ("N_in", "W_out")),  # a right turn
])
def test_a_car_following_another_through_a_turn_is_in_its_lane(rear_lane, front_lane, route):
    """The rear car 10 m before the line at 10 m/s, the front car 5 m past the junction at 2 m/s, both turning
    the same way: one lane all along, so the bodies overlap across it (the end of the rear car's lane projected
    onto the front lane's straight extension read it 10.2 m (left) / 3.8 m (right) beside it, laterally safe). The
    gap runs along the lanes through the junction; shorter than d_min = 10 + 1.75 + 13.5²/8 − 2²/16 = 34.28 m:
    dangerous."""
    net = RoadNetwork.from_file(INTERSECTION_TLS)
    rear = int(net.lane_indices([rear_lane])[0])
    pairs = _pair(net, [("a", front_lane, 5.0, 2.0, route), ("b", rear_lane, net.lane_length[rear] - 10.0, 10.0, route)])
    through = net.edge_distances(net.lane_edge[[rear]], net.edge_indices([front_lane.rsplit("_", 1)[0]]))[0] - \
        net.lane_length[rear]
    assert len(pairs) == 1 and pairs.kind[0] == 0
    assert pairs.lat_gap[0] == pytest.approx(-WIDTH, abs=0.01)
    assert pairs.lon_gap[0] == pytest.approx(10.0 + through + 5.0 - LENGTH, abs=0.1)
    assert pairs.lon_d_min[0] == pytest.approx(34.28, abs=0.01) and pairs.dangerous[0]


@pytest.mark.parametrize("routes", [True, False])
def test_a_car_behind_a_turning_car_in_the_junction_follows_it_whichever_way_it_goes(routes):
    """intersection_priority: a stands 5 m into its left turn (:J_8_0, from S_in_0); b, going straight, is 6 m
    before the line at 8 m/s on the same lane. Both leave S_in_0 the same way until a has left the junction: a
    same-direction pair in one lane, 6 + 5 - 4.5 = 6.5 m apart (< d_min), dangerous, whether the routes are known
    or not (with b's route known, it was in no situation at all, and b rear-ended a unjudged)."""
    net = RoadNetwork.from_file(NETWORKS / "intersection_priority" / "intersection_priority.net.xml")
    s_in = float(net.lane_length[net.lane_indices(["S_in_0"])[0]])
    pairs = _pair(net, [("a", ":J_8_0", 5.0, 0.0, ("S_in", "J_W")), ("b", "S_in_0", s_in - 6.0, 8.0, ("S_in", "J_N"))],
                  routes)
    assert len(pairs) == 1 and pairs.kind[0] == 0 and not pairs.a_is_rear[0]
    assert pairs.lon_gap[0] == pytest.approx(6.5, abs=0.15) and pairs.lat_gap[0] < 0.0 and pairs.dangerous[0]


def test_oncoming_cars_stay_a_pair_until_their_bodies_have_passed():
    """intersection_tls's north arm: a southbound on N_in_1, b northbound on N_out_1 0.9 m to the left of its
    lane's centre and drifting further left (towards a) at 1 m/s. Their centres have just passed each other (by
    0.9 m) but the bodies still overlap along the road by 3.6 m, 0.5 m apart across it (< the lateral d_min): a
    dangerous pair (it was dropped once the centres passed). Once the bodies are wholly past, it is no pair."""
    net = RoadNetwork.from_file(INTERSECTION_TLS)
    n_in = float(net.lane_length[net.lane_indices(["N_in_1"])[0]])
    a = ("a", "N_in_1", 200.0, 10.0, ("N_in", "S_out"))

    def passing(b_pos: float):
        return _pair(net, [a, ("b", "N_out_1", b_pos, 10.0, ("S_in", "N_out"))], lateral=((0.0, 0.0), (0.9, 1.0)))

    # N_out runs opposite N_in: b's front bumper at n_in - 200 + 0.9 + 4.5 puts its centre 0.9 m past a's.
    pairs = passing(n_in - 200.0 + 0.9 + LENGTH)
    assert len(pairs) == 1 and pairs.kind[0] == 1
    theta = np.arctan2(1.0, 10.0)  # b's heading against its lane: its box reaches further along it
    along = 0.5 * LENGTH + 0.5 * (LENGTH * np.cos(theta) + WIDTH * np.sin(theta))
    assert pairs.lon_gap[0] == pytest.approx(0.9 - along, abs=0.05) and pairs.dangerous[0]
    assert len(passing(n_in - 200.0 + LENGTH + LENGTH + 0.5)) == 0


def test_a_car_standing_still_lies_along_its_lane_whatever_its_noise_level_lateral_speed():
    """A placed ego at rest had lateral speeds of ±1e-5 m/s (its position's rounding); the footprint followed the
    direction of motion, arctan2(1e-5, 0) = 90°, so the car took its length across the road, and two cars standing
    beside it in the next lanes were in lateral danger (gaps 0.24 m for the real 1.66 m)."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    cars = [("ego", "hw0_1", 300.0, 1e-5), ("left", "hw0_2", 300.0, 0.0), ("right", "hw0_0", 300.0, 0.0)]
    poses = [_front_bumper(net, lane, pos) for _, lane, pos, _ in cars]
    n = len(cars)
    lanes = np.array([c[1] for c in cars])
    snapshot = WorldSnapshot(
        time=0.0, ids=np.array([c[0] for c in cars]), x=np.array([p[0] for p in poses]),
        y=np.array([p[1] for p in poses]), heading=np.array([p[2] for p in poses]), speed=np.zeros(n),
        accel=np.zeros(n), lat_speed=np.array([c[3] for c in cars]), length=np.full(n, LENGTH),
        width=np.full(n, WIDTH), lane_id=lanes, edge_id=np.full(n, "hw0"), lane_index=np.array([1, 2, 0]),
        lane_pos=np.full(n, 300.0), lat_pos=np.zeros(n), vclass=np.array(["ego", "background", "background"]),
        vtype=np.full(n, "car"), signals=np.zeros(n, int), route_index=np.zeros(n, int), route_edges=None)
    params = RssParamArrays.stack([preset_params("ad_rss", "background")] * n)
    pairs = evaluate(snapshot, vehicle_frame(snapshot, net, params, RouteTable(net).remaining(snapshot)), net)
    beside = np.flatnonzero(np.isin(snapshot.ids[pairs.a], ["ego"]) | np.isin(snapshot.ids[pairs.b], ["ego"]))
    assert len(beside) == 2
    assert pairs.lat_gap[beside] == pytest.approx([3.5 - WIDTH] * 2, abs=1e-6)
    assert not pairs.dangerous[beside].any()


def test_a_junction_that_only_joins_two_edges_has_a_lane_frame_and_no_false_danger(tmp_path):
    """netconvert writes the internal lane of a node that only joins two edges as one point twice (length 0.10 m):
    its frame divided by zero (NaN offsets, a raw numpy warning) and a car on it was in danger with a leader 160 m
    ahead. Its frame now runs straight on in the direction of the lane it leads to."""
    import subprocess
    import warnings

    from sumo_rss.rss.auditor import ParamResolver
    from sumo_rss.rss.fcd import audit_fcd
    from sumo_rss.sumo_home import sumo_tool

    (tmp_path / "n.nod.xml").write_text('<nodes><node id="A" x="0" y="0"/><node id="B" x="500" y="100"/>'
                                        '<node id="C" x="1000" y="200"/></nodes>')
    (tmp_path / "n.edg.xml").write_text('<edges><edge id="AB" from="A" to="B" numLanes="1" speed="30"/>'
                                        '<edge id="BC" from="B" to="C" numLanes="1" speed="30"/></edges>')
    subprocess.run([str(sumo_tool("netconvert")), "-n", str(tmp_path / "n.nod.xml"), "-e", str(tmp_path / "n.edg.xml"),
                    "-o", str(tmp_path / "n.net.xml")], check=True, capture_output=True)
    net = RoadNetwork.from_file(tmp_path / "n.net.xml")
    k = int(net.lane_indices([":B_0_0"])[0])
    start = net.shapes.points[k, 0]
    assert net.lane_length[k] == pytest.approx(0.1)  # the network has what this test is about
    heading = np.arctan2(100.0, 500.0)
    normal = np.array([-np.sin(heading), np.cos(heading)])
    s, d, lane_heading = net.frenet(np.array([k, k]), np.array([start[0], start[0] + normal[0]]),
                                    np.array([start[1], start[1] + normal[1]]))
    np.testing.assert_allclose(s, [0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(d, [0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(lane_heading, heading, atol=1e-9)
    # A follower on the junction's lane, its leader 160 m on along BC, both at 20 m/s: safe (d_min ≈ 46 m).
    ahead = start + 160.0 * np.array([np.cos(heading), np.sin(heading)])
    angle = f"{90.0 - np.degrees(heading):.6f}"
    steps = "".join(
        f'<timestep time="{t:.2f}">'
        f'<vehicle id="follower" x="{start[0]:.6f}" y="{start[1]:.6f}" angle="{angle}" speed="20" lane=":B_0_0" '
        f'pos="0.05" acceleration="0"/>'
        f'<vehicle id="leader" x="{ahead[0] + 2.0 * t:.6f}" y="{ahead[1]:.6f}" angle="{angle}" speed="20" '
        f'lane="BC_0" pos="{160.0 + 2.0 * t:.6f}" acceleration="0"/></timestep>' for t in (0.0, 0.1))
    (tmp_path / "fcd.xml").write_text(f"<fcd-export>{steps}</fcd-export>")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        warnings.filterwarnings("ignore", r".*vType", UserWarning)
        result = audit_fcd(tmp_path / "fcd.xml", net, ParamResolver())
    assert result.episodes.empty


def test_a_car_standing_still_at_a_lane_changes_leftover_angle_lies_along_its_lane():
    """sumo --lanechange.duration leaves a car that stops at the end of a lane change at its angle (38° at its lane's
    centre): its centre, put half its length behind the front bumper at that angle, was up to 1.5 m towards the
    next lane, and a car standing there overlapped it (a collision SUMO never had, when audited without its collision
    file). Standing, it lies along its lane; moving, SUMO's angle counts."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    cars = [("turned", "hw0_1", 300.0), ("left", "hw0_2", 301.0)]
    poses = [_front_bumper(net, lane, pos) for _, lane, pos in cars]
    n = len(cars)

    def pairs(speed: float):
        snapshot = WorldSnapshot(
            time=0.0, ids=np.array([c[0] for c in cars]), x=np.array([p[0] for p in poses]),
            y=np.array([p[1] for p in poses]), heading=np.array([poses[0][2] - np.radians(38.0), poses[1][2]]),
            speed=np.array([speed, 0.0]), accel=np.zeros(n), lat_speed=np.zeros(n), length=np.full(n, LENGTH),
            width=np.full(n, WIDTH), lane_id=np.array([c[1] for c in cars]), edge_id=np.full(n, "hw0"),
            lane_index=np.array([1, 2]), lane_pos=np.array([c[2] for c in cars]), lat_pos=np.zeros(n),
            vclass=np.full(n, "background"), vtype=np.full(n, "car"), signals=np.zeros(n, int),
            route_index=np.zeros(n, int), route_edges=None)
        params = RssParamArrays.stack([preset_params("ad_rss", "background")] * n)
        return evaluate(snapshot, vehicle_frame(snapshot, net, params, RouteTable(net).remaining(snapshot)), net)

    standing = pairs(0.0)
    assert standing.lat_gap == pytest.approx([3.5 - WIDTH], abs=1e-6)
    moving = pairs(1.0)  # its centre where SUMO's angle puts it: 0.5 * 4.5 m * sin 38° towards the left lane
    assert moving.lat_gap == pytest.approx([3.5 - WIDTH - 0.5 * LENGTH * np.sin(np.radians(38.0))], abs=1e-6)
