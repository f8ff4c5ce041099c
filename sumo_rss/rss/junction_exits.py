"""Cars leaving a junction: the front bumper on the exit lane, the rear still on the link's internal lanes.

Such a car has not left the conflict areas its rear is in (rss.md §4: d_exit is measured from the rear bumper), so
it stays an entry of the link it came by, at its front bumper's position along the link's path (link length + lane
position). A snapshot names only the lane the front bumper is on; the link is the one into that lane whose
rear-bumper point (``length`` - lane position back along the link's path) lies nearest the line through the front
bumper along the car's angle: SUMO's angle is the direction from the car's back position (on the internal lane it
came by) to its front. A car whose line passes farther than REAR_OFF_LINK from every link's point (a lane change onto
the exit lane, a teleport) is not placed on any. Units: m.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..road.junctions import JunctionModel
from ..road.link_pairs import expand_ranges
from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot

REAR_OFF_LINK = 1.0  # [m] farthest the link's rear-bumper point may lie from the car's line (less than half a lane)


@dataclass(frozen=True, eq=False)
class ExitLinks:
    """The links into each lane and their internal lanes, as arrays."""

    indptr: np.ndarray  # [lanes + 1] links into lane k: links[indptr[k]:indptr[k + 1]]
    links: np.ndarray  # link indices sorted by the lane they lead into
    path: np.ndarray  # [L, P] a link's internal lanes in driving order, -1 padded
    offset: np.ndarray  # [L, P] where each starts along the link's path [m], +inf padded
    from_lane: np.ndarray  # [L] the lane each link starts from


@lru_cache(maxsize=8)
def exit_links(junctions: JunctionModel) -> ExitLinks:
    """The junction model's :class:`ExitLinks` (built once per model)."""
    links = np.flatnonzero(junctions.link_length > 0.0)  # a link without internal lanes has no area to be in
    links = links[np.argsort(junctions.link_to_lane[links], kind="stable")]
    indptr = np.searchsorted(junctions.link_to_lane[links], np.arange(junctions.lane_link.size + 1))
    width = max((len(link.path) for link in junctions.links), default=1)
    path = np.full((len(junctions.links), width), -1, dtype=np.int64)
    offset = np.full(path.shape, np.inf)
    for k, link in enumerate(junctions.links):
        path[k, :len(link.path)] = link.path
        offset[k, :len(link.path)] = junctions.lane_link_offset[list(link.path)]
    return ExitLinks(indptr=indptr, links=links, path=path, offset=offset,
                     from_lane=np.array([link.from_lane for link in junctions.links], dtype=np.int64))


def with_leaving(entries: tuple[np.ndarray, np.ndarray, np.ndarray], snapshot: WorldSnapshot, lane: np.ndarray,
                 lane_pos: np.ndarray, network: RoadNetwork, junctions: JunctionModel
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``entries`` (vehicle rows, links, positions along the links' paths [m]) followed by the
    :func:`leaving_entries` of the step's cars."""
    leaving = leaving_entries(snapshot, lane, lane_pos, network, junctions)
    if not leaving[0].size:
        return entries
    rows, links, pos = (np.concatenate(pair) for pair in zip(entries, leaving))
    return rows, links, pos


def leaving_entries(snapshot: WorldSnapshot, lane: np.ndarray, lane_pos: np.ndarray, network: RoadNetwork,
                    junctions: JunctionModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entries (vehicle row, link, front bumper along the link's path [m]) of the cars on a normal lane (``lane``,
    front bumper at ``lane_pos``) whose rear bumper is still on the internal lanes of a link into it."""
    table = exit_links(junctions)
    cars = np.flatnonzero((junctions.lane_link[lane] < 0) & (lane_pos < snapshot.length))
    owner, at = expand_ranges(table.indptr[lane[cars]], table.indptr[lane[cars] + 1])
    if not at.size:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    rows, links = cars[owner], table.links[at]
    # Where the rear bumper would be along each candidate link's path, on which of its internal lanes, or on the
    # lane the link starts from (a car longer than the link).
    s = junctions.link_length[links] - (snapshot.length[rows] - lane_pos[rows])
    part = np.maximum(np.sum(table.offset[links] <= s[:, None], axis=1) - 1, 0)
    on = np.where(s < 0.0, table.from_lane[links], table.path[links, part])
    along = np.where(s < 0.0, network.lane_length[on] + s, s - table.offset[links, part])
    along = np.clip(along, 0.0, network.lane_length[on])
    x, y = network.shapes.point_at(on, network.shapes.shape_s(on, along), np.zeros(len(rows)))
    # How far that point is from the line through the front bumper along the car's angle (the chord from SUMO's
    # back position: on a curve shorter than the length along the lanes).
    cos, sin = np.cos(snapshot.heading[rows]), np.sin(snapshot.heading[rows])
    off = np.abs((x - snapshot.x[rows]) * sin - (y - snapshot.y[rows]) * cos)
    # Per car the nearest link, if near enough.
    order = np.lexsort((off, rows))
    nearest = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
    nearest = nearest[off[nearest] <= REAR_OFF_LINK]
    return rows[nearest], links[nearest], junctions.link_length[links[nearest]] + lane_pos[rows[nearest]]
