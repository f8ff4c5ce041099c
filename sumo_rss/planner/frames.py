"""The ego's planning lane and its Frenet frame along the ego's route, cached per run: shared by the EPSILON
planner and by the RSS guard of a SUMO-driven ego (``controller = "sumo_restricted"``)."""
from __future__ import annotations

import numpy as np

from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .lanes import LEFT, RIGHT, lane_chains
from .road_frame import RoadFrame

MAX_CACHED_FRAMES = 64


class PlanningFrames:
    """One per ego and run: frames by (lane, remaining route), the last lane choice and the last ego centre."""

    def __init__(self, network: RoadNetwork):
        self.network = network
        self._frames: dict[tuple[int, tuple[int, ...]], RoadFrame] = {}
        self._last_lane: tuple[WorldSnapshot, int, tuple[int, RoadFrame]] | None = None
        self._last_centre: tuple[WorldSnapshot, int, RoadFrame, tuple[np.ndarray, ...]] | None = None

    def planning_lane(self, snapshot: WorldSnapshot, ego: int) -> tuple[int, RoadFrame]:
        """The ego's lane for planning and its frame: the lane nearest to the ego's centre (epsilon.md §2.5 step
        4), i.e. SUMO's lane or its neighbour on the edge. SUMO puts a vehicle on the lane under its front bumper,
        so half-way through a lane change its centre may still be in the lane it leaves. The last answer is kept:
        the guard asks again for the snapshot just planned on."""
        last = self._last_lane
        if last is not None and last[0] is snapshot and last[1] == ego:
            return last[2]
        lane = int(self.network.lane_indices(snapshot.lane_id[ego:ego + 1])[0])
        route = snapshot.route_edges[ego][int(snapshot.route_index[ego]):] if snapshot.route_edges else ()
        edges = tuple(self.network.edge_indices(route).tolist())
        frame = self._frame(lane, edges)
        s, d, _ = self.ego_centre(snapshot, ego, frame)
        side = {LEFT: self.network.lane_left, RIGHT: self.network.lane_right}.get(int(frame.nearest_chain(s, d)[0]))
        if side is not None and side[lane] >= 0:
            lane = int(side[lane])
            frame = self._frame(lane, edges)
        self._last_lane = (snapshot, ego, (lane, frame))
        return lane, frame

    def ego_centre(self, snapshot: WorldSnapshot, ego: int, frame: RoadFrame
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ego's centre (s, d, heading_rel) [1] in ``frame`` from its front bumper (the last answer is kept:
        the lane choice and the vehicle setup both ask, mostly in the same frame). Read-only arrays."""
        last = self._last_centre
        if last is not None and last[0] is snapshot and last[1] == ego and last[2] is frame:
            return last[3]
        centre = frame.centre_of_bumper(snapshot.x[ego], snapshot.y[ego], snapshot.heading[ego],
                                        0.5 * float(snapshot.length[ego]))
        for array in centre:
            array.flags.writeable = False
        self._last_centre = (snapshot, ego, frame, centre)
        return centre

    def _frame(self, lane: int, edges: tuple[int, ...]) -> RoadFrame:
        """The frame around ``lane`` along the route ``edges`` (cached)."""
        frame = self._frames.get((lane, edges))
        if frame is None:
            if len(self._frames) > MAX_CACHED_FRAMES:
                self._frames.clear()
            frame = RoadFrame.build(lane_chains(self.network, lane, np.array(edges, dtype=int)))
            self._frames[(lane, edges)] = frame
        return frame
