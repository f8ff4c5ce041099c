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
