"""CFB scenario branching on crafted intention probabilities (columns: keep, left, right)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from sumo_rss.planner.behavior.cfb import branch_scenarios, uncertain_agents

PROBS = np.array([[0.90, 0.05, 0.05],   # agent 0: confident keep
                  [0.50, 0.40, 0.10],   # agent 1: keep or left
                  [0.30, 0.10, 0.60],   # agent 2: right or keep
                  [0.05, 0.90, 0.05]])  # agent 3: confident left


def test_uncertain_agents_are_those_with_close_top_two():
    assert uncertain_agents(PROBS).tolist() == [False, True, False, False]  # 0.5 vs 0.4; 0.6 vs 0.3 is 0.3 apart


def test_top_k_combinations_with_renormalised_weights():
    branched = np.array([False, True, True, False])
    s = branch_scenarios(PROBS, branched, k=4)
    # Combinations of agents 1 and 2: (keep, right) 0.30, (left, right) 0.24, (keep, keep) 0.15, (left, keep) 0.12.
    assert s.intentions.tolist() == [[0, 0, 2, 1], [0, 1, 2, 1], [0, 0, 0, 1], [0, 1, 0, 1]]
    total = 0.30 + 0.24 + 0.15 + 0.12
    np.testing.assert_allclose(s.weights, [0.30 / total, 0.24 / total, 0.15 / total, 0.12 / total])
    assert s.weights.sum() == pytest.approx(1.0)


def test_unbranched_agents_keep_their_map_intention_and_one_scenario_without_branching():
    s = branch_scenarios(PROBS, np.zeros(4, dtype=bool))
    assert s.intentions.tolist() == [[0, 0, 2, 1]] and s.weights.tolist() == [1.0]
    s = branch_scenarios(PROBS, np.array([False, True, False, False]), k=2)
    assert s.intentions.tolist() == [[0, 0, 2, 1], [0, 1, 2, 1]]
    np.testing.assert_allclose(s.weights, [0.5 / 0.9, 0.4 / 0.9])


def test_rule_based_belief_matches_the_one_hot_rule_far_from_its_thresholds():
    from sumo_rss.planner.behavior.intention import intention_probabilities

    p = intention_probabilities(offset=[0.0, 1.0, -1.0, 1.0, 1.0], lat_speed=[0.0, 1.0, -1.0, 1.0, -1.0],
                                has_left=[True, True, True, False, True], has_right=[True, True, True, True, True])
    assert np.argmax(p, axis=1).tolist() == [0, 1, 2, 0, 0]  # keep; left; right; no left lane; drifting back
    assert p[1, 1] > 0.95 and p[2, 2] > 0.95 and p[3, 1] == 0.0
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    # Well past the offset threshold (1.2 m), at the speed threshold 0.35 m/s, keep and left are equally likely;
    # at both thresholds the left probability is 0.5 · 0.5 (both conditions must hold).
    mid = intention_probabilities([1.2], [0.35], [True], [True])
    assert mid[0, 0] == pytest.approx(mid[0, 1], abs=0.02)
    assert intention_probabilities([0.4], [0.35], [True], [True])[0, 1] == pytest.approx(0.25)


def test_a_car_whose_lane_ends_leans_towards_the_lane_that_goes_on():
    from sumo_rss.planner.behavior.intention import LANE_END_NOTICE, rule_belief

    # Centred cars 50 m before their lane's end: urgency 1 − 50/200 = 0.75 moves towards the neighbour that exists
    # (the left one where both do); a lane without neighbours or without an end keeps its belief.
    p = rule_belief([0.0] * 4, [0.0] * 4, [True, False, False, True], [True, True, False, True],
                    [50.0, 50.0, 50.0, np.inf])
    keep = rule_belief([0.0], [0.0], [True], [True], [np.inf])[0, 0]
    urgency = 1.0 - 50.0 / LANE_END_NOTICE
    assert p[0, 1] == pytest.approx(urgency + (1.0 - urgency) * p[3, 1])
    assert p[1, 2] == pytest.approx(urgency + (1.0 - urgency) * (1.0 - keep) / 2.0) and p[1, 1] == 0.0
    assert p[2, 0] == pytest.approx(1.0)
    np.testing.assert_allclose(p.sum(axis=1), 1.0)


def _enumerated(probabilities, branched, k):
    """Every combination of the branched agents, ranked by probability then combination order (the reference)."""
    idx = np.flatnonzero(branched)
    combos = np.array(list(itertools.product(range(3), repeat=idx.size)), dtype=int)
    p = np.prod(probabilities[idx[None, :], combos], axis=1)
    order = [c for c in np.argsort(-p, kind="stable") if p[c] > 0.0][:k]
    return combos[order], p[order] / p[order].sum()


@pytest.mark.parametrize("seed", range(12))
def test_top_k_agrees_with_ranking_every_combination_ties_included(seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 8))
    # Probabilities on a coarse grid (ties between combinations are common), some zero.
    raw = rng.integers(0, 4, size=(m + 2, 3)).astype(float)
    raw[raw.sum(axis=1) == 0, 0] = 1.0
    probabilities = raw / raw.sum(axis=1, keepdims=True)
    branched = np.zeros(m + 2, dtype=bool)
    branched[rng.choice(m + 2, size=m, replace=False)] = True
    k = int(rng.integers(1, 7))
    scenarios = branch_scenarios(probabilities, branched, k)
    combos, weights = _enumerated(probabilities, branched, k)
    assert scenarios.intentions[:, branched].tolist() == combos.tolist()
    np.testing.assert_allclose(scenarios.weights, weights, rtol=1e-12)


def test_many_branched_agents_keep_the_top_k_without_enumerating_3_to_the_m():
    """40 uncertain agents (3^40 combinations): the best is every agent's MAP intention, the next ones swap the
    agent with the closest second choice."""
    probabilities = np.tile([0.5, 0.3, 0.2], (40, 1))
    probabilities[7] = [0.45, 0.44, 0.11]
    scenarios = branch_scenarios(probabilities, np.ones(40, dtype=bool), k=3)
    assert scenarios.intentions[0].tolist() == [0] * 40
    second = [0] * 40
    second[7] = 1
    assert scenarios.intentions[1].tolist() == second
    np.testing.assert_allclose(scenarios.weights[:2] / scenarios.weights[0], [1.0, 0.44 / 0.45])
