"""EUDM's cost weights (epsilon.md §4, §9 defaults), apart from the evaluation so that scenario files can be
validated against them without importing the planner."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CostWeights:
    """epsilon.md §9 defaults, and the port's cost beyond the horizon (``beyond_horizon``, docs/planner.md
    "Cost weights")."""

    lack_speed: float = 0.3
    over_speed: float = 0.03
    over_speed_tolerance: float = 1.0  # [m/s]
    leader_min_ratio: float = 0.4
    blocked_by_leader: float = 0.02
    leader_below_desired: float = 0.1
    rss_over_coeff: float = 0.5
    rss_over_power: float = 0.25
    rss_lack_coeff: float = 0.6
    rss_lack_power: float = 0.35
    rss_max_excess: float = 20.0  # [m/s] cap on |v - v_bound| in the exponent (keeps the penalty finite)
    occupied_lane: float = 0.10
    late_operation: float = 0.25
    cancel: float = 8.0
    lane_change_left: float = 0.015
    lane_change_right: float = 0.06
    recommended_reward: float = 1.0
    nav_speed_floor: float = 10.0  # [m/s] u = max(10, v)
    discount: float = 0.7
    # [s] the efficiency and leader costs of the speed the ego's end lane holds it to, charged this long after the
    # horizon (layers of the last layer's duration, discounted on); 0: the release's zero tail. 5 s: chosen on
    # highway_overtake tuning seeds 100-119 against 0 and 10 s (docs/planner.md "Cost weights")
    beyond_horizon: float = 5.0
