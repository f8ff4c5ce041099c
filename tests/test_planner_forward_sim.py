"""Forward simulation, evaluation and the planner's backup on the straight part of the highway net (hw0: lanes
at y = -8.75 / -5.25 / -1.75, 3.5 m apart; the frame's s runs along +x from the start of hw0)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.planner.behavior.cost_weights import CostWeights
from sumo_rss.planner.behavior.evaluation import breaks_lateral_response, leader_gap_for_cost, rss_penalty
from sumo_rss.boxes import boxes_overlap
from sumo_rss.planner.behavior.forward_sim import JunctionArea, Rollouts, SimSettings, Vehicles, prefix_tree, \
    simulate, step_times
from sumo_rss.planner.behavior.leaders import EGO_LEADER_RANGE, LEADER_RANGE, leaders_ahead
from sumo_rss.planner.epsilon import BACKUP, EpsilonPlanner, PlannerConfig
from sumo_rss.planner.lanes import CURRENT, LEFT, RIGHT, lane_chains
from sumo_rss.planner.road_frame import RoadFrame
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss import formulas
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.params import RssParamArrays, RssParams
from sumo_rss.sim.snapshot import WorldSnapshot


def _vehicles(s, d, v, length=4.5, chain=None):
    n = len(s)
    z = np.zeros(n)
    return Vehicles(np.asarray(s, float), np.asarray(d, float), z.copy(), np.asarray(v, float), z.copy(), z.copy(),
                    np.full(n, length), np.full(n, 1.8), np.asarray(chain if chain is not None else [CURRENT] * n))


def _keep(n_rollouts, n, layers=5, v0=20.0, chains=None):
    return Rollouts(np.full((n_rollouts, layers), CURRENT), np.full(n_rollouts, v0), np.ones(n_rollouts),
                    np.zeros(n_rollouts, dtype=bool), 4.2,
                    np.full((n_rollouts, n), CURRENT) if chains is None else chains, np.zeros(n))


def test_frame_offsets_and_round_trip(highway):
    _, frame = highway
    assert frame.exists.tolist() == [True, True, True]
    np.testing.assert_allclose(frame.centre_d([RIGHT, CURRENT, LEFT], [100.0] * 3), [-3.5, 0.0, 3.5], atol=1e-9)
    x, y, h = frame.to_world(np.array([100.0]), np.array([1.0]), np.array([0.1]))
    np.testing.assert_allclose([x[0], y[0], h[0]], [100.0, -4.25, 0.1], atol=1e-9)
    s, d, rel = frame.to_frame(x, y, h)
    np.testing.assert_allclose([s[0], d[0], rel[0]], [100.0, 1.0, 0.1], atol=1e-9)


def test_bumper_placement_keeps_the_lateral_offset_across_polyline_vertices(highway):
    """hw1 is a curve stored as a polyline (a vertex every ~34 m, ~1° apart). A car whose centre keeps d and its
    heading against the lane is placed so that SUMO reads a constant lateral offset of its front bumper — no
    phantom lateral speed at the vertices — and the placement inverts exactly."""
    net, frame = highway
    hw1 = int(net.lane_indices(["hw1_1"])[0])
    s = frame.to_frame(*net.shapes.points[hw1, 0], 0.0)[0][0] + np.arange(20.0, 220.0, 0.5)
    d, rel, half = np.full(s.size, 0.3), np.full(s.size, 0.02), 2.35
    x, y, heading = frame.bumper_at(s, d, rel, half)
    _, bumper_offset, _ = net.frenet(np.full(s.size, hw1), x, y)
    np.testing.assert_allclose(bumper_offset, 0.3 + half * np.sin(0.02), atol=1e-6)
    back = frame.centre_of_bumper(x, y, heading, half)
    np.testing.assert_allclose(np.stack(back), np.stack([s, d, rel]), atol=1e-6)
    # Rotating the bumper about the centre by the smooth heading instead reads ±v·Δangle/2 at every vertex.
    cx, cy, _ = frame.to_world(s, d, rel)
    smooth = np.interp(s, s[::60], np.unwrap(heading)[::60])
    _, rotated, _ = net.frenet(np.full(s.size, hw1), cx + half * np.cos(smooth), cy + half * np.sin(smooth))
    assert np.ptp(rotated) > 0.02


def test_step_times_keep_the_decision_grid():
    t, ends = step_times((0.3, 1.0, 1.0), 0.2)
    np.testing.assert_allclose(t, [0, 0.15, 0.3, 0.5, 0.7, 0.9, 1.1, 1.3, 1.5, 1.7, 1.9, 2.1, 2.3])
    assert ends.tolist() == [2, 7, 12]


def test_boxes_overlap_hand_cases():
    # Two 4 x 2 boxes: centres 3.9 m apart along x overlap, 4.1 m do not; rotated by 90° the second is 2 long.
    assert boxes_overlap(0, 0, 0, 4, 2, 3.9, 0, 0, 4, 2) and not boxes_overlap(0, 0, 0, 4, 2, 4.1, 0, 0, 4, 2)
    assert boxes_overlap(0, 0, 0, 4, 2, 2.9, 0, np.pi / 2, 4, 2)
    assert not boxes_overlap(0, 0, 0, 4, 2, 3.1, 0, np.pi / 2, 4, 2)


def test_follower_behind_a_stopped_car_stops_without_collision(highway):
    _, frame = highway
    # The ego at 15 m/s, 60 m behind a stopped car in its lane (bumper gap 55.5 m); 12 s of keep-lane.
    vehicles = _vehicles([100.0, 160.0], [0.0, 0.0], [15.0, 0.0])
    p = RssParamArrays.stack([RssParams()] * 2)
    sim = simulate(frame, vehicles, _keep(1, 2, layers=12, v0=20.0), (1.0,) * 12, SimSettings(), RssParams(), p)
    gap = sim.s[0, :, 1] - sim.s[0, :, 0] - 4.5
    # It stops farther back than the RSS distance between two stopped cars, ½·3.5·1² + 3.5²/(2·4) = 3.28 m.
    assert sim.valid[0] and gap.min() > 3.28
    assert sim.speed[0, -1, 0] < 0.5 and np.all(sim.speed[0, :, 1] == 0.0)
    # The ego's leader is the stopped car at every sample.
    np.testing.assert_allclose(sim.ego_lead_gap[0], gap)


def test_agent_behind_a_stopped_agent_stops_and_the_ego_is_its_leader(highway):
    _, frame = highway
    # Column 1 (an agent) follows the ego, which is stopped; agents use a 1.0 m minimum gap.
    vehicles = _vehicles([160.0, 110.0], [0.0, 0.0], [0.0, 14.0])
    p = RssParamArrays.stack([RssParams()] * 2)
    rollouts = _keep(1, 2, layers=8, v0=0.0)
    rollouts = Rollouts(rollouts.ego_chain, rollouts.ego_v0, rollouts.ego_spacing_scale, rollouts.ego_backup, 4.2,
                        rollouts.agent_chain, np.array([0.0, 14.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 8, SimSettings(), RssParams(), p)
    assert sim.valid[0] and sim.speed[0, -1, 1] < 0.5
    assert (sim.s[0, :, 0] - sim.s[0, :, 1] - 4.5).min() > 0.5


def test_lane_change_rollout_crosses_into_the_left_lane_unless_the_gap_is_unsafe(highway):
    _, frame = highway
    p = RssParamArrays.stack([RssParams()] * 2)
    # Left lane free (the only agent far behind in the right lane): the ego crosses the lane boundary (1.75 m)
    # and keeps going towards the left lane's centre.
    vehicles = _vehicles([100.0, 20.0], [0.0, -3.5], [20.0, 20.0], chain=[CURRENT, RIGHT])
    ego_chain = np.array([[CURRENT, LEFT, LEFT, LEFT, LEFT]])
    free = Rollouts(ego_chain, np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2, np.array([[1, RIGHT]]),
                    np.array([0.0, 20.0]))
    sim = simulate(frame, vehicles, free, (1.0,) * 5, SimSettings(), RssParams(), p)
    assert sim.valid[0] and sim.d[0, -1, 0] > 1.75 and np.all(np.diff(sim.d[0, 6:, 0]) > 0.0)
    beside = _vehicles([100.0, 100.0], [0.0, 3.5], [20.0, 20.0], chain=[CURRENT, LEFT])
    blocked = Rollouts(ego_chain, np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2, np.array([[1, LEFT]]),
                       np.array([0.0, 20.0]))
    sim = simulate(frame, beside, blocked, (1.0,) * 5, SimSettings(), RssParams(), p)
    # The RSS barrier holds the ego in its lane (no lateral progress beside an unsafe gap), so it is valid but
    # does not reach the left lane.
    assert sim.barrier_steps[0] > 0 and sim.d[0, -1, 0] < 1.5


def _snapshot(xs, ys, speeds, lanes, ego=0):
    n = len(xs)
    f = np.zeros(n)
    edges = [lane.rsplit("_", 1)[0] for lane in lanes]
    vclass = np.array(["background"] * n)
    vclass[ego] = "ego"
    return WorldSnapshot(time=40.0, ids=np.array([f"v{i}" for i in range(n)]), x=np.asarray(xs, float),
                         y=np.asarray(ys, float), heading=f.copy(), speed=np.asarray(speeds, float), accel=f.copy(),
                         lat_speed=f.copy(), length=np.full(n, 4.5), width=np.full(n, 1.8),
                         lane_id=np.array(lanes), edge_id=np.array(edges), lane_index=np.array(
                             [int(lane.rsplit("_", 1)[1]) for lane in lanes]),
                         lane_pos=np.asarray(xs, float), lat_pos=f.copy(), vclass=vclass,
                         vtype=np.array(["car"] * n), signals=np.zeros(n, int), route_index=np.zeros(n, int),
                         route_edges=tuple(("hw0", "hw1", "hw2") for _ in range(n)))


def test_backup_is_chosen_when_every_policy_collides(highway):
    net, _ = highway
    # The ego at 30 m/s; stopped cars 14 m ahead (front bumpers) in all three lanes: nothing avoids them.
    snap = _snapshot([300.0, 318.5, 318.5, 318.5], [-5.25, -5.25, -8.75, -1.75], [30.0, 0.0, 0.0, 0.0],
                     ["hw0_1", "hw0_1", "hw0_0", "hw0_2"])
    planner = EpsilonPlanner(net, ParamResolver(), PlannerConfig(desired_speed=30.0))
    result = planner.plan(snap, "v0")
    assert result.backup and result.policy == BACKUP
    assert all(np.isinf(c) for name, c in result.costs.items() if name != BACKUP)
    # The backup keeps the lane and brakes at b_min + 0.2 = 4.2 m/s² (ad_rss ego).
    np.testing.assert_allclose(result.trajectory.y, -5.25, atol=0.05)
    speed, elapsed = result.trajectory.speed, result.trajectory.t - 40.0
    assert np.all(np.diff(speed) <= 1e-9)
    # Braking ramps up at the 5 m/s³ jerk limit, then holds 4.2 m/s².
    assert speed[-1] < 30.0 - 4.2 * (elapsed[-1] - 1.0) + 1e-6


def test_free_road_prefers_keeping_the_lane_and_accelerating(highway):
    net, _ = highway
    snap = _snapshot([300.0], [-5.25], [20.0], ["hw0_1"])
    result = EpsilonPlanner(net, ParamResolver(), PlannerConfig(desired_speed=30.0)).plan(snap, "v0")
    assert result.policy == "A:KKKKK" and not result.backup
    assert result.agents == 0 and result.scenarios == 1
    assert result.trajectory.speed[-1] > 20.5


def test_shared_prefixes_simulate_like_separate_rollouts(highway):
    """The 9 lateral sequences of an ongoing keep share their first layers: simulated once per distinct prefix
    (1, 3, 5, 7, 9 per layer), every rollout equals its own separate simulation."""
    _, frame = highway
    layers = 5
    sequences = [[CURRENT] * layers]
    for h in range(1, layers):
        sequences += [[CURRENT] * h + [LEFT] * (layers - h), [CURRENT] * h + [RIGHT] * (layers - h)]
    ego_chain = np.array(sequences)
    R = len(sequences)
    # A slower leader in the ego's lane; the neighbour lanes' cars far enough ahead for RSS-safe changes.
    vehicles = _vehicles([100.0, 125.0, 330.0, 350.0], [0.0, 0.0, 3.5, -3.5], [22.0, 18.0, 25.0, 20.0],
                         chain=[CURRENT, CURRENT, LEFT, RIGHT])
    agents = np.tile([0, CURRENT, LEFT, RIGHT], (R, 1))
    rollouts = Rollouts(ego_chain, np.full(R, 25.0), np.ones(R), np.zeros(R, bool), 4.2, agents,
                        np.array([0.0, 18.0, 25.0, 20.0]))
    assert [first.size for first, _, _ in prefix_tree(rollouts)] == [1, 3, 5, 7, 9]
    p = RssParamArrays.stack([RssParams()] * 4)
    durations = (0.6, 1.0, 1.0, 1.0, 1.0)
    together = simulate(frame, vehicles, rollouts, durations, SimSettings(), RssParams(), p)
    for r in range(R):
        single = Rollouts(ego_chain[r:r + 1], np.full(1, 25.0), np.ones(1), np.zeros(1, bool), 4.2, agents[r:r + 1],
                          rollouts.agent_v0)
        alone = simulate(frame, vehicles, single, durations, SimSettings(), RssParams(), p)
        for name in ("s", "d", "heading", "speed", "ego_lead_gap"):
            np.testing.assert_allclose(getattr(together, name)[r], getattr(alone, name)[0], atol=1e-9, rtol=0)
        assert together.valid[r] == alone.valid[0] and np.array_equal(together.chain[r], alone.chain[0])
    # The lane changes do happen in the rollouts that ask for them.
    assert together.d[1, -1, 0] > 1.75 and together.d[2, -1, 0] < -1.75


def test_leader_search_matches_the_pairwise_definition():
    """Sorted leader search = the nearest car whose centre is ahead (within 120 m + its length; the ego's in its
    own lane within 250 m + its length) and inside the follower's band of the lane it looks at (ego radius 2.2 m,
    agents 1.25 m), on random traffic in 3 lanes."""
    rng = np.random.default_rng(7)
    G, n = 12, 15
    lane = rng.integers(0, 3, (G, n))
    s = np.sort(rng.uniform(0.0, 400.0, (G, n)), axis=1)  # spread out: no two cars overlap in a lane
    s = rng.permuted(s + np.arange(n) * 13.0, axis=1)  # the ego (column 0) anywhere in the traffic
    d = (lane - 1) * 3.5 + rng.uniform(-1.5, 1.5, (G, n))
    v = rng.uniform(0.0, 30.0, (G, n))
    length = rng.choice([4.5, 6.0, 12.0], n)
    centres = np.broadcast_to(np.array([-3.5, 0.0, 3.5])[:, None, None], (3, G, n))
    looks = np.stack([rng.integers(0, 3, (G, n)), lane])
    gaps, speeds, leaders = leaders_ahead(s, v, np.abs(d - centres), looks, length, (1.25, 2.2))
    radius = np.where(np.arange(n) == 0, 2.2, 1.25)  # column 0 is the ego
    assert (LEADER_RANGE, EGO_LEADER_RANGE) == (120.0, 250.0)
    for m in range(2):
        for r in range(G):
            for i in range(n):
                ds = s[r] - s[r, i]
                band = np.abs(d[r] - centres[looks[m, r, i], r]) < radius[i]
                reach = 250.0 if i == 0 and looks[m, r, i] == CURRENT else 120.0
                ok = (ds > 0.0) & (ds < reach + length) & band
                if not ok.any():
                    assert np.isinf(gaps[m, r, i]) and leaders[m, r, i] == n
                    continue
                gap = np.where(ok, ds - 0.5 * (length[i] + length), np.inf)
                j = int(np.argmin(gap))
                assert gaps[m, r, i] == pytest.approx(gap[j]) and speeds[m, r, i] == v[r, j]
                assert leaders[m, r, i] == j


def _first_lateral_unsafe(sim, agent, p):
    """Sample index at which the ego (4.5 x 1.8 m, its box rotated by its heading) first becomes laterally
    RSS-unsafe to ``agent`` (1.8 m wide, straight in its lane) (None: never)."""
    d_e, d_a, heading = sim.d[0, :, 0], sim.d[0, :, agent], sim.heading[0, :, 0]
    v_lat = sim.speed[0, :, 0] * np.sin(heading)
    towards = np.where(d_e >= d_a, -v_lat, v_lat)
    lat_min = formulas.combine_lateral(formulas.lateral_reach(towards, p), formulas.lateral_reach(0.0, p),
                                       p.lat_fluctuation_margin, p.lat_fluctuation_margin)
    ego_across = 4.5 * np.abs(np.sin(heading)) + 1.8 * np.cos(heading)
    unsafe = ~formulas.is_safe_distance(np.abs(d_e - d_a) - 0.5 * (ego_across + 1.8), lat_min)
    return int(np.argmax(unsafe)) if unsafe.any() else None


@pytest.mark.parametrize("gap", [60.0, 150.0, 160.0, 180.0, 260.0])
def test_the_ego_enters_a_gap_only_where_the_cut_in_is_rss_safe(highway, gap):
    """RSS's cut-in rule: the ego may make the gap's rear car laterally unsafe only while the pair is
    longitudinally safe; after that the rear car keeps its distance, and the ego is not held half-way.
    Ego at 20 m/s in the middle lane, a car at 30 m/s in the left lane ``gap`` m (bumpers) behind. Under ad_rss
    that car needs 147.0 m behind a 20 m/s ego (30 + 1.75 + 33.5²/8 - 20²/16)."""
    _, frame = highway
    p = RssParams()
    vehicles = _vehicles([200.0, 200.0 - 4.5 - gap], [0.0, 3.5], [20.0, 30.0], chain=[CURRENT, LEFT])
    rollouts = Rollouts(np.array([[CURRENT, LEFT, LEFT, LEFT, LEFT]]), np.array([20.0]), np.ones(1),
                        np.zeros(1, bool), 4.2, np.array([[1, LEFT]]), np.array([0.0, 30.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    onset = _first_lateral_unsafe(sim, 1, p)
    if onset is not None:
        gap_then = sim.s[0, onset, 0] - sim.s[0, onset, 1] - 4.5
        need = formulas.lon_safe_distance_same_dir(sim.speed[0, onset, 1], sim.speed[0, onset, 0], p, p)
        assert gap_then > need
    # The change starts after the first layer (1 s), when the gap is 10 m shorter; it needs 147 m then and
    # 147 m one commit time (1 s, another 10 m) later: a gap >= 167 m now. Smaller gaps only close further.
    entered = sim.d[0, -1, 0] > 1.75
    assert entered == (gap > 167.0)
    assert sim.valid[0]


def test_a_change_under_way_is_not_held_half_way_when_the_rear_car_closes_in(highway):
    """The ego is already moving across at 1 m/s (heading 0.05 rad at 20 m/s), 1 m from its lane's centre:
    laterally unsafe to the left lane's car 100 m behind at 30 m/s, which is now longitudinally unsafe (it needs
    147 m). The pair's duty is longitudinal (the rear car's), so the barrier does not hold the ego there."""
    _, frame = highway
    p = RssParams()
    vehicles = Vehicles(np.array([200.0, 95.5]), np.array([1.0, 3.5]), np.array([0.05, 0.0]), np.array([20.0, 30.0]),
                        np.zeros(2), np.zeros(2), np.full(2, 4.5), np.full(2, 1.8), np.array([CURRENT, LEFT]))
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 30.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    assert _first_lateral_unsafe(sim, 1, p) == 0
    assert sim.barrier_steps[0] == 0 and sim.d[0, -1, 0] > 3.0


@pytest.mark.parametrize("rear_gap", [-2.0, 100.0, 200.0])
def test_the_evasive_speed_up_accelerates_beyond_the_comfort_limit_only_before_an_rss_unsafe_rear_car(highway,
                                                                                                       rear_gap):
    """epsilon.md §3.6: with the gap's rear car RSS-unsafe (100 m behind at 30 m/s; it needs 147 m behind the
    20 m/s ego) the ego speeds up into the gap at up to 2 m/s² (the jerk limit, 3 m/s³, ramps it up), although its
    desired speed is its own speed; beside a safe gap (200 m) it keeps to its 1 m/s² limit and its speed. Also
    with the rear car beside it (a gap of -2 m, below λ: no speed is safe yet; the speed-up was lost when the
    smallest safe speed ahead became +inf there)."""
    _, frame = highway
    p = RssParams()
    vehicles = Vehicles(np.array([200.0, 200.0 - 4.5 - rear_gap]), np.array([1.0, 3.5]), np.array([0.05, 0.0]),
                        np.array([20.0, 30.0]), np.zeros(2), np.zeros(2), np.full(2, 4.5), np.full(2, 1.8),
                        np.array([CURRENT, LEFT]))
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 30.0]))
    settings = SimSettings()
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, settings, p, RssParamArrays.stack([p] * 2))
    peak = float(sim.ego_accel[0].max())
    if rear_gap < 147.0:
        assert settings.ego_limits.max_accel + 0.5 < peak <= settings.evasive_accel + 1e-9
        assert np.allclose(sim.ego_accel[0, 1:4], [0.6, 1.2, 1.8])  # 3 m/s³ over 0.2 s steps
    else:
        assert peak <= settings.ego_limits.max_accel + 1e-9 and sim.speed[0, -1, 0] <= 20.0 + 1e-9


def test_without_the_evasive_speed_up_the_ego_keeps_its_comfort_limit_before_an_rss_unsafe_rear_car(highway):
    """A mandatory change that seeks a gap behind (navigation.seek_speed) turns the speed-up off: the same rear car
    100 m behind at 30 m/s (RSS-unsafe) no longer speeds the 20 m/s ego up beyond its 1 m/s² limit or its desired
    speed, and the barrier still holds it in its lane."""
    _, frame = highway
    p = RssParams()
    vehicles = _vehicles([200.0, 95.5], [0.0, 3.5], [20.0, 30.0], chain=[CURRENT, LEFT])
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 30.0]))
    settings = replace(SimSettings(), evasive_speed_up=False)
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, settings, p, RssParamArrays.stack([p] * 2))
    assert sim.ego_accel[0].max() <= settings.ego_limits.max_accel + 1e-9 and sim.speed[0, -1, 0] <= 20.0 + 1e-9
    assert sim.barrier_steps[0] > 0 and sim.d[0, -1, 0] < 1.5


def _evasive(frame, speed_limit=np.inf, leader_gap=None):
    """The ego at 20 m/s changes left before a 30 m/s car 100 m behind in the target lane (RSS-unsafe: the
    evasive speed-up applies); optionally a 20 m/s car ``leader_gap`` m ahead in the ego's lane."""
    p = RssParams()
    s, d, v, chain = [200.0, 200.0 - 4.5 - 100.0], [0.0, 3.5], [20.0, 30.0], [CURRENT, LEFT]
    if leader_gap is not None:
        s, d, v, chain = s + [200.0 + 4.5 + leader_gap], d + [0.0], v + [20.0], chain + [CURRENT]
    n = len(s)
    vehicles = replace(_vehicles(s, d, v, chain=chain), heading=np.array([0.05] + [0.0] * (n - 1)))
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([chain]), np.array([0.0] + v[1:]), speed_limit)
    return simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * n)), p


def test_the_evasive_speed_up_stays_within_the_speed_limit(highway):
    _, frame = highway
    free, _ = _evasive(frame)
    assert free.speed[0, :, 0].max() > 22.0  # v_low + 10 m/s is far above 22 m/s
    capped, _ = _evasive(frame, speed_limit=22.0)
    assert capped.speed[0, :, 0].max() <= 22.0


def test_the_evasive_speed_up_keeps_the_rss_distance_to_the_leader_in_the_ego_lane(highway):
    """A leader 5 m beyond the RSS distance (ad_rss, 20/20 m/s: 65.78 m): speeding up with IDM's evasive 0.6 s
    headway alone took the ego 15.6 m inside it; the RSS floor of the following distance holds."""
    _, frame = highway
    need = formulas.lon_safe_distance_same_dir(20.0, 20.0, RssParams(), RssParams())
    sim, p = _evasive(frame, leader_gap=float(need) + 5.0)
    gap = sim.s[0, :, 2] - sim.s[0, :, 0] - 4.5
    assert np.all(gap > formulas.lon_safe_distance_same_dir(sim.speed[0, :, 0], sim.speed[0, :, 2], p, p))


def test_a_lawful_cut_in_is_not_charged_when_the_rear_car_closes_in(highway):
    _, frame = highway
    p = RssParams()
    vehicles = _vehicles([200.0, 200.0 - 4.5 - 190.0], [0.0, 3.5], [20.0, 30.0], chain=[CURRENT, LEFT])
    rollouts = Rollouts(np.array([[CURRENT, LEFT, LEFT, LEFT, LEFT]]), np.array([20.0]), np.ones(1),
                        np.zeros(1, bool), 4.2, np.array([[1, LEFT]]), np.array([0.0, 30.0]))
    params = RssParamArrays.stack([p] * 2)
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, params)
    onset = _first_lateral_unsafe(sim, 1, p)
    # Safe at the crossing, unsafe later (the rear car is faster): its duty, not the ego's.
    later_gap = sim.s[0, -1, 0] - sim.s[0, -1, 1] - 4.5
    assert onset is not None and later_gap < formulas.lon_safe_distance_same_dir(sim.speed[0, -1, 1],
                                                                                 sim.speed[0, -1, 0], p, p)
    penalty = rss_penalty(sim, frame, p, params.take(np.array([1])), np.full(2, 4.5), np.full(2, 1.8),
                          CostWeights())
    assert np.all(penalty == 0.0)
    # The same crossing with the rear car 100 m closer is a cut-in: charged from the crossing on.
    closer = replace(sim, s=sim.s + np.array([0.0, 100.0]))
    penalty = rss_penalty(closer, frame, p, params.take(np.array([1])), np.full(2, 4.5), np.full(2, 1.8),
                          CostWeights())
    assert np.all(penalty[0, :onset] == 0.0) and np.all(penalty[0, onset:] > 0.0)


def test_a_car_that_cuts_in_behind_an_ego_keeping_its_lane_is_not_charged_to_the_ego(highway):
    """A 25 m/s car 20 m behind in the right lane changes into the lane of the 20 m/s ego (RSS's lateral trigger,
    far inside the longitudinal distance). The ego keeps its lane, so it meets its lateral response and the
    cut-in is the other car's duty (rss.md §5): no charge. The same car cutting in behind an ego that itself
    moves towards it at 0.5 m/s (the ego is offset and heads into the right lane) is charged."""
    _, frame = highway
    p = RssParams()
    params = RssParamArrays.stack([p] * 2)
    vehicles = _vehicles([200.0, 200.0 - 4.5 - 20.0], [0.0, -3.5], [20.0, 25.0], chain=[CURRENT, RIGHT])
    rollouts = Rollouts(np.full((1, 5), CURRENT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, CURRENT]]), np.array([0.0, 25.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, params)
    assert _first_lateral_unsafe(sim, 1, p) is not None and np.all(sim.d[0, :, 0] == 0.0)
    args = (frame, p, params.take(np.array([1])), np.full(2, 4.5), np.full(2, 1.8), CostWeights())
    assert np.all(rss_penalty(sim, *args) == 0.0)
    towards = replace(sim, heading=sim.heading - np.array([0.025, 0.0]))  # 20 m/s x sin(0.025) ≈ 0.5 m/s
    assert np.any(rss_penalty(towards, *args) > 0.0)


@pytest.mark.parametrize("towards, unsafe_until, breaks", [
    (np.zeros(26), 5.0, False),  # keeps its lane
    (np.full(26, 0.5), 5.0, True),  # goes on at 0.5 m/s: above 0.7 - 0.8(τ - 1) + 0.05τ from τ = 4/3 s
    (np.full(26, 0.5), 1.2, False),  # ... but the pair is safe again before that
    (np.maximum(0.5 - 0.8 * np.maximum(np.arange(26) * 0.2 - 1.0, 0.0), 0.0), 5.0, False),  # brakes at b_lat
])
def test_the_lateral_response_is_judged_as_the_auditor_does(towards, unsafe_until, breaks):
    """ad_rss: ρ 1 s, a_lat 0.2, b_lat 0.8 m/s²; trigger at t = 0, samples every 0.2 s."""
    t = np.arange(26) * 0.2
    unsafe = (t <= unsafe_until + 1e-9)[None, :]
    assert breaks_lateral_response(t, np.array([0]), towards[None, :], unsafe, RssParams()).tolist() == [breaks]


def test_the_leader_cost_reads_the_gap_less_the_rss_distance_in_excess_of_the_idm_headway():
    """Under ad_rss an ego at 20 m/s behind an 18 m/s car that brakes at up to 10 m/s² needs
    20 + 1.75 + 23.5²/8 - 18²/20 = 74.58125 m; IDM's headway is 1 s x 20 m/s, so a 75 m gap reads as
    75 - 54.58125 m. The hardest-braking agent (10 of 6 and 10 m/s²) is the leader, as in the simulation."""
    ego = RssParams()
    agents = RssParamArrays.stack([replace(ego, lon_brake_max=6.0), replace(ego, lon_brake_max=10.0)])
    gap = np.array([75.0, np.inf, 75.0])
    v, v_lead = np.array([20.0, 20.0, 5.0]), np.array([18.0, 20.0, 20.0])
    read = leader_gap_for_cost(gap, v, v_lead, ego, agents, 1.0)
    # A slow ego behind a fast leader needs less than v·T (5 m): the gap is read as it is; so is no leader.
    assert read == pytest.approx([75.0 - 54.58125, np.inf, 75.0], abs=1e-9)
    assert np.array_equal(leader_gap_for_cost(gap, v, v_lead, ego, agents, None), gap)


def test_a_car_beside_a_bending_ramp_stays_in_its_lane():
    """The merge ramp bends (by 12° and 4°) where the straight motorway runs beside it. In the ramp's frame the
    motorway lane bends there too; a motorway car keeping its lane must follow it, not drift across (aiming at
    the lane beyond the bend, it cut the bend and crossed 3 m into the ramp's lane, and every ego policy
    'collided' with it)."""
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    frame = RoadFrame.build(lane_chains(net, int(net.lane_indices(["ramp_0"])[0]),
                                        net.edge_indices(["ramp", "mw_merge", "mw_out"])))
    x0, y0 = 530.0, -5.25  # on mw_in_0, driving east at 25 m/s, 70 m before the ramp's second bend
    s, d, rel = frame.to_frame(np.array([x0]), np.array([y0]), np.array([0.0]))
    vehicles = Vehicles(np.array([100.0, s[0]]), np.array([0.0, d[0]]), np.array([0.0, rel[0]]),
                        np.array([10.0, 25.0]), np.zeros(2), np.zeros(2), np.full(2, 4.5), np.full(2, 1.8),
                        np.array([CURRENT, LEFT]))
    p = RssParamArrays.stack([RssParams()] * 2)
    rollouts = _keep(1, 2, layers=8, v0=10.0, chains=np.array([[CURRENT, LEFT]]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 8, SimSettings(), RssParams(), p)
    s_a, d_a = sim.s[0, :, 1], sim.d[0, :, 1]
    assert s_a[0] < 319.0 - 50.0 and s_a[-1] > 391.0 + 10.0  # it passes the bend and the ramp's end
    np.testing.assert_allclose(d_a, frame.centre_d(LEFT, s_a), atol=0.25)
    # ... and in the world it keeps driving along y = -5.25.
    _, y, _ = frame.to_world(s_a, d_a, sim.heading[0, :, 1])
    np.testing.assert_allclose(y, y0, atol=0.25)


@pytest.mark.parametrize("rss_following", [True, False])
def test_the_ego_follows_a_car_at_no_less_than_the_rss_distance(highway, rss_following):
    """The ego at 25 m/s, 110 m (bumper gap 105.5 m) behind a car at 22 m/s, desired speed 30 m/s, 8 s of
    keep-lane. Its IDM keeps at least the RSS safe distance to the car (ad_rss: 25 + 1.75 + 28.5²/8 − 22²/16 =
    98.03 m at these speeds): it slows down and follows without ever being RSS-unsafe. With IDM's 1 s headway
    alone it closes in and becomes RSS-unsafe."""
    _, frame = highway
    vehicles = _vehicles([100.0, 210.0], [0.0, 0.0], [25.0, 22.0])
    p = RssParamArrays.stack([RssParams()] * 2)
    rollouts = _keep(1, 2, layers=8, v0=30.0)
    rollouts = replace(rollouts, agent_v0=np.array([0.0, 22.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 8, SimSettings(rss_following=rss_following), RssParams(), p)
    gap = sim.s[0, :, 1] - sim.s[0, :, 0] - 4.5
    d_min = formulas.lon_safe_distance_same_dir(sim.speed[0, :, 0], sim.speed[0, :, 1], RssParams(), RssParams())
    assert float(d_min[0]) == pytest.approx(98.03125, abs=1e-9)
    if rss_following:
        assert np.all(gap > d_min)
        assert gap[-1] - d_min[-1] < 15.0  # it follows at about the RSS distance, not far behind it
    else:
        assert np.any(gap < d_min)


def test_a_stop_line_is_approached_with_the_idm_not_held_at_an_rss_distance(highway):
    """The RSS distance applies to cars: a stop line 60 m ahead of the ego's front bumper (15 m/s) is a standing
    obstacle the ego stops just before (IDM s0 = 2 m), not one it stays D_rss(15) = 59.5 m away from."""
    _, frame = highway
    vehicles = _vehicles([100.0, 400.0], [0.0, 0.0], [15.0, 25.0])
    p = RssParamArrays.stack([RssParams()] * 2)
    rollouts = replace(_keep(1, 2, layers=10, v0=20.0), agent_v0=np.array([0.0, 25.0]))
    stop_s = 100.0 + 2.25 + 60.0
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 10, SimSettings(), RssParams(), p, ego_stop_s=stop_s)
    front = sim.s[0, :, 0] + 2.25
    assert front.max() <= stop_s and front[-1] > stop_s - 5.0 and sim.speed[0, -1, 0] < 1.0


@pytest.mark.parametrize("beyond", [0.5, 2.0, 10.0])
def test_before_a_junction_the_ego_stays_able_to_stop_ahead_of_its_conflict_area(highway, beyond):
    """A stop line 80 m ahead of the ego's front bumper (15 m/s) and the junction's first conflict area ``beyond``
    m past it. ad_rss: D(v) = v + 1.75 + (v + 3.5)²/8 m (ρ 1 s, a_acc 3.5, b_min 4), D(0) = 3.28 m. All the way,
    the ego's distance to the area stays above D(v) (rss.md §4's able-to-stop, which a car creeping up to the line
    broke: every creep was a danger episode with the crossing traffic). It comes to rest IDM's s0 = 2 m short of
    D(0) + the stop point's own margin, and never past the stop point."""
    _, frame = highway
    vehicles = _vehicles([100.0, 400.0], [0.0, 0.0], [15.0, 25.0])
    p = RssParams()
    rollouts = replace(_keep(1, 2, layers=16, v0=20.0), agent_v0=np.array([0.0, 25.0]))
    stop_s = 100.0 + 2.25 + 80.0
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 16, SimSettings(), p, RssParamArrays.stack([p] * 2),
                   ego_stop_s=stop_s, junction_area=JunctionArea(beyond, RssParamArrays.stack([p])))
    front, v = sim.s[0, :, 0] + 2.25, sim.speed[0, :, 0]
    to_area = stop_s + beyond - front
    assert np.all(to_area > v + 1.75 + (v + 3.5) ** 2 / 8.0)
    assert front.max() <= stop_s and v[-1] < 0.1
    rest = max(2.0 + 1.75 + 3.5 ** 2 / 8.0 - beyond, 2.0)  # s0 + max(D(0) − beyond, 0) before the stop point
    assert stop_s - front[-1] == pytest.approx(rest, abs=0.5)


def test_each_layer_ends_with_the_leader_on_the_lane_that_layer_tracked(highway):
    """The ego at 20 m/s in the middle lane with nothing ahead; a 12 m/s car 150 m ahead in the left lane. KKKKL
    changes left only in its last layer, so at the end of layers 1-4 it has no leader, as KKKKK (the sample that
    ends a layer is also the first of the next: it read the next layer's lane, the left car, 113.5 m ahead)."""
    _, frame = highway
    vehicles = _vehicles([100.0, 250.0], [0.0, 3.5], [20.0, 12.0], chain=[CURRENT, LEFT])
    rollouts = Rollouts(np.array([[CURRENT] * 5, [CURRENT] * 4 + [LEFT]]), np.full(2, 20.0), np.ones(2),
                        np.zeros(2, dtype=bool), 4.2, np.array([[CURRENT, LEFT]] * 2), np.array([0.0, 12.0]))
    p = RssParams()
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    ends = sim.layer_end
    assert np.isinf(sim.ego_lead_gap[:, ends[:4]]).all()
    assert np.isfinite(sim.ego_lead_gap[1, ends[4]]) and np.isinf(sim.ego_lead_gap[0, ends[4]])
    assert sim.ego_lead_is_car[1, ends[4]]
    # Within the last layer KKKKL looks at the left lane from its first sample on.
    assert np.isfinite(sim.ego_lead_gap[1, ends[3] + 1])


def test_a_stop_line_ahead_is_not_read_as_a_car_by_the_leader_cost(highway):
    """A stop line 100 m ahead of an ego at 15 m/s and no car: the simulation approaches it with the plain IDM, so
    the leader cost reads the gap as it is (with the RSS-following correction it read 55.5 m)."""
    _, frame = highway
    vehicles = _vehicles([100.0], [0.0], [15.0])
    p = RssParams()
    sim = simulate(frame, vehicles, _keep(1, 1), (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p]),
                   ego_stop_s=100.0 + 2.25 + 100.0)
    assert sim.ego_lead_gap[0, 0] == pytest.approx(100.0) and not sim.ego_lead_is_car[0, 0]
    agents = RssParamArrays.stack([p])
    read = leader_gap_for_cost(sim.ego_lead_gap[:, :1], sim.speed[:, :1, 0], sim.ego_lead_speed[:, :1], p, agents,
                               1.0, is_car=sim.ego_lead_is_car[:, :1])
    assert read[0, 0] == pytest.approx(100.0)
    assert leader_gap_for_cost(np.array([100.0]), np.array([15.0]), np.array([0.0]), p, agents, 1.0)[0] < 60.0


def test_the_mpdm_baseline_simulates_4_s_in_0_4_s_steps():
    """epsilon.md §8: MPDM's horizon is 4.0 s at 0.4 s steps (1 s layers at 0.4 s were cut into 0.333 s steps)."""
    config = PlannerConfig.mpdm(25.0)
    t, ends = step_times((config.layer_duration,) * config.layers, config.sim_step)
    np.testing.assert_allclose(np.diff(t), 0.4)
    assert t[-1] == pytest.approx(4.0) and ends[-1] == 10


def test_a_standing_ego_does_not_creep_into_the_rss_distance_with_hold_standing(highway):
    """With ``hold_standing`` a standing car is not assumed to accelerate during ρ, so standing 3 m behind a
    stopped car is RSS-safe. A plan that moves the ego is judged as moving (a_acc = 3.5 m/s²: d_min 3.28 m from
    rest at ad_rss values): it must not creep closer. It pulsed forward about once a second in the queues of
    intersection_priority, opening a new danger episode each time."""
    net, _ = highway
    snap = _snapshot([300.0, 307.5], [-5.25, -5.25], [0.0, 0.0], ["hw0_1", "hw0_1"])  # a 3.0 m bumper gap
    planner = EpsilonPlanner(net, ParamResolver("ad_rss", hold_standing=True), PlannerConfig(desired_speed=30.0))
    result = planner.plan(snap, "v0")
    assert result.trajectory.speed.max() < 0.01
    assert result.trajectory.x[-1] - result.trajectory.x[0] < 0.01


def test_the_motion_layer_starts_from_the_measured_acceleration_not_the_behaviour_layers_clipped_one(highway):
    """The forward simulation starts the ego at its measured acceleration clipped to its own [−5, 1] m/s²; the
    motion layer starts from the measured 1.5 m/s² itself (docs/motion.md, Inputs)."""
    net, _ = highway
    snap = _snapshot([300.0], [-5.25], [20.0], ["hw0_1"])
    snap.accel[0] = 1.5
    result = EpsilonPlanner(net, ParamResolver(), PlannerConfig(desired_speed=30.0)).plan(snap, "v0")
    assert result.frenet.s_ddot[0] == pytest.approx(1.5, abs=1e-6)


def test_the_mpdm_baseline_steps_its_speed_command_by_at_most_5_m_s_both_ways(highway):
    """epsilon.md §8: the commanded-speed step is capped at ±5 m/s. Alone at 30 m/s with a desired 10 m/s, the
    command was 10 (only the step up was capped) and the ego braked below 25 m/s within the 4 s; with 25 m/s it
    stays above 25."""
    net, _ = highway
    snap = _snapshot([300.0], [-5.25], [30.0], ["hw0_1"])
    result = EpsilonPlanner(net, ParamResolver(), PlannerConfig.mpdm(10.0)).plan(snap, "v0")
    speed = result.trajectory.speed
    assert speed.min() >= 25.0 - 1e-9 and speed[-1] < 29.0


def test_the_followed_trajectory_moves_as_fast_as_its_speeds_between_the_simulation_samples(highway):
    """The executed trajectory is sampled every 0.1 s from the forward simulation's 0.4 s (MPDM) samples: positions
    interpolated linearly moved at the mean speed of each 0.4 s while the speeds changed within it, off by
    ½·a·t·(Δt − t) (a braking MPDM ego: 0.35 m/s of placement against its speed)."""
    net, _ = highway
    snap = _snapshot([300.0], [-5.25], [30.0], ["hw0_1"])
    traj = EpsilonPlanner(net, ParamResolver(), PlannerConfig.mpdm(20.0)).plan(snap, "v0").trajectory
    moved = np.diff(traj.x) / np.diff(traj.t)  # hw0 runs along +x
    np.testing.assert_allclose(moved, 0.5 * (traj.speed[1:] + traj.speed[:-1]), atol=2e-3)
    assert np.ptp(np.diff(traj.speed)) > 0.05  # the speed does change within the samples


@pytest.mark.parametrize("max_accel", [1.0, 2.0])
def test_a_standing_egos_lane_change_starts_at_its_own_acceleration_limit(highway, max_accel):
    """A standing ego (at a lane's end) whose gap has come, a car at 25 m/s just past it in the left lane and the
    next one 200 m behind (a standing ego needs d_min(25, 0) = 128.3 m, and 25 m more for the barrier's 1 s):
    in the lane-change layers it accelerates at its own limit, not at the gap controller's 1 m/s² (epsilon.md
    §3.5's clip), and so crosses the lane boundary sooner (docs/planner.md, "A standing ego's start")."""
    _, frame = highway
    p = RssParams()
    vehicles = _vehicles([200.0, 235.0, 200.0 - 4.5 - 200.0], [0.0, 3.5, 3.5], [0.0, 25.0, 25.0],
                         chain=[CURRENT, LEFT, LEFT])
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([10.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT, LEFT]]), np.array([0.0, 25.0, 25.0]))
    settings = replace(SimSettings(), ego_idm=replace(SimSettings().ego_idm, accel=max_accel),
                       ego_limits=replace(SimSettings().ego_limits, max_accel=max_accel))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, settings, p, RssParamArrays.stack([p] * 3))
    assert sim.valid[0] and sim.barrier_steps[0] == 0
    start = sim.ego_accel[0, sim.t <= 2.0]  # before the rear car comes within its RSS distance (evasive speed-up)
    assert max_accel - 0.05 <= float(start.max()) <= max_accel + 1e-9
    across = float(sim.t[int(np.argmax(sim.d[0, :, 0] > 1.75))])
    assert across <= (3.6 if max_accel == 1.0 else 3.0)


def test_a_held_merge_waits_ready_beside_its_gap_laterally_safe():
    """On the acceleration lane (it ends, so the change is mandatory) beside a lane-1 car 10 m behind at 25 m/s
    (RSS-unsafe: the barrier holds the ego), the ego at 15 m/s moves towards lane 1 as far as it stays laterally
    RSS-safe to that car and out of the lane's band in which the agents see it in their way, ~1.1 m, and no
    further; before, it kept its lane's centre, ~1.6 s from standstill away from the lateral trigger
    (lane_change.ready_offset)."""
    net = RoadNetwork.from_file(NETWORKS / "merge" / "merge.net.xml")
    frame = RoadFrame.build(lane_chains(net, int(net.lane_indices(["ramp_0"])[0]),
                                        net.edge_indices(["ramp", "mw_merge", "mw_out"])))
    s, d, rel = frame.to_frame(np.array([800.0, 785.5]), np.array([-8.75, -5.25]), np.zeros(2))
    vehicles = Vehicles(s, d, rel, np.array([15.0, 25.0]), np.zeros(2), np.zeros(2), np.full(2, 4.5),
                        np.full(2, 1.8), np.array([CURRENT, LEFT]))
    p = RssParams()
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([15.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 25.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, replace(SimSettings(), ready_wait=True), p,
                   RssParamArrays.stack([p] * 2))
    across = sim.d[0, :, 0] - frame.centre_d(CURRENT, sim.s[0, :, 0])
    assert sim.barrier_steps[0] > 0 and 0.8 < across.max() < 1.3
    onset = _first_lateral_unsafe(sim, 1, p)  # once the car is by and far enough ahead the change goes on
    if onset is not None:
        v_e, v_a = sim.speed[0, onset, 0], sim.speed[0, onset, 1]
        gap = sim.s[0, onset, 1] - sim.s[0, onset, 0] - 4.5
        assert gap > 0.0 and gap >= formulas.lon_safe_distance_same_dir(v_e, v_a, p, p)
