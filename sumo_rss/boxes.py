"""Whether oriented boxes overlap: vehicle footprints in the planner's collision checks and the offline audit's
contacts (numpy over arrays), and in the forward-simulation kernel (numba, one pair at a time). Units: m, rad.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .jit import jitable


def boxes_overlap(ax: Any, ay: Any, ah: Any, al: Any, aw: Any, bx: Any, by: Any, bh: Any, bl: Any,
                  bw: Any) -> np.ndarray:
    """Whether oriented boxes (centre, heading, length, width) overlap, broadcast: a separating-axis test on the
    pairs whose bounding extents meet."""
    dx, dy = np.asarray(bx) - ax, np.asarray(by) - ay
    close = extents_meet(dx, dy, ah, al, aw, bh, bl, bw)  # every input takes part: the full shape
    shape = close.shape
    overlap = np.zeros(shape, dtype=bool)
    if not close.any():
        return overlap
    overlap[close] = ~separated(*(np.broadcast_to(np.asarray(a, dtype=float), shape)[close]
                                  for a in (dx, dy, ah, al, aw, bh, bl, bw)))
    return overlap


@jitable
def box_pair_overlaps(dx: float, dy: float, ah: float, al: float, aw: float, bh: float, bl: float,
                      bw: float) -> bool:
    """:func:`boxes_overlap` of one pair (box b's centre ``dx``, ``dy`` from box a's), in numba code."""
    return extents_meet(dx, dy, ah, al, aw, bh, bl, bw) and not separated(dx, dy, ah, al, aw, bh, bl, bw)


@jitable
def extents_meet(dx: Any, dy: Any, ah: Any, al: Any, aw: Any, bh: Any, bl: Any, bw: Any) -> np.ndarray:
    """Whether the boxes' bounding extents meet, without trigonometry (|sin h| ≤ |h|, |cos h| ≤ 1): boxes whose
    extents do not meet along x or y cannot overlap, and the exact test runs on the other pairs only."""
    abs_ah, abs_bh = np.abs(ah), np.abs(bh)
    return (np.abs(dx) < 0.5 * (al + bl + aw * abs_ah + bw * abs_bh)) & \
        (np.abs(dy) < 0.5 * (aw + bw + al * abs_ah + bl * abs_bh))


@jitable
def separated(dx: Any, dy: Any, ah: Any, al: Any, aw: Any, bh: Any, bl: Any, bw: Any) -> np.ndarray:
    """Whether one of the four edge normals separates the boxes."""
    return _separated_along(ah, dx, dy, ah, al, aw, bh, bl, bw) | \
        _separated_along(ah + np.pi / 2, dx, dy, ah, al, aw, bh, bl, bw) | \
        _separated_along(bh, dx, dy, ah, al, aw, bh, bl, bw) | \
        _separated_along(bh + np.pi / 2, dx, dy, ah, al, aw, bh, bl, bw)


@jitable
def _separated_along(phi: Any, dx: Any, dy: Any, ah: Any, al: Any, aw: Any, bh: Any, bl: Any,
                     bw: Any) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    dist = np.abs(dx * c + dy * s)
    ra = 0.5 * al * np.abs(np.cos(ah - phi)) + 0.5 * aw * np.abs(np.sin(ah - phi))
    rb = 0.5 * bl * np.abs(np.cos(bh - phi)) + 0.5 * bw * np.abs(np.sin(bh - phi))
    return dist > ra + rb
