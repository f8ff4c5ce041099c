"""Leaders in EUDM's forward simulation (epsilon.md §3): each vehicle's leader on the lanes it looks at, standing
obstacles taking a leader's place (a lane's end, a stop line), the band in which the ego is in an agent's way, and
the RSS distance the ego keeps behind the car it follows. Arrays [rollouts, vehicles], column 0 the ego; m, m/s.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...rss import formulas
from ...rss.situations import extent_across
from ..road_frame import RoadFrame

LEADER_RANGE = 120.0  # [m] leader search range (also the leader cost's range)


def hardest_braking(rss_agents: Any) -> Any:
    """The RSS parameters ([1] arrays) of the agent that can brake hardest. With ``SimSettings.rss_following`` the
    ego keeps the RSS distance to whichever car it follows, taken at this worst case."""
    return rss_agents.take(np.array([int(np.argmax(rss_agents.lon_brake_max))]))


def following_distance(v: Any, v_lead: Any, rss_ego: Any, front_worst: Any, held_gap: Any = np.inf) -> np.ndarray:
    """[m] The least bumper gap the ego at ``v`` keeps behind a car at ``v_lead`` with ``SimSettings.rss_following``:
    the RSS safe distance, taken at ``front_worst`` (:func:`hardest_braking`), or the car's ``held_gap`` (a car
    that cut in: the gap it left, see :func:`.forward_sim.simulate`) where that is shorter."""
    return np.minimum(formulas.lon_safe_distance_same_dir(v, v_lead, rss_ego, front_worst), held_gap)


def leaders_ahead(s: np.ndarray, v: np.ndarray, offset: np.ndarray, lanes: np.ndarray,
                  length: np.ndarray, radii: tuple[float, float], ego_band: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each vehicle's leader on each of the ``lanes`` [m, G, n] it looks at: the nearest vehicle ahead (centre
    further along s, within LEADER_RANGE + its length) inside the lane's band, |d - centre(s)| < the follower's
    search radius (``radii`` = (agents', the ego's); the ego is column 0). To the agents the ego is in a lane's
    band where |d - centre(s)| < ``ego_band`` [G] [m] (default: the agents' radius): a body that sticks out
    into their lane is in their way. For the agents, vehicles are sorted along s once per rollout, so the search
    is O(n log n) instead of O(n²); the ego's leaders are found directly.
    ``offset`` [chains, G, n]: |d − centre(s)| of every vehicle to every chain [m].
    Returns the bumper gaps [m] (inf: none), the leaders' speeds and their columns (n: none), [m, G, n]."""
    G, n = s.shape
    cols = np.arange(n)
    row_base = (np.arange(G) * n)[:, None]
    sorted_flat = (row_base + np.argsort(s, axis=1, kind="stable")).ravel()  # flat [r, vehicle] by s per rollout
    rank = np.empty(G * n, dtype=np.intp)
    rank[sorted_flat] = np.arange(G * n) % n
    rank = rank.reshape(G, n)
    chains = offset.shape[0]
    band = np.full((G, n), radii[0])
    if ego_band is not None:
        band[:, 0] = ego_band
    member = (offset < band).reshape(chains, -1).take(sorted_flat, axis=1).reshape(chains, G, n)
    # The first member strictly after each sorted position (n: none).
    position = np.where(member, cols, n)
    following = np.full((chains, G, n), n)
    following[..., :-1] = np.minimum.accumulate(position[..., :0:-1], axis=-1)[..., ::-1]
    lead = following.ravel().take((lanes * G + np.arange(G)[:, None]) * n + rank)  # [m, G, n]
    found = lead < n
    flat_j = np.where(found, sorted_flat.take(row_base + np.minimum(lead, n - 1)), row_base)
    # The ego: the nearest centre ahead inside its wider band of each lane it looks at.
    ds_ego = s - s[:, :1]  # [G, n]
    near = (ds_ego > 0.0) & (ds_ego < LEADER_RANGE + length)
    rows = np.arange(G)
    in_band = offset[lanes[:, :, 0], rows] < radii[1]  # [m, G, n] within the ego's band of each lane it looks at
    ego_lead = np.argmin(np.where(near & in_band, ds_ego, np.inf), axis=2)  # [m, G]
    found[:, :, 0] = in_band[np.arange(lanes.shape[0])[:, None], rows, ego_lead] & near[rows, ego_lead]
    flat_j[:, :, 0] = np.where(found[:, :, 0], row_base[:, 0] + ego_lead, row_base[:, 0])
    j = flat_j - row_base
    ds = s.ravel().take(flat_j) - s
    ahead = found & (ds > 0.0) & (ds < LEADER_RANGE + length[j])
    return np.where(ahead, ds - 0.5 * (length + length[j]), np.inf), v.ravel().take(flat_j), np.where(ahead, j, n)


def occupied_band(heading: np.ndarray, length: float, width: float, widest_agent: float, agent_radius: float
                  ) -> np.ndarray:
    """[m] per rollout: how far from a lane's centre line the ego's centre (``heading`` against it, ``length`` x
    ``width``) may be and still be in the way of an agent keeping to that centre line (its body, turned as it is,
    reaches half the widest agent's width from it), at least the agents' own band (``agent_radius`` [m]). A car stopped at an angle
    half-way into a lane blocks it."""
    reach = 0.5 * extent_across(length, width, np.cos(heading), np.sin(heading))
    return np.maximum(agent_radius, reach + 0.5 * widest_agent)


def lane_end_leader(frame: RoadFrame, chain: np.ndarray, s: np.ndarray, length: np.ndarray, gap: np.ndarray,
              v_lead: np.ndarray, margin: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A lane that ends is a stopped leader ``margin`` m before its end (new arrays: the caller writes into them)."""
    if np.isinf(frame.end_s).all():  # no lane of the frame ends (the common case: skip the look-ups)
        return gap.copy(), v_lead.copy()
    return stopped_leader(frame.end_s[chain] - margin - s - 0.5 * length[None, :], gap, v_lead)


def stopped_leader(stop_gap: np.ndarray, gap: np.ndarray, v_lead: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(gap, leader speed) with a standing obstacle ``stop_gap`` [m] ahead taking the leader's place where nearer."""
    closer = stop_gap < gap
    return np.where(closer, stop_gap, gap), np.where(closer, 0.0, v_lead)
