"""Candidate centrelines and past trajectories of the intention estimator, on the real networks."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.planner.intention.features import (BLINKER_LEFT, BLINKER_RIGHT, HISTORY_STEPS, KEEP, LANE_ARCS, LEFT,
                                                 RIGHT, CandidateFinder, distance_to_candidates,
                                                 history_in_agent_frame)
from sumo_rss.road.network import RoadNetwork
from sumo_rss.scenario import networks_root


def _net(name: str) -> RoadNetwork:
    return RoadNetwork.from_file(networks_root() / name / f"{name}.net.xml")


def _on_lane(net: RoadNetwork, lane_id: str, s: float) -> tuple[int, float, float, float]:
    """(lane index, x, y, heading) of a point s metres along the first segment of a straight lane."""
    k = int(net.lane_indices(np.array([lane_id]))[0])
    a, b = net.shapes.points[k, 0], net.shapes.points[k, 1]
    u = (b - a) / np.linalg.norm(b - a)
    p = a + s * u
    return k, float(p[0]), float(p[1]), float(np.arctan2(u[1], u[0]))


def _candidates(net: RoadNetwork, lane_id: str, s: float):
    k, x, y, h = _on_lane(net, lane_id, s)
    return CandidateFinder(net).candidates(np.array([k]), np.array([x]), np.array([y]), np.array([h]))


def test_an_acceleration_lane_has_keep_and_left_and_its_end_is_flagged():
    net = _net("merge")
    length = float(net.lane_length[net.lane_indices(np.array(["mw_merge_0"]))[0]])
    cand = _candidates(net, "mw_merge_0", 200.0)
    assert cand.mask[0].tolist() == [True, True, False, False, False, False]
    assert cand.lateral[0, :2].tolist() == [KEEP, LEFT]
    assert cand.to_lane_end[0] == pytest.approx(length - 200.0, abs=0.5)
    beyond = cand.lanes[0, 0, :, 2] == 1.0
    assert np.array_equal(beyond, LANE_ARCS > length - 200.0 + 1e-6)  # the keep lane stops where the lane ends
    assert not cand.lanes[0, 1, :, 2].any()  # the motorway goes on
    widths = net.lane_width[net.lane_indices(np.array(["mw_merge_0", "mw_merge_1"]))]
    assert cand.lanes[0, 1, 0, 1] == pytest.approx(widths.mean(), abs=0.05)  # one lane to the left


def test_a_junction_approach_has_one_keep_candidate_per_turn_straightest_first():
    net = _net("intersection_priority")
    cand = _candidates(net, "E_in_0", 200.0)  # ~93 m before the junction: every turn is in range
    assert cand.mask[0].sum() == 3 and cand.lateral[0, :3].tolist() == [KEEP, KEEP, KEEP]
    end = cand.lanes[0, :3, -1, :2]
    assert end[0] == pytest.approx([128.0, 0.0], abs=0.5)  # straight on, 128 m ahead in the agent frame
    assert {np.sign(end[1, 1]), np.sign(end[2, 1])} == {-1.0, 1.0}  # a right and a left turn
    assert np.isinf(cand.to_lane_end[0])


def test_far_from_the_junction_the_turns_coincide_and_are_one_candidate():
    cand = _candidates(_net("intersection_tls"), "N_in_0", 20.0)
    assert cand.lateral[0][cand.mask[0]].tolist() == [KEEP, LEFT]


def test_a_middle_highway_lane_has_keep_left_and_right_at_one_lane_width():
    cand = _candidates(_net("highway"), "hw0_1", 100.0)
    assert cand.lateral[0][cand.mask[0]].tolist() == [KEEP, LEFT, RIGHT]
    assert cand.lanes[0, :3, 35, 1] == pytest.approx([0.0, 3.5, -3.5], abs=0.3)
    assert cand.lanes[0, 0, :, 0] == pytest.approx(LANE_ARCS, abs=1e-6)


def test_labels_go_to_the_nearest_candidate():
    cand = _candidates(_net("highway"), "hw0_1", 100.0)
    k, x, y, h = _on_lane(_net("highway"), "hw0_1", 160.0)
    left = np.array([x - 3.5 * np.sin(h), y + 3.5 * np.cos(h)])  # 60 m ahead, one lane to the left
    dist = distance_to_candidates(cand.world, cand.mask, left[None, 0], left[None, 1])
    assert np.argmin(dist[0]) == 1 and dist[0, 1] < 0.3 and np.isinf(dist[0, 3])


def test_history_is_in_the_agent_frame_with_the_blinkers():
    t = np.arange(HISTORY_STEPS) * 0.2
    px, py = 10.0 + 0.0 * t, 5.0 - 10.0 * (2.0 - t)  # driving north at 10 m/s, now at (10, 5)
    signals = np.zeros((1, HISTORY_STEPS), dtype=int)
    signals[0, -3:] = BLINKER_LEFT | 8  # the left blinker for the last 0.4 s (and a brake light, ignored)
    signals[0, 0] = BLINKER_RIGHT
    hist = history_in_agent_frame(px[None], py[None], signals, np.array([10.0]), np.array([5.0]),
                                  np.array([np.pi / 2]))
    assert hist[0, -1] == pytest.approx([0.0, 0.0, 0.0, 1.0])
    assert hist[0, 0] == pytest.approx([-20.0, 0.0, 1.0, 0.0])  # 20 m straight behind
    assert hist[0, 1:-3, 2:].sum() == 0.0
