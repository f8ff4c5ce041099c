"""The SSC corridor on the straight part of the highway net (hw0: three 3.5 m lanes; the frame's d = 0 is the
middle lane's centre, so the road spans d ∈ [−5.25, 5.25] m). The ego and the agents are 4.5 m × 1.8 m."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.lanes import lane_chains
from sumo_rss.planner.motion.corridor import CorridorSettings, RoadLayer, build_corridor, occupancy
from sumo_rss.planner.motion.ssc_qp import MotionFailure
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork

LENGTH, WIDTH = 4.5, 1.8  # [m]
SETTINGS = CorridorSettings()
TIMES = np.round(np.arange(26) * 0.2, 10)  # [s] the forward simulation's samples over 5 s
EGO_S = 100.3  # [m]


@pytest.fixture(scope="module")
def road():
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    frame = RoadFrame.build(lane_chains(net, int(net.lane_indices(["hw0_1"])[0]), net.edge_indices(["hw0", "hw1"])))
    return RoadLayer(frame, LENGTH, WIDTH, SETTINGS)


def _agents(s, d, n=1):
    """Agents at (s[k, i], d[k, i]) with heading 0."""
    s, d = np.asarray(s, float).reshape(TIMES.size, n), np.asarray(d, float).reshape(TIMES.size, n)
    return s, d, np.zeros_like(s), np.full(n, LENGTH), np.full(n, WIDTH)


def _cells(grid):
    s = grid.s_origin + SETTINGS.s_res * np.arange(SETTINGS.s_cells)
    d = SETTINGS.d_min + SETTINGS.d_res * np.arange(SETTINGS.d_cells)
    return s, d


def test_road_edges_keep_the_ego_body_on_the_three_lanes(road):
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, _agents(np.full(26, -1e3), np.zeros(26)), np.inf, SETTINGS)
    _, d = _cells(grid)
    free = ~grid.occupied[0, 20]  # the ego's own s cell
    # A centre anywhere in a free cell keeps the body (± 0.9 m) on [−5.25, 5.25] m (0.01 m: touching lanes).
    assert np.all(np.abs(d[free]) + 0.1 + 0.5 * WIDTH <= 5.25 + 0.01 + 1e-9)
    # ... and every cell whose body certainly fits is free: |d| + 0.1 + 0.9 ≤ 5.25 − one cell of quantisation.
    assert np.all(free[np.abs(d) + 0.1 + 0.5 * WIDTH <= 5.25 - 0.2])
    assert free[np.isclose(d, 4.0)].all() and not free[np.isclose(d, 4.6)].any()
    assert np.array_equal(free, free[::-1])  # symmetric road


def test_an_ego_over_the_road_edge_plans_from_where_it_is_and_no_further_out(road):
    """An ego whose body is 0.45 m over the right edge (centre at d = −4.8 m; the road ends at −5.25 m): without
    its d its own cell is off-road and every corridor fails at the start; with it the right edge moves out to the
    ego's cell and no further, the left edge stays, and a corridor back to the lane centre is found."""
    empty = _agents(np.full(26, -1e3), np.zeros(26))
    ego_d = -4.8
    fixed = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, empty, np.inf, SETTINGS)
    moved = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, empty, np.inf, SETTINGS, ego_d=ego_d)
    _, d = _cells(moved)
    ego_cell = np.isclose(d, ego_d)
    before, after = ~fixed.occupied[0, 20], ~moved.occupied[0, 20]
    assert not before[ego_cell].any() and after[ego_cell].all()
    assert np.array_equal(after, before | ((d >= ego_d - 1e-9) & (d < 0.0)))  # freed up to the ego's cell only
    assert np.array_equal(moved.occupied[:, :, d > 0.0], fixed.occupied[:, :, d > 0.0])
    seeds_d = np.minimum(ego_d + 0.5 * TIMES, -3.5)  # back to the right lane's centre
    with pytest.raises(MotionFailure):
        build_corridor(fixed, EGO_S + 20.0 * TIMES, seeds_d, 20.0)
    corridor = build_corridor(moved, EGO_S + 20.0 * TIMES, seeds_d, 20.0)
    assert corridor.knots[-1] == pytest.approx(TIMES[-1])
    # An ego on the road changes nothing, and neither does one whose centre is off it too (more than half its
    # width beyond the nearest free cell: not an overhang to plan back from).
    for d_elsewhere in (-3.5, -6.0):
        elsewhere = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, empty, np.inf, SETTINGS, ego_d=d_elsewhere)
        assert np.array_equal(elsewhere.occupied, fixed.occupied)


def test_agents_are_inflated_by_the_ego_footprint_and_rasterised_conservatively(road):
    s_agent = EGO_S + 30.0 + 2.0 * TIMES  # [m] 30 m ahead, 2 m/s faster
    empty = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, _agents(np.full(26, -1e3), np.zeros(26)), np.inf, SETTINGS)
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, _agents(s_agent, np.full(26, 0.3)), np.inf, SETTINGS)
    s, d = _cells(grid)
    half_s = 0.5 * LENGTH + 0.5 * LENGTH + SETTINGS.margin  # 4.6 m
    half_d = 0.5 * WIDTH + 0.5 * WIDTH + SETTINGS.margin  # 1.9 m
    for k in (0, 12, 25):
        touches_s = (s + 0.5 * SETTINGS.s_res >= s_agent[k] - half_s) & (s - 0.5 * SETTINGS.s_res <= s_agent[k] + half_s)
        touches_d = (d + 0.5 * SETTINGS.d_res >= 0.3 - half_d) & (d - 0.5 * SETTINGS.d_res <= 0.3 + half_d)
        expected = (touches_s[:, None] & touches_d[None, :]) | empty.occupied[k]
        assert np.array_equal(grid.occupied[k], expected), k


def test_corridor_chains_free_cubes_with_shared_time_boundaries_around_the_seeds(road):
    v = 15.0  # [m/s]
    seeds_s, seeds_d = EGO_S + v * TIMES, np.zeros(TIMES.size)
    agents = _agents(np.column_stack([EGO_S + 40.0 + v * TIMES, EGO_S - 25.0 + v * TIMES]),
                     np.column_stack([np.zeros(26), np.full(26, 3.5)]), n=2)
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, agents, np.inf, SETTINGS)
    corridor = build_corridor(grid, seeds_s, seeds_d, v)
    assert corridor.knots[0] == 0.0 and corridor.knots[-1] == pytest.approx(TIMES[-1])
    assert np.all(np.diff(corridor.knots) > 0.0)
    cells = corridor.cells
    assert np.array_equal(cells[1:, 4], cells[:-1, 5])  # consecutive cubes share their time boundary
    for s_lo, s_hi, d_lo, d_hi, t_lo, t_hi in cells:
        assert not grid.occupied[t_lo:t_hi + 1, s_lo:s_hi + 1, d_lo:d_hi + 1].any()
    assert corridor.contains(TIMES, seeds_s, seeds_d).all()
    # The car ahead bounds the cubes: the ego's centre stays 4.6 m (+ rasterisation) behind the car's centre.
    lead = EGO_S + 40.0 + v * corridor.knots[1:]
    assert np.all(corridor.bounds[:, 0, 1] <= lead - 4.6 + 1e-9)


def test_a_stop_line_bounds_the_ego_centre(road):
    stop = EGO_S + 30.0  # [m]
    seeds_s = EGO_S + np.minimum(10.0 * TIMES - TIMES ** 2, 25.0)  # braking from 10 m/s, stays 5 m short
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, _agents(np.full(26, -1e3), np.zeros(26)), stop, SETTINGS)
    corridor = build_corridor(grid, seeds_s, np.zeros(26), 10.0)
    assert np.all(corridor.bounds[:, 0, 1] <= stop + 1e-9)


def test_a_path_through_a_car_is_reported_not_crashed_on(road):
    parked = _agents(np.full(26, EGO_S + 20.0), np.zeros(26))
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, parked, np.inf, SETTINGS)
    with pytest.raises(MotionFailure) as failure:
        build_corridor(grid, EGO_S + 15.0 * TIMES, np.zeros(26), 15.0)
    assert failure.value.reason == "corridor_blocked"


def test_a_corridor_ends_before_a_blocked_seed_late_in_the_horizon(road):
    # The seeds reach a car parked 60 m ahead (its inflated box from 55.4 m, a cell from 55.2 m) at the 3.8 s seed
    # at 15 m/s: the corridor covers the free seeds before it (>= 2 s); the QP's end state is the last of them.
    parked = _agents(np.full(26, EGO_S + 60.0), np.zeros(26))
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, parked, np.inf, SETTINGS)
    seeds = EGO_S + 15.0 * TIMES
    corridor = build_corridor(grid, seeds, np.zeros(26), 15.0)
    end = corridor.knots[-1]
    assert end == pytest.approx(3.6) and end == TIMES[corridor.cells[-1, 5]]
    assert not grid.occupied[corridor.cells[-1, 5], grid.s_index(seeds[TIMES == end])[0], grid.d_index(np.zeros(1))[0]]
    for cube in corridor.cells:
        assert not grid.occupied[cube[4]:cube[5] + 1, cube[0]:cube[1] + 1, cube[2]:cube[3] + 1].any()


def _free_centre_cells(net, lane, route, ego_s, heading=None):
    """The s centres of the grid's cells on d = 0 and whether they are free in the first slice, with no agents."""
    frame = RoadFrame.build(lane_chains(net, int(net.lane_indices([lane])[0]), net.edge_indices(route)))
    grid = occupancy(RoadLayer(frame, LENGTH, WIDTH, SETTINGS), TIMES, ego_s, LENGTH, WIDTH,
                     _agents(np.full(26, -1e4), np.zeros(26)), np.inf, SETTINGS, heading)
    s, d = _cells(grid)
    return s, ~grid.occupied[0][:, np.isclose(d, 0.0)].ravel()


def test_the_road_goes_on_past_both_ends_of_the_network_but_not_past_a_lane_that_ends():
    # hw2 is the last edge of the highway (899.87 m): the car leaves the network there, so its lane goes on.
    highway = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")
    s, free = _free_centre_cells(highway, "hw2_1", ["hw2"], 880.0)
    assert free[(s > 880.0) & (s < 1000.0)].all()
    # hw0 starts the network: a car that has just entered has its rear behind the start of its lane.
    s, free = _free_centre_cells(highway, "hw0_1", ["hw0"], 1.0)
    assert free[(s > -10.0) & (s < 100.0)].all()
    # The acceleration lane (to 270.56 m) ends for good: no centre in a free cell puts the front bumper past its
    # end (the body's front reaches half a cell and half the car's length beyond the centre's cell centre).
    merge = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    s, free = _free_centre_cells(merge, "mw_merge_0", ["mw_merge", "mw_out"], 200.0)
    end = 270.5588739
    assert not free[s + 0.5 * SETTINGS.s_res + 0.5 * LENGTH > end].any()
    assert free[(s > 200.0) & (s + 0.5 * SETTINGS.s_res + 0.5 * LENGTH + SETTINGS.s_res <= end)].all()


def test_a_turned_ego_is_kept_clear_of_agents_by_its_turned_footprint(road):
    # Turned by 0.44 rad (merging at walking pace) the body reaches 0.5·(4.5·sin + 1.8·cos) = 1.78 m across and
    # 0.5·(4.5·cos + 1.8·sin) = 2.43 m along, not 0.9 m and 2.25 m.
    heading = np.full(26, 0.44)
    reach_d = 0.5 * (LENGTH * np.sin(0.44) + WIDTH * np.cos(0.44))
    reach_s = 0.5 * (LENGTH * np.cos(0.44) + WIDTH * np.sin(0.44))
    agent_s = EGO_S + 20.0
    agent = _agents(np.full(26, agent_s), np.full(26, 3.5))
    grid = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, agent, np.inf, SETTINGS, heading)
    straight = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, agent, np.inf, SETTINGS)
    s, d = _cells(grid)
    # The agent (4.5 × 1.8 m, straight, in the left lane): its box plus the turned footprint and the margin.
    half_s, half_d = 0.5 * LENGTH + reach_s + SETTINGS.margin, 0.5 * WIDTH + reach_d + SETTINGS.margin
    touches = (np.abs(s - agent_s)[:, None] <= half_s + 0.5 * SETTINGS.s_res) & \
        (np.abs(d - 3.5)[None, :] <= half_d + 0.5 * SETTINGS.d_res)
    # The road edges are the unturned body's: the same as with no agent and no heading.
    empty = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, _agents(np.full(26, -1e3), np.zeros(26)), np.inf, SETTINGS)
    assert np.array_equal(grid.occupied[0], touches | empty.occupied[0])
    assert (grid.occupied[0] & ~straight.occupied[0]).any()  # more is blocked than for the unturned body
    # Turned only at the last sample: the slices before its neighbour keep the unturned footprint.
    late = occupancy(road, TIMES, EGO_S, LENGTH, WIDTH, agent, np.inf, SETTINGS,
                     np.where(np.arange(26) == 25, 0.44, 0.0))
    assert np.array_equal(late.occupied[:24], straight.occupied[:24])
    assert np.array_equal(late.occupied[24:], grid.occupied[24:])
