"""Key vehicles: the agents EUDM simulates with the ego (epsilon.md §2.1, with the port's fix: the follower in
the ego's lane is key too)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sim.snapshot import WorldSnapshot
from ..road_frame import RoadFrame

MAX_LANE_OFFSET = 2.0  # [m] farther from every key lane's centre line, a vehicle is on none of them
SEARCH_RADIUS = 250.0  # [m] Euclidean pre-filter around the ego (R_f ≤ 170 m; rear range: 5·v or the RSS reach)


def front_range(v_ego: float) -> float:
    """R_f = clamp(v·max(5, v/1.6) + 100, 30, 170) [m]."""
    return float(np.clip(v_ego * max(5.0, v_ego / 1.6) + 100.0, 30.0, 170.0))


@dataclass(frozen=True, eq=False)
class KeyVehicles:
    """Key vehicles in the planning frame; positions are of the vehicles' geometric centres."""

    rows: np.ndarray  # snapshot rows of the key vehicles
    chain: np.ndarray  # RIGHT / CURRENT / LEFT chain each is on
    s: np.ndarray  # centre position along the frame, relative to the ego's centre [m]
    d: np.ndarray  # offset from its own chain's centre line [m], + = left
    frame_s: np.ndarray  # absolute frame s [m]
    frame_d: np.ndarray  # frame d [m]
    heading: np.ndarray  # heading relative to the frame's centre line [rad]


def key_vehicles(snapshot: WorldSnapshot, ego_row: int, frame: RoadFrame,
                 rear_reach: np.ndarray | None = None) -> KeyVehicles:
    """Vehicles on a key lane within R_f ahead of the ego or max(20, 5·|v|, ``rear_reach``) behind it.
    ``rear_reach[row]`` [m] (per snapshot row): how far behind the ego that car could still be RSS-unsafe as
    its follower — a gap the ego merges into is judged on every car that could make it unsafe."""
    cx, cy = snapshot.centres()
    near = np.flatnonzero(np.hypot(cx - cx[ego_row], cy - cy[ego_row]) <= SEARCH_RADIUS)
    s, d, rel = frame.to_frame(cx[near], cy[near], snapshot.heading[near])
    chain = frame.nearest_chain(s, d)
    d_own = d - frame.centre_d(chain, s)
    ego = int(np.flatnonzero(near == ego_row)[0])
    dist = s - s[ego]
    speed = snapshot.speed[near]
    on_lane = np.abs(d_own) <= MAX_LANE_OFFSET
    ahead = (dist >= 0.0) & (dist < front_range(float(snapshot.speed[ego_row])))
    reach = np.maximum(20.0, 5.0 * np.abs(speed))
    if rear_reach is not None:
        reach = np.maximum(reach, rear_reach[near])
    behind = (dist < 0.0) & (-dist < reach)
    key = on_lane & (ahead | behind) & (near != ego_row)
    idx = np.flatnonzero(key)
    order = idx[np.argsort(near[idx], kind="stable")]
    return KeyVehicles(near[order], chain[order], dist[order], d_own[order], s[order], d[order], rel[order])
