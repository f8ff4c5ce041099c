"""Gap seeking for a held discretionary lane change (planner/gap_seek.py; docs/planner.md, "The discretionary
overtake seeks its gap"): hand-made states on the shipped highway, the planner's real forward simulation."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.planner.behavior.dcp_tree import Lat
from sumo_rss.planner.behavior.forward_sim import Vehicles
from sumo_rss.planner.behavior.manager import LaneChangeContext
from sumo_rss.planner.epsilon import EpsilonPlanner, PlannerConfig
from sumo_rss.planner.gap_seek import line_up_speed
from sumo_rss.planner.lanes import CURRENT, LEFT
from sumo_rss.rss import formulas
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.params import RssParamArrays, preset_params
from sumo_rss.road.network import RoadNetwork
from sumo_rss.sim.snapshot import WorldSnapshot

EGO, CAR = preset_params("ad_rss", "ego"), preset_params("ad_rss", "background")


def _vehicles(s: list[float], speed: list[float], chain: list[int]) -> tuple[Vehicles, RssParamArrays]:
    n = len(s)
    zeros = np.zeros(n)
    vehicles = Vehicles(s=np.array(s, float), d=zeros, heading=zeros, speed=np.array(speed, float), accel=zeros,
                        curvature=zeros, length=np.array([4.7] + [4.5] * (n - 1)), width=np.full(n, 1.9),
                        chain=np.array(chain))
    return vehicles, RssParamArrays.stack([EGO] + [CAR] * (n - 1))


def test_a_gap_behind_a_passing_car_lines_up_at_the_ego_speed_once_the_car_is_far_enough_ahead():
    """The ego at 21 m/s behind a truck at 21 m/s; in the left lane a car at 31 m/s 20 m behind (centres) and the
    next 300 m behind: the gap between them lines up when the first is d_min(21, 31) ahead (6.2 s), and stays
    until the second is d_min(31, 21) + 10 m (the barrier's 1 s look-ahead) behind (13.1 s)."""
    cars = _vehicles([0.0, 70.0, -20.0, -300.0], [21.0, 21.0, 31.0, 31.0], [CURRENT, CURRENT, LEFT, LEFT])
    front_need = float(formulas.lon_safe_distance_same_dir(21.0, 31.0, EGO, CAR))
    opens = (front_need + 20.0 + 0.5 * (4.5 + 4.7)) / 10.0
    assert 6.0 < opens < 6.5
    assert line_up_speed(*cars, Lat.LEFT, opens + 0.1, 5.0, 1.0, 250.0) == pytest.approx(21.0)  # no slower than it is
    assert line_up_speed(*cars, Lat.RIGHT, 30.0, 5.0, 1.0, 250.0) is None  # nobody in the right lane: nothing lines up


def test_a_gap_too_short_at_the_ego_speed_lines_up_slower_and_none_lines_up_in_a_dense_stream():
    """210 m between the left lane's cars (bumpers) is short for a change at 21 m/s (d_min(31, 21) = 154 m behind the
    ego, d_min(21, 31) = 38 m before the car ahead and 10 m that close in 1 s); 1 m/s slower the ego needs less ahead
    than it needs more behind: it lines up at 20 m/s, and never at 21. Cars every 60 m leave no gap at any speed:
    no seeking (the change is called off)."""
    short = _vehicles([0.0, 70.0, -20.0, -230.0], [21.0, 21.0, 31.0, 31.0], [CURRENT, CURRENT, LEFT, LEFT])
    assert line_up_speed(*short, Lat.LEFT, 15.0, 5.0, 1.0, 250.0) == pytest.approx(20.0)
    assert line_up_speed(*short, Lat.LEFT, 60.0, 0.0, 1.0, 250.0) is None  # at 21 m/s never
    s = [0.0, 70.0] + list(-20.0 - 60.0 * np.arange(6))
    dense = _vehicles(s, [21.0, 21.0] + [31.0] * 6, [CURRENT, CURRENT] + [LEFT] * 6)
    assert line_up_speed(*dense, Lat.LEFT, 6.0, 5.0, 1.0, 250.0) is None


def test_a_gap_safe_now_is_not_sought():
    """A change held beside a gap that is RSS-safe now is held by something this test does not see: no seeking."""
    cars = _vehicles([0.0, 70.0, 150.0, -300.0], [21.0, 21.0, 31.0, 21.0], [CURRENT, CURRENT, LEFT, LEFT])
    assert line_up_speed(*cars, Lat.LEFT, 15.0, 5.0, 1.0, 250.0) is None


def _snapshot(xs: list[float], lanes: list[str], speeds: list[float]) -> WorldSnapshot:
    n = len(xs)
    f = np.zeros(n)
    y = {"hw0_0": -8.75, "hw0_1": -5.25, "hw0_2": -1.75}
    vclass = np.array(["ego"] + ["background"] * (n - 1))
    return WorldSnapshot(time=40.0, ids=np.array([f"v{i}" for i in range(n)]), x=np.asarray(xs, float),
                         y=np.array([y[lane] for lane in lanes]), heading=f.copy(), speed=np.asarray(speeds, float),
                         accel=f.copy(), lat_speed=f.copy(), length=np.full(n, 4.5), width=np.full(n, 1.8),
                         lane_id=np.array(lanes), edge_id=np.array(["hw0"] * n),
                         lane_index=np.array([int(lane[-1]) for lane in lanes]), lane_pos=np.asarray(xs, float),
                         lat_pos=f.copy(), vclass=vclass, vtype=np.array(["car"] * n), signals=np.zeros(n, int),
                         route_index=np.zeros(n, int), route_edges=tuple(("hw0", "hw1", "hw2") for _ in range(n)))


def _planner_with_due_left_change(net: RoadNetwork, snap: WorldSnapshot) -> EpsilonPlanner:
    planner = EpsilonPlanner(net, ParamResolver(), PlannerConfig(desired_speed=33.0))
    lane = planner.planning_lane(snap, 0)[0]
    planner.manager.context = LaneChangeContext(Lat.LEFT, 36.0, 39.0, frozenset({lane}))
    return planner


@pytest.mark.parametrize("cars, kept", [(1, True), (5, False)])
def test_a_held_overtake_is_kept_while_a_gap_lines_up_and_called_off_where_none_can(highway, cars, kept):
    """The ego at 21 m/s in the right lane 70 m behind a truck at 21 m/s, a due left change (operation time 39 s,
    now 40 s); the left lane's car at 25 m/s 20 m behind the ego holds the change (the barrier) over the horizon.
    Alone, the gap behind it lines up within the context's 14 s left at 19 m/s (at 21 m/s in 20.8 s): the context
    is kept and the next cycle seeks, slower; with a stream every 60 m no gap can come: called off as before."""
    net, _ = highway
    behind = [580.0 - 60.0 * k for k in range(cars)]
    snap = _snapshot([600.0, 670.0] + behind, ["hw0_0", "hw0_0"] + ["hw0_1"] * cars, [21.0, 21.0] + [25.0] * cars)
    planner = _planner_with_due_left_change(net, snap)
    result = planner.plan(snap, "v0")
    assert np.max(result.trajectory.y) < -8.75 + 0.6  # held in its lane
    assert (planner.manager.context is not None) is kept
    assert planner.manager.lane_changes_called_off == int(not kept)
    later = _snapshot(list(np.array(snap.x) + 0.1 * snap.speed), list(snap.lane_id), list(snap.speed))
    seeking = planner.plan(WorldSnapshot(**{**vars(later), "time": 40.1}), "v0")
    assert planner.stats.overtake_seek_cycles == int(kept)
    if kept:
        assert seeking.trajectory.speed[-1] < 20.0


def test_no_seeking_without_a_held_change(highway):
    """The same scene without a lane-change context: nothing is held, nothing is sought."""
    snap = _snapshot([600.0, 670.0, 580.0, 280.0], ["hw0_0", "hw0_0", "hw0_1", "hw0_1"], [21.0, 21.0, 31.0, 31.0])
    planner = EpsilonPlanner(highway[0], ParamResolver(), PlannerConfig(desired_speed=33.0))
    for k in range(3):
        planner.plan(WorldSnapshot(**{**vars(snap), "time": 40.0 + 0.1 * k}), "v0")
    assert planner.stats.overtake_seek_cycles == 0
