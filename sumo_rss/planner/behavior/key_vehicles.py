"""Key vehicles: the agents EUDM simulates with the ego (epsilon.md §2.1, with the port's fix: the follower in
the ego's lane is key too)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sim.snapshot import WorldSnapshot
from ..lanes import CURRENT, LaneChains

MAX_LANE_OFFSET = 2.0  # [m] farther from every key lane's centre line, a vehicle is on none of them


def front_range(v_ego: float) -> float:
    """R_f = clamp(v·max(5, v/1.6) + 100, 30, 170) [m]."""
    return float(np.clip(v_ego * max(5.0, v_ego / 1.6) + 100.0, 30.0, 170.0))


@dataclass(frozen=True, eq=False)
class KeyVehicles:
    rows: np.ndarray  # snapshot rows of the key vehicles
    chain: np.ndarray  # RIGHT / CURRENT / LEFT chain each is on
    s: np.ndarray  # centre position along that chain, relative to the ego's [m]
    d: np.ndarray  # offset from the chain's centre line [m], + = left


def key_vehicles(snapshot: WorldSnapshot, ego_row: int, chains: LaneChains) -> KeyVehicles:
    """Vehicles on a key lane within R_f ahead of the ego or max(20, 5·|v|) behind it."""
    cx = snapshot.x - 0.5 * snapshot.length * np.cos(snapshot.heading)
    cy = snapshot.y - 0.5 * snapshot.length * np.sin(snapshot.heading)
    n = len(snapshot)
    s_all = np.full((3, n), np.nan)
    d_all = np.full((3, n), np.inf)
    for which in range(3):
        if chains.exists(which):
            s_all[which], d_all[which] = chains.project(which, cx, cy)
    chain = np.argmin(np.abs(d_all), axis=0)
    cols = np.arange(n)
    s, d = s_all[chain, cols], d_all[chain, cols]
    ego_s, _ = chains.project(CURRENT, cx[ego_row:ego_row + 1], cy[ego_row:ego_row + 1])
    dist = s - ego_s[0]
    on_lane = np.abs(d) <= MAX_LANE_OFFSET
    ahead = (dist >= 0.0) & (dist < front_range(float(snapshot.speed[ego_row])))
    behind = (dist < 0.0) & (-dist < np.maximum(20.0, 5.0 * np.abs(snapshot.speed)))
    key = on_lane & (ahead | behind) & (cols != ego_row)
    rows = np.flatnonzero(key)
    return KeyVehicles(rows, chain[rows], dist[rows], d[rows])
