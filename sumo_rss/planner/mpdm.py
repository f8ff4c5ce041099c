"""Cost of the MPDM baseline (epsilon.md §8): lane-change cost, box-proximity safety, efficiency.

MPDM simulates 3 lateral policies (keep, left, right) at a constant speed command in one scenario; its cost per
policy is 0.5 for a lane change, plus per step 0.01·|Δv|·0.5 for every agent whose box, inflated by 1 m, touches
the ego's, plus 0.5·(|v_T − v_ref|/10 + 1.5·ratio·|v_T − v_ref|/max(2, gap)) at the end, ratio being how close
the leader is (1 − gap/120). Units: m, s, m/s.
"""
from __future__ import annotations

import numpy as np

from .behavior.dcp_tree import Lat, Policy
from .behavior.evaluation import Evaluation
from ..boxes import boxes_overlap
from .behavior.forward_sim import SimResult, Vehicles
from .behavior.leaders import LEADER_RANGE

LANE_CHANGE_COST = 0.5
SAFETY_INFLATION = 1.0  # [m]
SAFETY_WEIGHT = 0.01 * 0.5
EFFICIENCY_WEIGHT = 0.5


def mpdm_costs(sim: SimResult, policies: list[Policy], policy_of: np.ndarray, weight_of: np.ndarray, v_ref: float,
               vehicles: Vehicles) -> Evaluation:
    L, W = vehicles.length, vehicles.width
    near = boxes_overlap(sim.s[..., :1], sim.d[..., :1], sim.heading[..., :1], L[0] + SAFETY_INFLATION,
                         W[0] + SAFETY_INFLATION, sim.s[..., 1:], sim.d[..., 1:], sim.heading[..., 1:],
                         L[1:] + SAFETY_INFLATION, W[1:] + SAFETY_INFLATION)
    dv = np.abs(sim.speed[..., :1] - sim.speed[..., 1:])
    safety = SAFETY_WEIGHT * np.where(near, dv, 0.0).sum(axis=(1, 2))
    v_end = sim.speed[:, -1, 0]
    gap = np.minimum(sim.ego_lead_gap[:, -1], LEADER_RANGE)
    ratio = 1.0 - gap / LEADER_RANGE
    efficiency = EFFICIENCY_WEIGHT * (np.abs(v_end - v_ref) / 10.0 +
                                      1.5 * ratio * np.abs(v_end - v_ref) / np.maximum(2.0, gap))
    lane_change = np.array([LANE_CHANGE_COST if p.lateral is not Lat.KEEP else 0.0 for p in policies])[policy_of]
    per_rollout = weight_of * (safety + efficiency + lane_change)
    P = len(policies)
    cost = np.zeros(P)
    np.add.at(cost, policy_of, per_rollout)
    valid = np.ones(P, dtype=bool)
    np.logical_and.at(valid, policy_of, sim.valid)
    return Evaluation(cost, valid, np.zeros(P, dtype=bool), cost[:, None])
