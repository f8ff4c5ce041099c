"""Persons as road users (rss.md §10): a person on a crossing and a vehicle whose path crosses it.

The crossing is the conflict area (:mod:`~sumo_rss.road.crossings`): the vehicle's d_enter / d_exit run along its
link's path, the person's along the crossing in its walking direction (a person walks either way). Priority comes
from the crossing's link: SUMO's junction logic (a zebra gives the person priority), at signals the two links'
states (G over g over the rest). Safety is the intersection test of rss.md §4 with the person's own parameters, so
the responses owed and the blame follow as for two cars.

Persons on walking areas and sidewalks form no situation with vehicles (the paper's "vehicles need not worry about
pedestrians on the sidewalk"); persons are not paired with persons. A person on an edge without a sidewalk walks
on a vehicle lane: :mod:`.jaywalking` (the paper's heading-change wedge).
"""
from __future__ import annotations

import collections
import itertools
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..angles import wrap_angle
from ..road.crossings import CrossingEntries, CrossingModel
from ..road.junctions import JunctionModel
from ..road.link_pairs import expand_ranges
from ..road.network import RoadNetwork
from ..road_users import PERSON_CLASS
from ..sim.persons import PersonSnapshot
from ..sim.snapshot import WorldSnapshot
from .intersection import junction_entries, next_route_edge
from .jaywalking import AREA_ID as JAYWALK_AREA, jaywalking_situations
from .junction_exits import with_leaving
from .params import PARAM_NAMES, RssParamArrays
from .person_pairs import Side, vehicle_person_situations
from .situations import PairSituations, VehicleFrame
from .sorted_keys import find_sorted

# [rad] a person at a crossing's end who faces within this of the crossing's direction may step onto it (SUMO's
# persons turn towards a crossing on the walking area before they step on; one walking along the kerb or towards
# the other crossing of a corner faces 90° away)
STEP_ON_ANGLE = np.radians(60.0)
SPEED_WINDOW_S = 0.5  # [s] persons' accelerations are speed changes over this long (a person's ρ; _accelerations)
TIME_EPS = 1e-6  # [s]
STEP_ON_RADIUS = 10.0  # [m] persons this close to a crossing's end are in its situations (7 s at 1.4 m/s)


@dataclass(frozen=True, eq=False)
class RoadUsers:
    """The vehicles of a step followed by its persons, in one row space (what the responsibility tracker reads;
    situations name their rows)."""

    ids: np.ndarray  # str
    vclass: np.ndarray  # str
    accel: np.ndarray  # [m/s²]
    speed: np.ndarray  # [m/s]
    params: RssParamArrays
    vehicles: int  # rows [0, vehicles) are the snapshot's vehicles
    on_road: np.ndarray  # per person: walking on a vehicle lane (an edge without a sidewalk)


def _stacked(a: RssParamArrays, b: RssParamArrays) -> RssParamArrays:
    return RssParamArrays(*(np.concatenate([getattr(a, name), getattr(b, name)]) for name in PARAM_NAMES))


class PersonAudit:
    """Person rows and person situations of each step of one run (time order)."""

    def __init__(self, network: RoadNetwork, junctions: JunctionModel):
        self.network, self.junctions = network, junctions
        # The persons' speeds at the steps of the last SPEED_WINDOW_S: (time [s], ids sorted, speeds [m/s]).
        self._speeds: collections.deque[tuple[float, np.ndarray, np.ndarray]] = collections.deque()

    @cached_property
    def crossings(self) -> CrossingModel:
        """The network's crossings (read when the first person appears: an audit without persons never needs
        them)."""
        return CrossingModel.from_file(self.network.path, self.network, self.junctions)

    @cached_property
    def _entries(self) -> CrossingEntries:
        return CrossingEntries.of(self.crossings, self.network.shapes)

    @cached_property
    def _sorted_area_ids(self) -> np.ndarray:
        return np.sort(self.crossings.area_id.astype(str))

    def area_numbers(self, area: np.ndarray) -> np.ndarray:
        """A number per area id of ``area`` (fixed for the run): a crossing area's rank among the network's, one
        more for a person on a vehicle lane."""
        area = area.astype(str)
        return np.where(np.char.endswith(area, ":" + JAYWALK_AREA), len(self._sorted_area_ids),
                        np.searchsorted(self._sorted_area_ids, area))

    def users(self, snapshot: WorldSnapshot, params: RssParamArrays, person_params: RssParamArrays) -> RoadUsers:
        """The step's road users: ``snapshot``'s vehicles with their ``params``, then its persons with
        ``person_params`` and their accelerations (:meth:`_accelerations`)."""
        persons = snapshot.persons
        if persons is None or not len(persons):
            self._speeds.clear()
            return RoadUsers(snapshot.ids, snapshot.vclass, snapshot.accel, snapshot.speed, params, len(snapshot),
                             np.zeros(0, dtype=bool))
        accel = self._accelerations(snapshot.time, persons)
        return RoadUsers(np.concatenate([snapshot.ids, persons.ids]),
                         np.concatenate([snapshot.vclass, np.full(len(persons), PERSON_CLASS)]),
                         np.concatenate([snapshot.accel, accel]), np.concatenate([snapshot.speed, persons.speed]),
                         _stacked(params, person_params), len(snapshot),
                         ~find_sorted(self.crossings.walkway_edges, persons.edge_id.astype(str))[0])

    def _accelerations(self, time: float, persons: PersonSnapshot) -> np.ndarray:
        """[m/s²] each person's speed change over the last SPEED_WINDOW_S (over the steps it was seen in, 0 for a
        person first seen now). SUMO's persons have no acceleration: their speed jitters from step to step by up to
        ±0.1 m/s (the striping model's dawdling), ±2 m/s² as a difference over one 0.1 s step, as much as a person's
        whole a_acc; over 0.5 s (a person's ρ) it is ±0.4 m/s²."""
        order = np.argsort(persons.ids)
        self._speeds.append((time, persons.ids[order], persons.speed[order]))
        while len(self._speeds) > 1 and self._speeds[1][0] <= time - SPEED_WINDOW_S + TIME_EPS:
            self._speeds.popleft()
        accel = np.zeros(len(persons))
        left = np.ones(len(persons), dtype=bool)  # not yet found at an earlier step
        for then, ids, speed in self._speeds:  # oldest first: the longest span each person was seen over
            if then >= time:
                break
            pos = np.minimum(np.searchsorted(ids, persons.ids), len(ids) - 1)
            hit = left & (ids[pos] == persons.ids)
            accel[hit] = (persons.speed[hit] - speed[pos[hit]]) / (time - then)
            left &= ~hit
        return accel

    def situations(self, snapshot: WorldSnapshot, frame: VehicleFrame, users: RoadUsers,
                   horizon: float) -> PairSituations | None:
        """The step's person situations (rows of ``users``; None without any): on crossings
        (:meth:`_crossing_situations`) and on vehicle lanes (:func:`~.jaywalking.jaywalking_situations`)."""
        persons = snapshot.persons
        if persons is None or not len(persons):
            return None
        parts = [self._crossing_situations(snapshot, frame, users, horizon)]
        if users.on_road.any():
            parts.append(jaywalking_situations(persons, users.on_road, frame, snapshot.ids, snapshot.length,
                                               self.network, users.params, users.vehicles))
        parts = [part for part in parts if part is not None]
        return parts[0] if len(parts) == 1 else PairSituations.concat(parts) if parts else None

    def _crossing_situations(self, snapshot: WorldSnapshot, frame: VehicleFrame, users: RoadUsers,
                             horizon: float) -> PairSituations | None:
        """Every (vehicle, person on a crossing) pair whose paths meet in a crossing area that neither has left,
        one situation per pair and area (rows of ``users``; None without any). Vehicles within ``horizon`` [m] of
        a junction take part, as in :func:`~sumo_rss.rss.intersection.intersection_situations`."""
        persons, model = snapshot.persons, self.crossings
        if persons is None or not len(persons) or not len(model):
            return None
        walking, crossing, s, forward, v_along = self._on_crossings(persons)
        if not walking.size:
            return None
        # Vehicles' entries into links (also a car leaving the junction whose rear is still on its link, as in
        # intersection_situations), and their crossing areas with a person on that crossing.
        rows, links, pos = with_leaving(
            junction_entries(frame.lane, frame.lane_pos, next_route_edge(frame.route_edges, frame.edge), self.network,
                             self.junctions, horizon), snapshot, frame.lane, frame.lane_pos, self.network,
            self.junctions)
        entry, k = model.areas_of_links(links)
        by_crossing = np.argsort(crossing, kind="stable")
        on = crossing[by_crossing]
        pair, hit = expand_ranges(np.searchsorted(on, model.crossing[k], side="left"),
                                  np.searchsorted(on, model.crossing[k], side="right"))
        entry, k, w = entry[pair], k[pair], by_crossing[hit]  # w: into ``walking``
        if not k.size:
            return None
        r, p = rows[entry], walking[w]
        length = snapshot.length[r]
        enter_v, exit_v = model.link_start[k] - pos[entry], model.link_end[k] - pos[entry] + length
        s_w, fwd, p_length, v_p = s[w], forward[w], persons.length[p], v_along[w]
        enter_p = np.where(fwd, model.cross_start[k] - s_w, s_w - model.cross_end[k])
        exit_p = np.where(fwd, model.cross_end[k] - s_w, s_w - model.cross_start[k]) + p_length
        keep = (exit_v > 0.0) & (exit_p > 0.0)
        if not keep.any():
            return None
        r, p, k, link = r[keep], p[keep], k[keep], links[entry[keep]]
        enter_v, exit_v, enter_p, exit_p, length, p_length, v_p = (x[keep] for x in (
            enter_v, exit_v, enter_p, exit_p, length, p_length, v_p))
        vehicle_first, by_signal = self._priority(snapshot.tls_states, link, model.crossing[k],
                                                  model.static_priority[k])
        return vehicle_person_situations(
            Side(r, snapshot.ids[r], np.maximum(frame.v_lon[r], 0.0), enter_v, exit_v, length),
            Side(users.vehicles + p, persons.ids[p], v_p, enter_p, exit_p, p_length), vehicle_first, by_signal,
            users.params, model.area_id[k])

    def _on_crossings(self, persons: PersonSnapshot
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(person row, crossing, s [m] along the crossing's centre line, walking forward along it, speed along
        that walking direction [m/s], ≥ 0) of every person
        on a crossing, and of every person within STEP_ON_RADIUS of a crossing's end who faces along it (s < 0 before
        its start, > its length past its end). Which crossing a person takes is not known (an FCD has no routes of
        persons): its position and heading tell, the same way online and offline."""
        model = self.crossings
        at = np.minimum(np.searchsorted(model.edge_ids, persons.edge_id), len(model.edge_ids) - 1)
        on = np.flatnonzero(model.edge_ids[at] == persons.edge_id)
        crossing = at[on]
        s, _, lane_heading = self.network.frenet(model.lane[crossing], persons.x[on], persons.y[on])
        cos_on = np.cos(wrap_angle(persons.heading[on] - lane_heading))
        forward = cos_on >= 0.0
        # Persons near a crossing's end, facing along it (within STEP_ON_ANGLE of the way they would walk it) and
        # not past it: they may step onto it. One walking elsewhere (along the kerb, onto the other crossing of a
        # corner) faces 90° away.
        entries = self._entries
        entry_crossing, entry_forward, point, along = entries.crossing, entries.forward, entries.point, entries.along
        near = entries.tree.query_ball_point(np.column_stack([persons.x, persons.y]), STEP_ON_RADIUS) \
            if entries.tree is not None else [[] for _ in range(len(persons))]
        count = np.fromiter(map(len, near), int, len(persons))
        who = np.repeat(np.arange(len(persons)), count)
        e = np.fromiter(itertools.chain.from_iterable(near), int, int(count.sum()))
        c = entry_crossing[e]
        dx, dy = point[e, 0] - persons.x[who], point[e, 1] - persons.y[who]
        cos_at = np.cos(wrap_angle(persons.heading[who] - along[e]))
        facing = cos_at > np.cos(STEP_ON_ANGLE)
        ahead = dx * np.cos(along[e]) + dy * np.sin(along[e]) > -0.5 * persons.length[who]
        towards = facing & ahead & (model.edge_ids[c] != persons.edge_id[who])
        distance = np.hypot(dx, dy)
        s_at = np.where(entry_forward[e], -distance, entries.length[e] + distance)
        return (np.concatenate([on, who[towards]]), np.concatenate([crossing, c[towards]]),
                np.concatenate([s, s_at[towards]]), np.concatenate([forward, entry_forward[e][towards]]),
                np.maximum(np.concatenate([persons.speed[on] * np.abs(cos_on), persons.speed[who[towards]] *
                                           cos_at[towards]]), 0.0))

    def _priority(self, tls_states: dict[str, str] | None, link: np.ndarray, crossing: np.ndarray,
                  static: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(+1: the vehicle has priority, -1: the person, 0: neither; whether the signals decided it). The signals
        decide where both links are signalised and their ranks differ, else the junction's logic (``static``); a
        signalised link whose state is unknown gives no priority either way."""
        vehicle_rank = self.junctions.signal_ranks(tls_states)[link]
        person_rank = self.crossings.signal_ranks(tls_states)[crossing]
        index = self.crossings.tls_index[crossing]
        by_signal = (vehicle_rank >= 0) & (person_rank >= 0) & (vehicle_rank != person_rank)
        unknown = ((self.junctions.link_tls_index[link] >= 0) & (vehicle_rank < 0)) | ((index >= 0) &
                                                                                        (person_rank < 0))
        first = np.where(unknown, 0, static)
        return np.where(by_signal, np.sign(vehicle_rank - person_rank), first).astype(int), by_signal
