"""Where the ego must stop before a junction (epsilon.md port decision 5: red lights and yield lines are
semantic constraints; a stop line is an s upper bound of the ego's motion).

The ego approaching a junction on its route stops at the stop line (the end of its lane):
- on **red**, and on **yellow** when it can still stop there at its RSS b_min (rss.md's signal rule);
- to **yield** to a vehicle on a conflicting link that has priority over the ego's link (by the signals where
  both links are signalised and their states differ, else by the junction's static priority), unless that
  vehicle reaches the conflict area only ``YIELD_MARGIN`` s or more after the ego would have cleared it;
- never once it can no longer stop at the line at its RSS b_max (it drives on; the RSS guard still applies).
Vehicles on conflicting approaches are the junction's key vehicles for this rule. Pure numpy, no libsumo.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..road.junctions import JunctionModel
from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot

STOP_RANGE = 150.0  # [m] stop lines farther ahead than this are not considered yet
STOP_MARGIN = 1.0  # [m] the front bumper stops this far before the line
YIELD_MARGIN = 2.0  # [s] time a prioritised vehicle must arrive after the ego has cleared their conflict area
CLEAR_ACCEL = 1.5  # [m/s²] acceleration assumed for the ego crossing the junction
MIN_SPEED = 0.5  # [m/s] slower vehicles outside the junction are waiting, not arriving
RED, YELLOW = "rRs", "yYu"  # SUMO signal characters that stop the ego


@dataclass(frozen=True)
class StopLine:
    """``distance`` [m] from the ego's front bumper to where it must stop (inf: drive on), and why."""

    distance: float
    reason: str  # 'red' | 'yellow' | 'yield' | '' (none)


NO_STOP = StopLine(np.inf, "")


def _next_edges(snapshot: WorldSnapshot, network: RoadNetwork) -> np.ndarray:
    """[n] index of each vehicle's next route edge (-1: unknown or none)."""
    out = np.full(len(snapshot), -1, dtype=int)
    if snapshot.route_edges is None:
        return out
    for i, (route, at) in enumerate(zip(snapshot.route_edges, snapshot.route_index.tolist())):
        if 0 <= at < len(route) - 1:
            out[i] = int(network.edge_indices([route[at + 1]])[0])
    return out


def _links(junctions: JunctionModel, network: RoadNetwork, lanes: np.ndarray, lane_pos: np.ndarray,
           next_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each vehicle's link through the junction ahead (-1: none) and its front bumper's position along the link
    [m] (negative before the stop line): the link it is on, or the one from its lane to its route's next edge."""
    inside = junctions.lane_link[lanes]
    cand = junctions.lane_links[lanes]  # [n, k]
    to_edge = junctions.link_to_edge[np.maximum(cand, 0)]
    match = (cand >= 0) & (to_edge == next_edges[:, None])
    approach = np.where(match.any(axis=1), cand[np.arange(lanes.size), match.argmax(axis=1)], -1)
    link = np.where(inside >= 0, inside, approach)
    pos = np.where(inside >= 0, junctions.lane_link_offset[lanes] + lane_pos, lane_pos - network.lane_length[lanes])
    return link, pos


def _time_to_cover(v: float, distance: float, accel: float) -> float:
    """[s] to drive ``distance`` [m] from speed ``v`` [m/s] at constant ``accel`` [m/s²]."""
    return float((-v + np.sqrt(v * v + 2.0 * accel * max(distance, 0.0))) / accel)


def stop_line(snapshot: WorldSnapshot, ego: int, network: RoadNetwork, junctions: JunctionModel,
              b_min: float, b_max: float) -> StopLine:
    """Whether and where the ego (snapshot row ``ego``) must stop before the junction ahead; ``b_min``/``b_max``
    [m/s²] are its RSS braking: it stops for yellow if it can at b_min, and for anything if it can at b_max."""
    lanes = network.lane_indices(snapshot.lane_id)
    link, pos = _links(junctions, network, lanes, snapshot.lane_pos, _next_edges(snapshot, network))
    own = int(link[ego])
    distance = -float(pos[ego]) - STOP_MARGIN
    if own < 0 or junctions.lane_link[lanes[ego]] >= 0 or distance > STOP_RANGE:
        return NO_STOP
    v = float(snapshot.speed[ego])
    if distance < v * v / (2.0 * b_max):  # too late to stop at the line: committed
        return NO_STOP
    ranks = junctions.signal_ranks(snapshot.tls_states)
    tls = junctions.link_tls[own]
    if tls and snapshot.tls_states and tls in snapshot.tls_states:
        state = snapshot.tls_states[tls][junctions.link_tls_index[own]]
        if state in RED:
            return StopLine(distance, "red")
        if state in YELLOW and distance >= v * v / (2.0 * b_min):
            return StopLine(distance, "yellow")
    foes = np.flatnonzero((link >= 0) & (np.arange(link.size) != ego))
    foes = foes[junctions.area_index[own, link[foes]] >= 0]
    if foes.size == 0:
        return NO_STOP
    fl = link[foes]
    by_signal = (ranks[own] >= 0) & (ranks[fl] >= 0) & (ranks[fl] != ranks[own])
    prioritised = np.where(by_signal, ranks[fl] > ranks[own], junctions.static_priority[own, fl] < 0)
    start, end = junctions.area_start[fl, own], junctions.area_end[fl, own]  # along each foe's link
    f_pos, f_v = pos[foes], snapshot.speed[foes]
    inside_area = (f_pos >= start) & (f_pos - snapshot.length[foes] <= end)
    arriving = (f_pos < start) & ((f_v >= MIN_SPEED) | (f_pos >= 0.0))
    t_foe = np.where(inside_area, 0.0, (start - f_pos) / np.maximum(f_v, MIN_SPEED))
    clear = -float(pos[ego]) + float(np.max(junctions.area_end[own, fl])) + float(snapshot.length[ego])
    t_clear = _time_to_cover(v, clear, CLEAR_ACCEL)
    if np.any(prioritised & (inside_area | (arriving & (t_foe < t_clear + YIELD_MARGIN)))):
        return StopLine(distance, "yield")
    return NO_STOP
