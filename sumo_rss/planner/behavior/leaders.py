"""Leaders in EUDM's forward simulation (epsilon.md §3): each vehicle's leader on the lanes it looks at, standing
obstacles taking a leader's place (a lane's end, a stop line), the band in which the ego is in an agent's way, and
the RSS distance the ego keeps behind the car it follows. Arrays [rollouts, vehicles], column 0 the ego; m, m/s.
The leader search is part of the forward-simulation kernel (numba); the other functions are jitable (numpy over
arrays for the policy costs, compiled in the kernel).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...jit import jitable, kernel, select
from ...rss import formulas
from ...rss.situations import extent_across
from ..lanes import CURRENT

LEADER_RANGE = 120.0  # [m] leader search range (also the leader cost's range)
# [m] the ego's in its own lane (the planning frame's reach ahead): RSS's safe distance at highway speeds is longer
# than LEADER_RANGE (docs/planner.md, "A speed target reached at the limit, and the ego's leader beyond 120 m")
EGO_LEADER_RANGE = 250.0


def hardest_braking(rss_agents: Any) -> Any:
    """The RSS parameters ([1] arrays) of the agent that can brake hardest. With ``SimSettings.rss_following`` the
    ego keeps the RSS distance to whichever car it follows, taken at this worst case."""
    return rss_agents.take(np.array([int(np.argmax(rss_agents.lon_brake_max))]))


@jitable
def following_distance(v: Any, v_lead: Any, rss_ego: Any, front_worst: Any, held_gap: Any = np.inf) -> np.ndarray:
    """[m] The least bumper gap the ego at ``v`` keeps behind a car at ``v_lead`` with ``SimSettings.rss_following``:
    the RSS safe distance, taken at ``front_worst`` (:func:`hardest_braking`), or the car's ``held_gap`` (a car
    that cut in: the gap it left, see :func:`.forward_sim.simulate`) where that is shorter."""
    return np.minimum(formulas.lon_safe_distance_same_dir(v, v_lead, rss_ego, front_worst), held_gap)


def leaders_ahead(s: np.ndarray, v: np.ndarray, offset: np.ndarray, lanes: np.ndarray,
                  length: np.ndarray, radii: tuple[float, float], ego_band: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each vehicle's leader on each of the ``lanes`` [m, G, n] it looks at: the nearest vehicle ahead (centre
    further along s, within LEADER_RANGE + its length; the ego's in the CURRENT chain within EGO_LEADER_RANGE +
    its length) inside the lane's band, |d - centre(s)| < the follower's
    search radius (``radii`` = (agents', the ego's); the ego is column 0). To the agents the ego is in a lane's
    band where |d - centre(s)| < ``ego_band`` [G] [m] (default: the agents' radius): a body that sticks out
    into their lane is in their way. An agent's leader is the first vehicle in the lane's band after it in the
    order along s (stable for equal s); the ego's is the nearest one ahead in its band.
    ``offset`` [chains, G, n]: |d − centre(s)| of every vehicle to every chain [m].
    Returns the bumper gaps [m] (inf: none), the leaders' speeds and their columns (n: none), [m, G, n]; the
    speed where there is none is the ego's (a free road is read by the gap)."""
    band = np.full(s.shape[0], float(radii[0])) if ego_band is None else np.asarray(ego_band, dtype=float)
    return find_leaders(np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(v, dtype=float),
                        np.ascontiguousarray(offset, dtype=float), np.ascontiguousarray(lanes, dtype=np.int64),
                        np.ascontiguousarray(length, dtype=float), float(radii[0]), float(radii[1]), band)


@kernel
def find_leaders(s: np.ndarray, v: np.ndarray, offset: np.ndarray, lanes: np.ndarray, length: np.ndarray,
                 agent_radius: float, ego_radius: float, ego_band: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`leaders_ahead` in numba (the forward-simulation kernel's leader search)."""
    looks, G, n = lanes.shape
    gaps = np.empty((looks, G, n))
    speeds = np.empty((looks, G, n))
    leader = np.empty((looks, G, n), dtype=np.int64)
    rank = np.empty(n, dtype=np.int64)
    order = np.empty(n, dtype=np.int64)
    for g in range(G):
        for p in range(n):  # a stable insertion sort along s (n is small; np.argsort costs seconds of compile time)
            q = p
            while q > 0 and s[g, order[q - 1]] > s[g, p]:
                order[q] = order[q - 1]
                q -= 1
            order[q] = p
        for p in range(n):
            rank[order[p]] = p
        for m in range(looks):
            for i in range(n):
                chain = lanes[m, g, i]
                reach = EGO_LEADER_RANGE if i == 0 and chain == CURRENT else LEADER_RANGE
                j = -1
                if i == 0:
                    best = np.inf
                    for q in range(1, n):
                        ds = s[g, q] - s[g, 0]
                        if 0.0 < ds < reach + length[q] and offset[chain, g, q] < ego_radius and ds < best:
                            best, j = ds, q
                else:
                    for p in range(rank[i] + 1, n):
                        q = order[p]
                        if offset[chain, g, q] < (ego_band[g] if q == 0 else agent_radius):
                            j = q
                            break
                gaps[m, g, i], speeds[m, g, i], leader[m, g, i] = np.inf, v[g, 0], n
                if j >= 0:
                    speeds[m, g, i] = v[g, j]
                    ds = s[g, j] - s[g, i]
                    if 0.0 < ds < reach + length[j]:
                        gaps[m, g, i], leader[m, g, i] = ds - 0.5 * (length[i] + length[j]), j
    return gaps, speeds, leader


@jitable
def occupied_band(heading: Any, length: Any, width: Any, widest_agent: Any, agent_radius: Any) -> np.ndarray:
    """[m] per rollout: how far from a lane's centre line the ego's centre (``heading`` against it, ``length`` x
    ``width``) may be and still be in the way of an agent keeping to that centre line (its body, turned as it is,
    reaches half the widest agent's width from it), at least the agents' own band (``agent_radius`` [m]). A car
    stopped at an angle half-way into a lane blocks it."""
    reach = 0.5 * extent_across(length, width, np.cos(heading), np.sin(heading))
    return np.maximum(agent_radius, reach + 0.5 * widest_agent)


@jitable
def stopped_leader(stop_gap: Any, gap: Any, v_lead: Any) -> tuple[np.ndarray, np.ndarray]:
    """(gap, leader speed) with a standing obstacle ``stop_gap`` [m] ahead taking the leader's place where nearer."""
    closer = stop_gap < gap
    return select(closer, stop_gap, gap), select(closer, 0.0, v_lead)
