"""CFB's open-loop pre-check (EUDM paper, port decision 1): does an agent's intention matter for the ego?

Each agent is rolled out open loop (constant speed, moving to the lane of the intention over
``LANE_CHANGE_TIME``) for every intention it may have, and the ego likewise for each lane it may take. An
agent *matters* if some intention other than its most likely one brings it into conflict with some ego
option: closer than a time gap ``CONFLICT_HEADWAY`` (plus ``CONFLICT_MARGIN``) along the frame while laterally
overlapping (plus ``LATERAL_MARGIN``). Only those agents are branched.
"""
from __future__ import annotations

import numpy as np

from ..lanes import LEFT, RIGHT
from ..road_frame import RoadFrame
from .forward_sim import Vehicles

LANE_CHANGE_TIME = 3.0  # [s]
CONFLICT_HEADWAY = 1.0  # [s]
CONFLICT_MARGIN = 5.0  # [m]
LATERAL_MARGIN = 0.5  # [m]
SAMPLE_STEP = 0.5  # [s]
MIN_PROBABILITY = 0.05


def intention_matters(frame: RoadFrame, vehicles: Vehicles, agent_chain: np.ndarray, probs: np.ndarray,
                      horizon: float) -> np.ndarray:
    """[agents] bool: a non-MAP intention with probability ≥ MIN_PROBABILITY conflicts with an ego option."""
    n = len(probs)
    if n == 0:
        return np.zeros(0, dtype=bool)
    t = np.arange(SAMPLE_STEP, horizon + 1e-9, SAMPLE_STEP)  # [T]
    shift = np.array([0, 1, -1])  # keep, left, right
    ego_chain = np.clip(int(vehicles.chain[0]) + shift, RIGHT, LEFT)  # [3] options
    ego_s, ego_d = _open_loop(frame, vehicles.s[0], vehicles.d[0], vehicles.speed[0], ego_chain, t)
    agent_target = np.clip(agent_chain[:, None] + shift[None, :], RIGHT, LEFT)  # [n, 3]
    ag_s, ag_d = _open_loop(frame, vehicles.s[1:, None], vehicles.d[1:, None], vehicles.speed[1:, None],
                            agent_target, t)  # [n, 3, T]
    ds = np.abs(ag_s[:, :, None, :] - ego_s[None, None, :, :])  # [n, 3 intentions, 3 ego options, T]
    lon_limit = 0.5 * (vehicles.length[1:, None, None, None] + vehicles.length[0]) + CONFLICT_MARGIN + \
        CONFLICT_HEADWAY * vehicles.speed[0]
    lat_limit = 0.5 * (vehicles.width[1:, None, None, None] + vehicles.width[0]) + LATERAL_MARGIN
    conflict = np.any((ds < lon_limit) & (np.abs(ag_d[:, :, None, :] - ego_d[None, None, :, :]) < lat_limit),
                      axis=(2, 3))  # [n, 3]
    possible = probs >= MIN_PROBABILITY
    possible[np.arange(n), np.argmax(probs, axis=1)] = False
    return np.any(conflict & possible, axis=1)


def _open_loop(frame: RoadFrame, s0: np.ndarray, d0: np.ndarray, v: np.ndarray, chain: np.ndarray,
               t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Constant-speed positions at times ``t``, blending linearly from d0 to the chain's centre."""
    s = np.asarray(s0)[..., None] + np.asarray(v)[..., None] * t
    blend = np.minimum(t / LANE_CHANGE_TIME, 1.0)
    d = np.asarray(d0)[..., None] * (1.0 - blend) + frame.centre_d(chain[..., None], s) * blend
    return np.broadcast_to(s, d.shape), d
