"""Policy evaluation of EUDM (epsilon.md §4): per-layer costs, discount, scenario weighting.

Per layer i (end-of-layer ego state, except RSS which sums over the layer's samples):
efficiency (c_ego), leader (c_lead), RSS safe-velocity penalty (c_rss), forbidden lane (c_occ),
navigation/user (c_nav); C_i = t_i·γ^i·[(c_ego + c_lead)/2 + (c_rss + c_occ)/2 + c_nav]. Beyond the horizon (a
departure from the release's zero tail, docs/planner.md "Cost weights"): (c_ego + c_lead)/2 at the speed the ego's
end lane holds it to, over ``CostWeights.beyond_horizon`` s more layers with the discount continued. A policy's cost
is the scenario-weighted sum over its rollouts; a policy that collides in any of its scenarios is invalid.
Units: m, s, m/s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...angles import cos_sin
from ...rss import formulas
from ...rss.compliance import lateral_speed_bound
from ...rss.step_input import EPS_ACCEL
from ...rss.situations import extent_across
from ..lanes import CURRENT, LEFT, RIGHT
from ..road_frame import RoadFrame
from .cost_weights import CostWeights
from .dcp_tree import Lat, Policy
from .forward_sim import SimResult
from .leaders import LEADER_RANGE, following_distance, hardest_braking
from .lane_change import laterally_safe


@dataclass(frozen=True)
class Navigation:
    """Lane-change wishes for the cost: the direction the manager recommends now (None: none), user forbids."""

    recommended: Lat | None = None
    forbid_left: bool = False
    forbid_right: bool = False


@dataclass(frozen=True, eq=False)
class Evaluation:
    """Per policy: total cost, validity, whether RSS was violated, and the cost per layer."""

    cost: np.ndarray  # [P]
    valid: np.ndarray  # [P] bool
    risky: np.ndarray  # [P] bool
    layer_cost: np.ndarray  # [P, layers + 1] scenario-weighted; the last column: beyond the horizon


def rss_penalty(sim: SimResult, frame: RoadFrame, rss_ego: Any, rss_agents: Any, length: np.ndarray,
                width: np.ndarray, w: CostWeights, cut_in_ahead: np.ndarray | None = None) -> np.ndarray:
    """RSS safe-velocity penalty per rollout and sample [R, T+1], summed over agents (epsilon.md §4.1.3).
    Lateral speeds are taken relative to each car's own lane (as the auditor does), so lanes that converge in
    the frame (a ramp and the motorway) do not read as cars driving at each other. ``cut_in_ahead`` [agents] bool:
    cars ahead that the ego owes no longitudinal braking (they cut in, rss.md §5): no charge while they are
    ahead. The ego keeps the gap they left it (:func:`simulate`'s ``cut_in_gap``) and the guard keeps it from
    closing in."""
    s, d, v, h = sim.s, sim.d, sim.speed, sim.heading
    ds = s[..., 1:] - s[..., :1]
    cos_rel, sin_rel = cos_sin(h - frame.slope(sim.chain, s))
    v_lat, across = v * sin_rel, extent_across(length, width, cos_rel, sin_rel)
    lat_unsafe = ~laterally_safe(d[..., :1], d[..., 1:], v_lat[..., :1], v_lat[..., 1:], across[..., :1],
                                 across[..., 1:], rss_ego, rss_agents)
    front = ds >= 0.0
    # The ego is charged for every car ahead that it is laterally unsafe to (it is the rear car), and for a rear
    # car from the sample it cuts in: the pair turns laterally unsafe while it is longitudinally unsafe (RSS's
    # lateral trigger) and the ego breaks the lateral response it then owes (it goes on moving towards the car).
    # A rear car that turns unsafe later, was already beside or behind the ego in its lane at the start, or cuts
    # in behind an ego that keeps to its lane, is that car's duty. Speed bounds are computed for those pairs only.
    crossing = np.zeros_like(lat_unsafe)
    crossing[:, 1:] = lat_unsafe[:, 1:] & ~lat_unsafe[:, :-1] & ~front[:, 1:]
    cut_in = np.zeros_like(lat_unsafe)
    if np.any(crossing):
        r_idx, k_idx, a_idx = np.nonzero(crossing)
        gap_x = -ds[r_idx, k_idx, a_idx] - 0.5 * (length[0] + length[1:][a_idx])
        v_low_x = formulas.min_safe_speed_ahead(gap_x, v[r_idx, k_idx, a_idx + 1], rss_ego, rss_agents.take(a_idx))
        dangerous = (gap_x < 0.0) | (v[r_idx, k_idx, 0] < v_low_x - 1e-6)
        ego_left = d[r_idx, :, 0] >= d[r_idx, :, a_idx + 1]  # [crossings, T+1]
        towards = np.where(ego_left, -v_lat[r_idx, :, 0], v_lat[r_idx, :, 0])
        breaks = breaks_lateral_response(sim.t, k_idx, towards, lat_unsafe[r_idx, :, a_idx], rss_ego)
        cut_in[r_idx, k_idx, a_idx] = dangerous & breaks
        cut_in = np.logical_or.accumulate(cut_in, axis=1)
    charged = lat_unsafe & (front | cut_in)
    if cut_in_ahead is not None:
        charged &= ~(front & cut_in_ahead)
    penalty = np.zeros(charged.shape[:2])
    if not np.any(charged):
        return penalty
    sample, agent = np.nonzero(charged.reshape(-1, charged.shape[-1]))
    gap = np.abs(ds[charged]) - 0.5 * (length[0] + length[1:][agent])
    v_e, v_o, front = v[..., 0].ravel()[sample], v[..., 1:][charged], front[charged]
    p_o = rss_agents.take(agent)
    v_up = formulas.max_safe_speed_behind(np.maximum(gap, 0.0), v_o, rss_ego, p_o)
    v_up = np.where(gap < 0.0, 0.0, np.maximum(v_up, 0.0))
    v_low = formulas.min_safe_speed_ahead(gap, v_o, rss_ego, p_o)
    too_fast = front & (v_e > v_up + 1e-6)
    too_slow = ~front & (v_e < v_low - 1e-6)
    fast = w.rss_over_coeff * v_e * 10.0 ** (w.rss_over_power * np.minimum(np.abs(v_e - v_up), w.rss_max_excess))
    slow = w.rss_lack_coeff * v_e * 10.0 ** (w.rss_lack_power * np.minimum(np.abs(v_e - v_low), w.rss_max_excess))
    return np.bincount(sample, np.where(too_fast, fast, 0.0) + np.where(too_slow, slow, 0.0),
                       minlength=penalty.size).reshape(penalty.shape)


def breaks_lateral_response(t: np.ndarray, onset: np.ndarray, towards: np.ndarray, lat_unsafe: np.ndarray,
                             rss_ego: Any) -> np.ndarray:
    """Per lateral trigger: whether the ego breaks the lateral response it owes (rss.md §5, judged as the
    auditor does) while the pair stays laterally unsafe. ``t`` [T+1] sample times [s]; ``onset`` [C] the sample
    of each trigger; ``towards`` [C, T+1] the ego's lateral speed towards the other car [m/s]; ``lat_unsafe``
    [C, T+1]. The speed towards the other may grow by at most a_lat during ρ, must then fall at b_lat until it is
    ≤ 0 and stay there (tolerance: the auditor's, integrated over the time since the trigger)."""
    tau = t[None, :] - t[onset][:, None]  # [C, T+1] time since the trigger
    u0 = towards[np.arange(onset.size), onset][:, None]
    bound = lateral_speed_bound(u0, tau, rss_ego.response_time, rss_ego.lat_accel_max, rss_ego.lat_brake_min)
    still_unsafe = np.logical_and.accumulate(lat_unsafe | (tau < 0.0), axis=1) & (tau > 0.0)
    return np.any(still_unsafe & (towards > bound + EPS_ACCEL * tau), axis=1)


def evaluate(sim: SimResult, frame: RoadFrame, policies: list[Policy], policy_of: np.ndarray, weight_of: np.ndarray,
             v_ref: float, nav: Navigation, rss_ego: Any, rss_agents: Any, length: np.ndarray,
             width: np.ndarray, w: CostWeights = CostWeights(), rss_following_headway: float | None = None,
             cut_in_ahead: np.ndarray | None = None) -> Evaluation:
    """Costs of ``policies`` from the rollouts in ``sim``; rollout r plays policy ``policy_of[r]`` with scenario
    weight ``weight_of[r]``. ``rss_agents`` covers the agents only (columns 1..n). ``rss_following_headway`` [s]:
    the ego IDM's T when the simulation kept the ego at least the RSS distance behind its leader
    (``SimSettings.rss_following``; None: it did not). ``cut_in_ahead`` [agents]: as in :func:`rss_penalty`."""
    ends = sim.layer_end
    starts = np.concatenate([[0], ends[:-1]])
    durations = sim.t[ends] - sim.t[starts]
    v = sim.speed[:, ends, 0]  # [R, layers]
    v_lead = sim.ego_lead_speed[:, ends]
    gap = leader_gap_for_cost(sim.ego_lead_gap[:, ends], v, v_lead, rss_ego, rss_agents, rss_following_headway,
                              sim.ego_lead_held_gap[:, ends], sim.ego_lead_is_car[:, ends])
    c_ego, c_lead = efficiency_costs(v, v_lead, gap, v_ref, w)
    per_sample = rss_penalty(sim, frame, rss_ego, rss_agents, length, width, w, cut_in_ahead)  # [R, T+1]
    sample_layer = np.searchsorted(ends, np.arange(sim.t.size), side="left")  # sample k ∈ layer (k ≤ end)
    c_rss = np.zeros_like(v)
    for i in range(len(ends)):
        c_rss[:, i] = per_sample[:, (sample_layer == i) & (np.arange(sim.t.size) > 0)].sum(axis=1)
    c_occ, c_nav = _lane_costs(policies, policy_of, v, nav, w)
    discount = durations * w.discount ** np.arange(len(ends))
    layer = discount * (0.5 * (c_ego + c_lead) + 0.5 * (c_rss + c_occ) + c_nav)  # [R, layers]
    end_chain = np.array([TARGET_CHAIN[p.lats[len(ends) - 1]] for p in policies])[policy_of]
    tail = beyond_horizon_cost(sim, end_chain, gap[:, -1], v_ref, w, float(durations[-1]))
    P = len(policies)
    layer_cost = np.zeros((P, len(ends) + 1))  # the layers, then the cost beyond the horizon
    np.add.at(layer_cost, policy_of, weight_of[:, None] * np.column_stack([layer, tail]))
    valid = np.ones(P, dtype=bool)
    np.logical_and.at(valid, policy_of, sim.valid)
    risky = np.zeros(P, dtype=bool)
    np.logical_or.at(risky, policy_of, per_sample.sum(axis=1) > 0.0)
    return Evaluation(layer_cost.sum(axis=1), valid, risky, layer_cost)


def efficiency_costs(v: np.ndarray, v_lead: np.ndarray, gap: np.ndarray, v_ref: float, w: CostWeights
                     ) -> tuple[np.ndarray, np.ndarray]:
    """epsilon.md §4.1.1-2: the ego's efficiency cost c_ego at speed ``v`` and its leader cost c_lead behind a
    leader at ``v_lead`` ``gap`` m ahead as the cost reads it (:func:`leader_gap_for_cost`; inf: none); ``v_ref``:
    the reference speed [m/s]. Arrays of one shape."""
    c_ego = np.where(v < v_ref, w.lack_speed * (v_ref - v),
                     np.where(v > v_ref + w.over_speed_tolerance, w.over_speed * (v - v_ref - w.over_speed_tolerance),
                              0.0))
    residual = np.clip((LEADER_RANGE - gap) / LEADER_RANGE, 0.0, 1.0)
    blocked = (v < v_ref) & (v_lead < v_ref) & (gap < LEADER_RANGE)
    c_lead = np.where(blocked, np.maximum(w.leader_min_ratio, residual) *
                      (w.blocked_by_leader * np.maximum(v - v_lead, 0.0) + w.leader_below_desired * (v_ref - v_lead)),
                      0.0)
    return c_ego, c_lead


def beyond_horizon_cost(sim: SimResult, end_chain: np.ndarray, gap: np.ndarray, v_ref: float, w: CostWeights,
                        layer_duration: float) -> np.ndarray:
    """[R] What each rollout's end state costs after the horizon: the release's (c_ego + c_lead)/2 at the speed the
    ego's end lane holds it to, over ``w.beyond_horizon`` s of further layers of ``layer_duration`` s, discounted on
    from the last layer (γ^L .. γ^(L+N-1), N layers). That speed is the reference speed, or the speed of the car
    the ego follows there at the horizon's end where it is slower (the leader cost's range; a lane end or a stop
    line is not a speed the ego is held to: that wait is over when the light turns or the ego merges). An ego that
    has not reached the lane its last layer aims at (``end_chain`` [R]: chain index) is taken on at its end speed
    where that is slower: a lane change the virtual barrier held gains nothing. ``gap`` [R]: the bumper gap to that
    leader as the leader cost reads it [m] (inf: none). The release's cost stops at the horizon: a change that
    wins 8 m/s behind a slow car pays its navigation cost in every layer and gets the speed in the last two or
    three, discounted, so it lost to keeping behind the car (docs/planner.md)."""
    layers = int(round(w.beyond_horizon / layer_duration))
    if layers <= 0:
        return np.zeros(sim.speed.shape[0])
    v_end, v_lead = sim.speed[:, -1, 0], sim.ego_lead_speed[:, -1]
    led = np.isfinite(gap) & sim.ego_lead_is_car[:, -1]
    held = np.where(led, np.minimum(v_lead, v_ref), v_ref)
    held = np.where(sim.chain[:, -1, 0] == end_chain, held, np.minimum(held, v_end))
    c_ego, c_lead = efficiency_costs(held, np.where(led, v_lead, v_ref), np.where(led, gap, np.inf), v_ref, w)
    first = sim.layer_end.size
    weight = layer_duration * float(np.sum(w.discount ** np.arange(first, first + layers)))
    return weight * 0.5 * (c_ego + c_lead)


def leader_gap_for_cost(gap: np.ndarray, v: np.ndarray, v_lead: np.ndarray, rss_ego: Any, rss_agents: Any,
                        rss_following_headway: float | None, held_gap: Any = np.inf, is_car: Any = True
                        ) -> np.ndarray:
    """The ego's bumper gap [m] to its leader as the leader cost reads it (inf: no leader). With RSS following the
    ego's IDM keeps the RSS safe distance where it exceeds the headway v·T, so the ego follows ~100 m back under
    ad_rss where EPSILON's IDM follows 20-30 m back, and the cost's 120 m range would rate a leader that holds
    the ego to its speed as hardly in the way (residual ratio at its 0.4 floor). The cost therefore reads the gap
    as EPSILON's IDM would: less the excess over v·T of the distance the simulation keeps
    (:func:`following_distance`, with the leader's ``held_gap`` [m]). Only behind a car (``is_car``): the
    simulation approaches a lane end or a stop line with the plain IDM, so that gap is read as it is."""
    if rss_following_headway is None or rss_agents.lon_brake_max.size == 0:
        return gap
    led = np.isfinite(gap) & is_car
    following = following_distance(v, np.where(led, v_lead, v), rss_ego, hardest_braking(rss_agents), held_gap)
    return gap - np.where(led, np.maximum(following - rss_following_headway * v, 0.0), 0.0)


TARGET_CHAIN = {Lat.KEEP: CURRENT, Lat.LEFT: LEFT, Lat.RIGHT: RIGHT}  # the lane chain a lateral action aims at


def _lane_costs(policies: list[Policy], policy_of: np.ndarray, v: np.ndarray, nav: Navigation,
                w: CostWeights) -> tuple[np.ndarray, np.ndarray]:
    """Forbidden-lane and navigation/user costs per rollout and layer."""
    u = np.maximum(w.nav_speed_floor, v)
    n_layers = v.shape[1]
    occ_rate = np.zeros((len(policies), 1))
    nav_rate = np.zeros((len(policies), n_layers))
    for p, policy in enumerate(policies):
        lateral = policy.lateral
        forbidden = (lateral is Lat.LEFT and nav.forbid_left) or (lateral is Lat.RIGHT and nav.forbid_right)
        occ_rate[p] = w.occupied_lane if forbidden else 0.0
        if lateral is Lat.KEEP:
            continue
        if policy.is_cancel:
            nav_rate[p] = w.cancel
        elif nav.recommended is lateral:
            late = np.array([lat is not lateral for lat in policy.lats[:n_layers]], dtype=float)
            nav_rate[p] = -w.recommended_reward + w.late_operation * late
        else:
            nav_rate[p] = w.lane_change_left if lateral is Lat.LEFT else w.lane_change_right
    return occ_rate[policy_of] * v, nav_rate[policy_of] * u
