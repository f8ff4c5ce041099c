"""Rule-based soft intention belief for highway agents (epsilon.md §2.2 made soft, for CFB).

EPSILON's released rule is one-hot: a lane change left when d > 0.4 m and ḋ > 0.35 m/s (right mirrored), else keep.
Here the same thresholds are the midpoints of smooth ramps, so an agent drifting towards a lane boundary becomes
gradually uncertain instead of flipping, and a lane that does not exist gets probability 0.
"""
from __future__ import annotations

from typing import Any

import numpy as np

OFFSET_MID, OFFSET_SPREAD = 0.4, 0.15  # [m] lateral offset from the lane centre, + = left
SPEED_MID, SPEED_SPREAD = 0.35, 0.12  # [m/s] lateral speed, + = left
LANE_END_NOTICE = 200.0  # [m] an agent this near the end of its lane starts to be expected to leave it
LANE_END_CERTAINTY = 0.9  # the highest probability the lane end alone gives to leaving


def _ramp(x: np.ndarray, mid: float, spread: float) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-(x - mid) / spread))


def intention_probabilities(offset: Any, lat_speed: Any, has_left: Any, has_right: Any) -> np.ndarray:
    """[n, 3] probabilities (keep, left, right) from each agent's lateral offset [m] and speed [m/s] in its lane
    (+ = left) and whether a lane to the left / right exists that it may enter."""
    d, v = np.asarray(offset, dtype=float), np.asarray(lat_speed, dtype=float)
    left = _ramp(d, OFFSET_MID, OFFSET_SPREAD) * _ramp(v, SPEED_MID, SPEED_SPREAD) * np.asarray(has_left, dtype=bool)
    right = _ramp(-d, OFFSET_MID, OFFSET_SPREAD) * _ramp(-v, SPEED_MID, SPEED_SPREAD) * \
        np.asarray(has_right, dtype=bool)
    keep = np.clip(1.0 - left - right, 0.0, 1.0)
    total = keep + left + right
    return np.column_stack([keep, left, right]) / total[:, None]


def rule_belief(offset: Any, lat_speed: Any, has_left: Any, has_right: Any, to_lane_end: Any) -> np.ndarray:
    """:func:`intention_probabilities`, plus: an agent whose lane ends ``to_lane_end`` [m] ahead (inf: it does
    not end) will change towards the lane on its left, or, with none there, on its right (the lane that goes on),
    surer the nearer the end."""
    probs = intention_probabilities(offset, lat_speed, has_left, has_right)
    to_end = np.asarray(to_lane_end, dtype=float)
    urgency = np.clip(1.0 - to_end / LANE_END_NOTICE, 0.0, LANE_END_CERTAINTY) * np.isfinite(to_end)
    left, right = np.asarray(has_left, dtype=bool), np.asarray(has_right, dtype=bool)
    shift = np.where(left | right, urgency, 0.0)
    probs = probs * (1.0 - shift)[:, None]
    probs[:, 1] += np.where(left, shift, 0.0)
    probs[:, 2] += np.where(left, 0.0, shift)
    return probs
