"""Traffic signals in the audit: the red/yellow-light rule and signal states for offline audits.

The rule (beyond the paper; on by default): a car that crosses the stop line of a signalised link while it is
red, or while it is yellow although the car could have stopped at b_min when it turned yellow, commits a
violation of its own kind (no pair episode needed).

Offline, signal states come from SUMO's signal-state output (written by a ``SaveTLSStates`` timed event) when
given, else from the network's own programs when they are fixed-time; other programs are unknown, and their links
are treated as equal priority.
"""
from __future__ import annotations

import warnings
from bisect import bisect_right
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np

from ..road.junctions import JunctionModel
from ..road.model_cache import cached
from ..road.net_file import signal_programs
from ..road.network import RoadNetwork
from ..road.topology import read_topology
from ..sim.snapshot import WorldSnapshot
from ..sumo_xml import MALFORMED, output_elements
from .intersection import next_route_edge
from .record_checks import signal_state
from .sorted_keys import find_sorted
from .situations import VehicleFrame

RED, YELLOW = "rRu", "yY"  # u: red-yellow, SUMO lets no car pass yet
# A car that moved farther in a step than its speeds allow (plus this acceleration and slack) was teleported by SUMO
# (a jam: "waited too long"), possibly past a stop line: that is no entry to judge.
TELEPORT_ACCEL, TELEPORT_SLACK = 10.0, 1.0  # [m/s²], [m]


class SignalConstraint(str, Enum):
    """Signal violations (values go into violations.csv, role 'signal', bound 0 m/s, actual = entry speed)."""

    RED_LIGHT = "signal-red-light"  # crossed the stop line on red
    YELLOW_LIGHT = "signal-yellow-light"  # crossed on yellow although it could have stopped at b_min


class SignalRule:
    """Watches every car approaching a signalised link and reports red- and yellow-light entries."""

    def __init__(self, network: RoadNetwork, junctions: JunctionModel, run_id: str = ""):
        self.network = network
        self.junctions = junctions
        self.run_id = run_id
        self.records: list[dict] = []
        self._approach = _Approach.empty(junctions.lane_links.shape[1])  # the cars approaching at the step before
        self._time: float | None = None  # [s] of the step before

    def step(self, snapshot: WorldSnapshot, frame: VehicleFrame) -> None:
        """SUMO's signal states at a step are those its cars moved under to get there: a car that crossed a stop
        line since the step before is judged by the state now, and a light that shows yellow first now turned
        yellow where the cars were at the step before (whether they could have stopped is taken from there)."""
        j = self.junctions
        if not snapshot.tls_states:
            return
        chars = j.signal_chars(snapshot.tls_states)
        lane = frame.lane
        links = self._approach_links(frame)
        # Whether each car could stop at its stop line from here at b_min.
        can_stop = snapshot.speed ** 2 / (2.0 * frame.params.lon_brake_min) <= \
            self.network.lane_length[lane] - frame.lane_pos
        before = self._approach
        ids = snapshot.ids.astype(str)
        seen, at = before.find(ids)
        approaching = (links >= 0).any(axis=1)
        # Cars that approached a signalised link at the step before and left the approach lane (onto the link's
        # internal lane, or past it within one step): judged by the state of the link they crossed.
        inside = j.lane_link[lane]
        for k in np.flatnonzero(seen & ~approaching):
            row = int(at[k])
            held = [int(lk) for lk in before.links[row] if lk >= 0]
            crossed = int(inside[k]) if inside[k] >= 0 else \
                next((lk for lk in held if j.link_to_edge[lk] == frame.edge[k]), -1)
            if crossed in held and not self._teleported(before, row, snapshot, k):
                slot = int(np.flatnonzero(before.links[row] == crossed)[0])
                char = chr(chars[crossed]) if chars[crossed] else ""
                could_stop = bool(char) and char in YELLOW and bool(_could_stop_before(
                    before.char[row, slot], before.decision[row, slot], before.can_stop[row, slot]))
                self._judge(str(ids[k]), str(snapshot.vclass[k]), char, could_stop, float(snapshot.speed[k]),
                            snapshot.time)
        # The approaching cars' links, their states now, and whether each car could have stopped when its light
        # turned yellow: decided at the step the light first showed yellow, from where the car was at the step
        # before; a car first seen under yellow, from where it is now.
        a = np.flatnonzero(approaching)
        mine = links[a]
        char = np.where(mine >= 0, chars[np.maximum(mine, 0)], 0).astype(np.uint8)
        rows = at[a]
        same = (before.links[rows][:, None, :] == mine[:, :, None]) & (mine >= 0)[:, :, None] & \
            seen[a][:, None, None] if len(before) else np.zeros(mine.shape + mine.shape[1:], dtype=bool)
        had = same.any(axis=2)
        slot = same.argmax(axis=2)
        earlier = np.where(had, _could_stop_before(before.char[rows[:, None], slot], before.decision[rows[:, None], slot],
                                                   before.can_stop[rows[:, None], slot]) if len(before) else False,
                           can_stop[a][:, None])
        self._approach = _Approach.of(ids[a], mine, char, _is_yellow(char) & earlier,
                                      np.repeat(can_stop[a][:, None], mine.shape[1], axis=1),
                                      np.column_stack([snapshot.x[a], snapshot.y[a], snapshot.speed[a]]))
        self._time = snapshot.time

    def _teleported(self, before: _Approach, row: int, snapshot: WorldSnapshot, k: int) -> bool:
        """Whether car ``k`` moved farther since the step before than its speeds then and now allow."""
        x, y, v = before.where[row]
        dt = snapshot.time - self._time
        reach = max(v, float(snapshot.speed[k])) * dt + 0.5 * TELEPORT_ACCEL * dt * dt + TELEPORT_SLACK
        return float(np.hypot(snapshot.x[k] - x, snapshot.y[k] - y)) > reach

    def _approach_links(self, frame: VehicleFrame) -> np.ndarray:
        """[n, links of a lane] the signalised links (-1: none) each car on an approach lane may take: the one of
        its route, or every one of its lane where its route is unknown (an FCD without routes); the stop line it
        crosses tells which."""
        j = self.junctions
        cand = j.lane_links[frame.lane]
        next_edge = next_route_edge(frame.route_edges, frame.edge)
        unknown = (frame.route_edges < 0).all(axis=1)
        signalised = (cand >= 0) & (j.link_tls_index[np.maximum(cand, 0)] >= 0)
        on_route = j.link_to_edge[np.maximum(cand, 0)] == next_edge[:, None]
        return np.where(signalised & (on_route | unknown[:, None]), cand, -1)

    def _judge(self, vid: str, vclass: str, char: str, could_stop: bool, speed: float, time: float) -> None:
        if char and char in RED:
            constraint = SignalConstraint.RED_LIGHT
        elif char and char in YELLOW and could_stop:
            constraint = SignalConstraint.YELLOW_LIGHT
        else:
            return
        self.records.append({"run_id": self.run_id, "episode_key": "", "vehicle_id": vid, "vehicle_class": vclass,
                             "role": "signal", "constraint": constraint.value, "bound": 0.0,
                             "worst_actual": speed, "excess": speed, "t_start_s": time, "t_end_s": time})


@dataclass(frozen=True, eq=False)
class _Approach:
    """The cars approaching signalised links at one step, sorted by id; per car and link slot (-1: none): the
    link, its state character's byte then (0: unknown), whether the car could have stopped when its light turned
    yellow (as decided then), and whether it could stop from where it was; per car its x, y [m] and speed [m/s]."""

    ids: np.ndarray
    links: np.ndarray
    char: np.ndarray
    decision: np.ndarray
    can_stop: np.ndarray
    where: np.ndarray

    @staticmethod
    def empty(slots: int) -> _Approach:
        return _Approach.of(np.zeros(0, dtype=str), np.zeros((0, slots), dtype=int),
                            np.zeros((0, slots), dtype=np.uint8), np.zeros((0, slots), dtype=bool),
                            np.zeros((0, slots), dtype=bool), np.zeros((0, 3)))

    @staticmethod
    def of(ids: np.ndarray, links: np.ndarray, char: np.ndarray, decision: np.ndarray, can_stop: np.ndarray,
           where: np.ndarray) -> _Approach:
        order = np.argsort(ids, kind="stable")
        return _Approach(ids[order], links[order], char[order], decision[order], can_stop[order], where[order])

    def find(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(approached at that step, its row) per id."""
        return find_sorted(self.ids, ids)

    def __len__(self) -> int:
        return int(self.ids.shape[0])


_YELLOW_BYTES = tuple(YELLOW.encode())


def _is_yellow(char: np.ndarray) -> np.ndarray:
    yellow = char == _YELLOW_BYTES[0]
    for byte in _YELLOW_BYTES[1:]:
        yellow = yellow | (char == byte)
    return yellow


def _could_stop_before(char: np.ndarray, decision: np.ndarray, can_stop: np.ndarray) -> np.ndarray:
    """Whether a car could have stopped when its light turned yellow, from its state at the step before: the
    decision taken then if the light already showed yellow, else whether it could stop from where it was."""
    return np.where(_is_yellow(char), decision, can_stop)


class SignalStates:
    """Signal states over time for offline audits: ``states(time) -> {signal: state string}``."""

    def __init__(self, net_file: Path, saved_states: Path | None = None):
        self.saved_states = saved_states
        self.known_until: float | None = None  # [s] the last saved state's time where the file breaks off
        self._saved: dict[str, tuple[list[float], list[str]]] = {}
        self._programs: dict[str, tuple[float, list[tuple[float, str]]]] = {}
        signals = cached(Path(net_file), "signals", lambda: signal_programs(net_file), keep=True)
        if saved_states is not None:
            self._read_saved(saved_states, read_topology(net_file).signals)
            foreign = sorted(set(self._saved) - set(signals))
            if foreign:
                raise ValueError(f"{saved_states}: states of signal(s) {', '.join(foreign[:5])} that {net_file} does "
                                 "not have; is it the signal-state file of a run on this network?")
            missing = sorted(set(signals) - set(self._saved))
            if missing:
                warnings.warn(f"{saved_states}: no states of signal(s) {', '.join(missing)}; their network programs "
                              "are used instead", stacklevel=2)
        for tl_id, programs in signals.items():
            if tl_id in self._saved:
                continue
            if len(programs) != 1 or programs[0].type != "static":
                warnings.warn(f"{net_file}: signal {tl_id} has no single fixed-time program; its links are "
                              "audited as equal priority (give --tls-states for the real states)", stacklevel=2)
                continue
            self._programs[tl_id] = (programs[0].offset, list(programs[0].phases))

    def _read_saved(self, path: Path, links: dict[str, int]) -> None:
        """``links``: signal id → links it controls, to check the states' lengths against."""
        cut: list[int] = []
        try:
            for number, elem in enumerate(output_elements(path, "tlsStates", "tlsState", on_cut=cut.append), 1):
                times, states = self._saved.setdefault(elem.get("id", ""), ([], []))
                time, state = signal_state(path, number, elem, links, times[-1] if times else None)
                times.append(time)
                states.append(state)
        except (*MALFORMED, ValueError) as exc:
            raise ValueError(f"{path}: not a readable SUMO signal-state file (SaveTLSStates output: {exc})") from exc
        if cut:
            self.known_until = max((times[-1] for times, _ in self._saved.values()), default=0.0)

    def begin_after(self, time: float) -> dict[str, float]:
        """The signals whose saved states begin after ``time`` [s] (signal → its first state's time [s]): before
        that no state of theirs is known, and their links are audited as unsignalised ones of equal priority."""
        return {tl: times[0] for tl, (times, _) in self._saved.items() if times and times[0] > time + 1e-6}

    def states(self, time: float) -> dict[str, str] | None:
        out = {}
        for tl, (times, states) in self._saved.items():
            k = bisect_right(times, time + 1e-9) - 1
            if k >= 0:
                out[tl] = states[k]
        for tl, (offset, phases) in self._programs.items():
            cycle = sum(d for d, _ in phases)
            t = (time - offset) % cycle
            for duration, state in phases:
                if t < duration - 1e-9:
                    out[tl] = state
                    break
                t -= duration
        return out or None
