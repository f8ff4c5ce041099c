"""The cost beyond the planning horizon (docs/planner.md "Cost weights"): the release's efficiency and leader costs
of the speed the ego's end lane holds it to, over further discounted layers. On the straight part of the highway
net (the frame around hw0_1; the left lane hw0_2 3.5 m to the left)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sumo_rss.planner.behavior.cost_weights import CostWeights
from sumo_rss.planner.behavior.evaluation import beyond_horizon_cost
from sumo_rss.planner.behavior.forward_sim import Rollouts, SimSettings, Vehicles, simulate
from sumo_rss.planner.lanes import CURRENT, LEFT
from sumo_rss.rss.params import RssParamArrays, RssParams

V_REF, V_SLOW = 33.0, 25.0  # [m/s]
TAIL = CostWeights()  # the default: 5 s beyond the horizon
GAMMA_TAIL = sum(0.7 ** i for i in range(5, 10))  # layers 6-10 of 1 s: 0.4656...


def _behind_a_slow_car(frame):
    """The ego at 25 m/s 60 m (bumper gap) behind a 25 m/s car in its lane, the left lane free; rollouts: keep,
    and a change left from the second layer on (K L L L L)."""
    vehicles = Vehicles(np.array([200.0, 264.5]), np.zeros(2), np.zeros(2), np.full(2, V_SLOW), np.zeros(2),
                        np.zeros(2), np.full(2, 4.5), np.full(2, 1.8), np.array([CURRENT, CURRENT]))
    ego_chain = np.array([[CURRENT] * 5, [CURRENT] + [LEFT] * 4])
    rollouts = Rollouts(ego_chain, np.full(2, V_REF), np.ones(2), np.zeros(2, dtype=bool), 4.2,
                        np.full((2, 2), CURRENT), np.array([0.0, V_SLOW]))
    p = RssParams()
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    return sim, ego_chain[:, -1]


def test_keeping_behind_a_slow_car_costs_its_speed_beyond_the_horizon_and_the_free_lane_nothing(highway):
    """Keeping: (0.3·(33 − 25) + max(0.4, (120 − gap)/120)·0.1·(33 − 25))/2 per layer, weighted
    Σ 0.7^5..0.7^9; the change left ends in the free lane at any speed: nothing."""
    _, frame = highway
    sim, end_chain = _behind_a_slow_car(frame)
    assert sim.chain[1, -1, 0] == LEFT and np.isinf(sim.ego_lead_gap[1, -1])
    gap = sim.ego_lead_gap[:, -1]
    tail = beyond_horizon_cost(sim, end_chain, gap, V_REF, TAIL, 1.0)
    lead_ratio = max(0.4, (120.0 - gap[0]) / 120.0)
    assert tail[0] == pytest.approx(GAMMA_TAIL * 0.5 * (0.3 * 8.0 + lead_ratio * 0.1 * 8.0), rel=1e-12)
    assert tail[1] == 0.0
    release = CostWeights(beyond_horizon=0.0)  # epsilon.md §4.2: no tail
    assert np.all(beyond_horizon_cost(sim, end_chain, gap, V_REF, release, 1.0) == 0.0)


def test_a_change_still_short_of_its_lane_at_the_horizon_is_taken_on_at_its_end_speed(highway):
    """The same change held in its lane (say by the virtual barrier) gains nothing it has not reached: it goes on
    at its end speed, and pays that speed's deficit beyond the horizon (no leader cost: none in its target lane)."""
    _, frame = highway
    sim, end_chain = _behind_a_slow_car(frame)
    held = replace(sim, chain=np.where(np.arange(2)[:, None, None] == 1, CURRENT, sim.chain))
    v_end = float(held.speed[1, -1, 0])
    assert v_end < V_REF
    tail = beyond_horizon_cost(held, end_chain, held.ego_lead_gap[:, -1], V_REF, TAIL, 1.0)
    assert tail[1] == pytest.approx(GAMMA_TAIL * 0.5 * 0.3 * (V_REF - v_end), rel=1e-12)
