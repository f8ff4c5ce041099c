"""Lane-change navigation rules of the EPSILON planner around the DCP-tree (docs/planner.md step 6 and "Not timid"):
when the route or a lane's end makes a change mandatory and to which side; which sides an owed lateral response
rules out; the gap the ego keeps behind a car that cut in; when a discretionary change that cannot get going is
called off. Units: m, s, m/s."""
from __future__ import annotations

import numpy as np

from ..rss.owed_responses import OwedResponses
from ..sim.snapshot import WorldSnapshot
from .behavior.dcp_tree import Lat, Policy
from .behavior.evaluation import TARGET_CHAIN
from .behavior.forward_sim import SimResult, Vehicles
from .behavior.key_vehicles import KeyVehicles
from .behavior.manager import LaneChangeContext
from .lanes import CURRENT, LEFT, RIGHT
from .road_frame import RoadFrame

# A lane change the route makes mandatory is due this far before the lane ends, per change still to make: the larger
# of [m] and [s] at the ego's speed (a change takes ~6-7 s: 4 consistent cycles, >= 2 s to its operation time, ~3 s
# to cross).
MANDATORY_REACH_M, MANDATORY_REACH_S = 200.0, 10.0
# [m] kept beyond the gap a car that cut in left, while its episode's lateral duty holds the ego behind it, where it
# is slower than the ego's reference speed by DROP_BACK_SLOWER [m/s] or more.
DROP_BACK_M, DROP_BACK_SLOWER = 10.0, 3.0
# A lane change is held while the ego is within STILL_IN_LANE_M [m] of its lane's centre and no rollout moves it
# CHANGE_PROGRESS_M [m] towards the target lane within the horizon: a discretionary one is then called off, a
# mandatory one seeks a gap.
STILL_IN_LANE_M, CHANGE_PROGRESS_M = 0.3, 0.5
# [m/s] A held mandatory change seeks its gap this much slower than the slower of the target lane's nearest cars
# ahead of and behind the ego, so that the gaps come by (docs/planner.md, "highway_exit on seeds 0-19").
SEEK_SLOWER = 5.0


def mandatory_change(frame: RoadFrame, s_ego: float, v: float) -> Lat | None:
    """The direction the ego (centre at ``s_ego`` in ``frame``, speed ``v``) must change to when its lane ends, or
    leaves its route, within reach: the route's side (the fewest lane changes to its end,
    :func:`.route_lanes.lane_changes_needed`), else the side that exists (left first). The reach grows with the
    changes still to make: max(MANDATORY_REACH_M, MANDATORY_REACH_S·v) per change."""
    end = float(frame.end_s[CURRENT])
    here, total = frame.chains.changes
    if not np.isfinite(end) or end - s_ego >= max(total, 1) * max(MANDATORY_REACH_M, MANDATORY_REACH_S * v):
        return None
    if here:
        return Lat.LEFT if here > 0 else Lat.RIGHT
    if total:  # the changes are to be made on an edge ahead (e.g. into a deceleration lane that starts there)
        return None
    if frame.exists[LEFT]:
        return Lat.LEFT
    if frame.exists[RIGHT]:
        return Lat.RIGHT
    return None


def held_sides(owed: OwedResponses | None) -> frozenset[Lat]:
    """The sides towards which the ego owes a lateral response in an open episode (it may not move that way)."""
    if owed is None or not np.any(owed.owed_lat):
        return frozenset()
    return frozenset(Lat.LEFT if left else Lat.RIGHT for left in owed.other_is_left[owed.owed_lat])


def cut_in_gaps(snapshot: WorldSnapshot, key: KeyVehicles, vehicles: Vehicles, owed: OwedResponses | None,
                frame: RoadFrame, v_ref: float) -> np.ndarray | None:
    """[m] per vehicle column: the bumper gap now to a car ahead that the ego owes no longitudinal braking in an
    open episode (inf elsewhere; None: no such car). Such a car cut in: RSS puts its gap on that car (rss.md §5), so
    the ego keeps the gap it was left, not the RSS distance, and lets it grow back as the car pulls away, rather
    than braking to restore the distance at once. But where that car is slower than the ego's reference speed
    ``v_ref`` [m/s] by DROP_BACK_SLOWER or more and the episode's lateral duty holds the ego in its lane on a side
    where a lane is (the episode lasts until the gap is RSS-safe again), the ego keeps DROP_BACK_M more than the
    gap: it drops back until the episode ends and it may pass (behind a car at its own speed the gap would never
    grow back)."""
    cut_in = owed.without_lon_duty() if owed is not None else frozenset()
    if not cut_in:
        return None
    gap = vehicles.s[1:] - vehicles.s[0] - 0.5 * (vehicles.length[0] + vehicles.length[1:])
    ids = snapshot.ids[key.rows]
    ahead = np.isin(ids, list(cut_in)) & (gap >= 0.0)
    if not np.any(ahead):
        return None
    side_exists = np.where(owed.other_is_left, frame.exists[LEFT], frame.exists[RIGHT])
    holding = np.isin(ids, owed.other_id[owed.owed_lat & side_exists]) & \
        (snapshot.speed[key.rows] < v_ref - DROP_BACK_SLOWER)
    return np.concatenate([[np.inf], np.where(ahead, np.where(holding, gap + DROP_BACK_M, gap), np.inf)])


def change_held(direction: Lat, policies: list[Policy], policy_of: np.ndarray, sim: SimResult, offset: float,
                still_in_lane: float = STILL_IN_LANE_M) -> bool:
    """Whether a lane change towards ``direction`` has not begun (the ego within ``still_in_lane`` [m] of its lane's
    centre, ``offset`` [m]) and no rollout of that direction gets going within the horizon (CHANGE_PROGRESS_M towards
    the target lane): the virtual barrier holds every one of them (the gap is not RSS-safe). Where the ego's lane ends
    a held mandatory change waits off its lane's centre, ready beside the gap (:func:`.behavior.lane_change.
    ready_offset`): it is asked with ``still_in_lane`` = inf, the rollouts' progress alone deciding."""
    if abs(offset) > still_in_lane:
        return False
    side = 1.0 if direction is Lat.LEFT else -1.0
    mine = np.flatnonzero(np.isin(policy_of, [k for k, p in enumerate(policies) if p.lateral is direction]))
    return bool(mine.size) and not np.any(side * (sim.d[mine, -1, 0] - sim.d[mine, 0, 0]) >= CHANGE_PROGRESS_M)


def change_stuck(context: LaneChangeContext | None, now: float, policies: list[Policy], policy_of: np.ndarray,
                 sim: SimResult, offset: float) -> bool:
    """Whether to call off the discretionary lane change of ``context``: it is due but held
    (:func:`change_held`). Its recommended reward (epsilon.md §4.1) would otherwise keep the ego "changing" beside
    the gap until the context expires 15 s after its operation time, and a pure lane keep is not in the tree
    meanwhile. A mandatory change keeps waiting for its gap (:func:`seek_speed`)."""
    if context is None or context.mandatory or now < context.operation_time - 1e-9:
        return False
    return change_held(context.direction, policies, policy_of, sim, offset)


def seek_speed(vehicles: Vehicles, direction: Lat) -> float:
    """[m/s] The speed at which a held mandatory change towards ``direction`` seeks its gap: SEEK_SLOWER below the
    slower of the nearest cars ahead of and behind the ego (column 0 of ``vehicles``) in the target lane (inf: no car
    there). Beside the target lane's traffic at its speed the gap beside the ego never changes, and under RSS it is
    rarely long enough (~240 m at 30 m/s under ad_rss); slower, the ego lets the cars pass until a gap behind them
    is RSS-safe, and being slower than the cars around the gap shortens the gap it needs (the rear car's distance
    grows, the front car's falls faster). The evasive speed-up into the nearest gap (epsilon.md §3.6) is off
    meanwhile: it would keep the ego beside the car it cannot cut in front of."""
    target = TARGET_CHAIN[direction]
    ds = vehicles.s[1:] - vehicles.s[0]
    in_lane = vehicles.chain[1:] == target
    speeds = vehicles.speed[1:]
    nearest = [speeds[side][np.argmin(np.abs(ds[side]))] for side in (in_lane & (ds >= 0.0), in_lane & (ds < 0.0))
               if np.any(side)]
    return max(min(nearest) - SEEK_SLOWER, 0.0) if nearest else np.inf
