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
        # id → {link: (its state, could have stopped when it turned yellow, could stop from here)} for the links
        # it may take from its approach lane
        self._approach: dict[str, dict[int, tuple[str, bool, bool]]] = {}
        self._where: dict[str, tuple[float, float, float]] = {}  # id → (x [m], y [m], speed [m/s]) of an approacher
        self._time: float | None = None  # [s] of the step before

    def step(self, snapshot: WorldSnapshot, frame: VehicleFrame) -> None:
        """SUMO's signal states at a step are those its cars moved under to get there: a car that crossed a stop
        line since the step before is judged by the state now, and a light that shows yellow first now turned
        yellow where the cars were at the step before (whether they could have stopped is taken from there)."""
        j = self.junctions
        if not snapshot.tls_states:
            return
        lane = frame.lane
        inside = j.lane_link[lane]
        links = self._approach_links(frame)
        # Whether each car could stop at its stop line from here at b_min.
        can_stop = snapshot.speed ** 2 / (2.0 * frame.params.lon_brake_min) <= \
            self.network.lane_length[lane] - frame.lane_pos
        # Cars that approached a signalised link at the step before and left the approach lane (onto the link's
        # internal lane, or past it within one step).
        was_approaching = np.isin(snapshot.ids, list(self._approach)) if self._approach else \
            np.zeros(len(snapshot.ids), dtype=bool)
        approach, where = {}, {}
        for k in np.flatnonzero((links >= 0).any(axis=1) | (inside >= 0) | was_approaching):
            vid = str(snapshot.ids[k])
            before = self._approach.get(vid, {})
            if not (links[k] >= 0).any():
                crossed = int(inside[k]) if inside[k] >= 0 else \
                    next((lk for lk in before if j.link_to_edge[lk] == frame.edge[k]), -1)
                if crossed in before and not self._teleported(vid, snapshot, k):
                    # crossed the stop line of this link since the step before
                    char = self._state(snapshot, crossed)
                    self._judge(vid, str(snapshot.vclass[k]), char, self._could_stop(char, before[crossed], None),
                                float(snapshot.speed[k]), snapshot.time)
                continue
            states = {}
            for lk in (int(x) for x in links[k] if x >= 0):
                char = self._state(snapshot, lk)
                states[lk] = (char, self._could_stop(char, before.get(lk), bool(can_stop[k])), bool(can_stop[k]))
            approach[vid] = states
            where[vid] = (float(snapshot.x[k]), float(snapshot.y[k]), float(snapshot.speed[k]))
        self._approach, self._where, self._time = approach, where, snapshot.time

    def _teleported(self, vid: str, snapshot: WorldSnapshot, k: int) -> bool:
        """Whether car ``k`` moved farther since the step before than its speeds then and now allow."""
        x, y, v = self._where[vid]
        dt = snapshot.time - self._time
        reach = max(v, float(snapshot.speed[k])) * dt + 0.5 * TELEPORT_ACCEL * dt * dt + TELEPORT_SLACK
        return float(np.hypot(snapshot.x[k] - x, snapshot.y[k] - y)) > reach

    def _state(self, snapshot: WorldSnapshot, link: int) -> str:
        """The signal state character of ``link`` in ``snapshot`` ('' if unknown)."""
        j = self.junctions
        state = snapshot.tls_states.get(j.link_tls[link], "")
        return state[j.link_tls_index[link]] if 0 <= j.link_tls_index[link] < len(state) else ""

    @staticmethod
    def _could_stop(char: str, before: tuple[str, bool, bool] | None, can_stop_now: bool | None) -> bool:
        """Whether the car could have stopped at b_min when its light turned yellow (False unless ``char`` is
        yellow): decided at the step the light first showed yellow, from where the car was at the step before
        (``before``: that step's (state, decision, could stop from there)); a car first seen under yellow, from
        where it is now."""
        if not (char and char in YELLOW):
            return False
        if before is None:
            return bool(can_stop_now)
        return before[1] if before[0] and before[0] in YELLOW else before[2]

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
