"""Angle helper shared by the snapshot, the auditor and the planner."""
from __future__ import annotations

from typing import Any

import numpy as np


def wrap_angle(angle: Any) -> np.ndarray:
    """``angle`` [rad] wrapped into (-π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
