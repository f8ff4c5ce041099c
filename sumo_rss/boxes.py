"""Whether oriented boxes overlap: vehicle footprints in the planner's collision checks and the offline audit's
contacts. Units: m, rad.
"""
from __future__ import annotations

from typing import Any

import numpy as np


def boxes_overlap(ax: Any, ay: Any, ah: Any, al: Any, aw: Any, bx: Any, by: Any, bh: Any, bl: Any,
                  bw: Any) -> np.ndarray:
    """Whether oriented boxes (centre, heading, length, width) overlap, broadcast: a separating-axis test on the
    pairs whose bounding extents meet."""
    dx, dy = np.asarray(bx) - ax, np.asarray(by) - ay
    # Bounding extents without trigonometry (|sin h| ≤ |h|, |cos h| ≤ 1): boxes whose extents do not meet along x
    # or y cannot overlap, and the exact test runs on the other pairs only.
    abs_ah, abs_bh = np.abs(ah), np.abs(bh)
    close = (np.abs(dx) < 0.5 * (al + bl + aw * abs_ah + bw * abs_bh)) & \
        (np.abs(dy) < 0.5 * (aw + bw + al * abs_ah + bl * abs_bh))  # every input takes part: the full shape
    shape = close.shape
    overlap = np.zeros(shape, dtype=bool)
    if not close.any():
        return overlap
    dx, dy, ah, al, aw, bh, bl, bw = (np.broadcast_to(np.asarray(a, dtype=float), shape)[close]
                                      for a in (dx, dy, ah, al, aw, bh, bl, bw))
    separated = np.zeros(dx.shape, dtype=bool)
    for phi in (ah, ah + np.pi / 2, bh, bh + np.pi / 2):
        c, s = np.cos(phi), np.sin(phi)
        dist = np.abs(dx * c + dy * s)
        ra = 0.5 * al * np.abs(np.cos(ah - phi)) + 0.5 * aw * np.abs(np.sin(ah - phi))
        rb = 0.5 * bl * np.abs(np.cos(bh - phi)) + 0.5 * bw * np.abs(np.sin(bh - phi))
        separated |= dist > ra + rb
    overlap[close] = ~separated
    return overlap
