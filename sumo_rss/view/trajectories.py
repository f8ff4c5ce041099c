"""The compact per-step trajectory file a run or an audit writes for the viewer: ``trajectories.npz``.

Columnar and step-major (CSR): the rows of step ``k`` are ``step_start[k]:step_start[k + 1]``, one per recorded
vehicle, ``vehicle`` indexing the per-vehicle arrays. Positions are SUMO's front-bumper centres [m] as float32
(1 mm or better up to 16 km from the origin), headings in rad (math convention), speeds in m/s. Signal states are
stored only when they change. A run records the vehicles within ``NEAR_EGO_M`` of its ego (every vehicle with
``--fcd``, or when the run has no ego); an audit records every vehicle of the FCD.

Pure numpy: recorded from anything shaped like a ``WorldSnapshot`` (this package imports nothing from ``sim``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from ..errors import SumoRssError
from ..files import read_npz, write_npz
from ..rss.numbering import Numbering
from ..spool import ColumnSpool

TRAJECTORY_FILE = "trajectories.npz"
NEAR_EGO_M = 150.0  # [m] a run without --fcd records the vehicles whose front bumper is this close to the ego's
FORMAT_VERSION = 1
EGO_CLASS = "ego"  # the snapshots' vehicle class of the ego (sim.snapshot.EGO_CLASS; not imported: no sim here)


class SnapshotLike(Protocol):
    """What the recorder reads of a snapshot (``sim.snapshot.WorldSnapshot`` has it)."""

    time: float
    ids: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    length: np.ndarray
    width: np.ndarray
    vclass: np.ndarray
    vtype: np.ndarray
    tls_states: dict[str, str] | None


@dataclass(frozen=True, eq=False)
class Trajectories:
    """A trajectory file's contents (see the module docstring). Per step: ``time`` [s], ``step_start`` (one more);
    per row: ``vehicle``, ``x``, ``y`` [m], ``heading`` [rad], ``speed`` [m/s]; per vehicle: ``ids``, ``length``,
    ``width`` [m], ``vclass``, ``vtype``; per signal change: ``signal_time`` [s], ``signal`` (index into
    ``signal_ids``), ``signal_state`` (SUMO's state string). ``scope``: 'all' or 'near-ego:<m>';
    ``net_file``: the network the run drove on or the audit judged on."""

    time: np.ndarray
    step_start: np.ndarray
    vehicle: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    ids: np.ndarray
    length: np.ndarray
    width: np.ndarray
    vclass: np.ndarray
    vtype: np.ndarray
    signal_ids: np.ndarray
    signal_time: np.ndarray
    signal: np.ndarray
    signal_state: np.ndarray
    scope: str
    net_file: str

    @classmethod
    def read(cls, path: Path) -> Trajectories:
        """Load ``path``; SumoRssError naming the file and what is wrong where it is not a trajectory file."""
        arrays = read_npz(path, "a trajectory file as 'sumo-rss run' writes it")
        version = int(arrays.pop("format_version", -1))
        if version != FORMAT_VERSION:
            raise SumoRssError(f"{path}: format_version: expected {FORMAT_VERSION}, got {version} (written by another "
                               "version of sumo-rss: run it again)")
        missing = sorted(set(_FIELDS) - arrays.keys())
        if missing:
            raise SumoRssError(f"{path}: expected the arrays {', '.join(_FIELDS)}, missing {', '.join(missing)}")
        rows = int(arrays["step_start"][-1]) if len(arrays["step_start"]) else -1
        if len(arrays["step_start"]) != len(arrays["time"]) + 1 or rows != len(arrays["vehicle"]):
            raise SumoRssError(f"{path}: step_start: expected one offset per step and one more (the row count)")
        return cls(**{name: arrays[name] for name in _FIELDS}, scope=str(arrays["scope"]),
                   net_file=str(arrays["net_file"]))


_FIELDS = ("time", "step_start", "vehicle", "x", "y", "heading", "speed", "ids", "length", "width", "vclass",
           "vtype", "signal_ids", "signal_time", "signal", "signal_state")


class TrajectoryRecorder:
    """Collects the snapshots of a run (:meth:`add`, once per step) and writes ``trajectories.npz``.

    ``near_ego_m``: record only the vehicles within this distance [m] of the ego (none at steps without it on the
    road); None: every vehicle. ``spool``: a folder the rows go to as they are recorded (:mod:`sumo_rss.spool`;
    memory then holds a few MB of them, the per-step times and the per-vehicle sizes); None: kept in memory. Costs
    a few numpy calls and one dict look-up per vehicle per step."""

    def __init__(self, net_file: Path, near_ego_m: float | None = None, spool: Path | None = None):
        self.net_file = str(Path(net_file).resolve())
        self.near_ego_m = near_ego_m
        self._numbers = Numbering()  # every vehicle recorded: its number (its row of the per-vehicle lists)
        self._length: list[float] = []
        self._width: list[float] = []
        self._vclass: list[str] = []
        self._vtype: list[str] = []
        self._times: list[float] = []
        self._counts: list[int] = []
        self._rows_of_steps = ColumnSpool({"vehicle": np.int32, "x": np.float32, "y": np.float32,
                                           "heading": np.float32, "speed": np.float32}, spool, TRAJECTORY_FILE)
        self._signal_ids: dict[str, int] = {}
        self._signal_last: dict[str, str] = {}
        self._signal_changes: list[tuple[float, int, str]] = []

    def add(self, snapshot: SnapshotLike) -> None:
        """Record one step."""
        rows = self._rows(snapshot)
        ids = snapshot.ids[rows].tolist()
        known = len(self._numbers)
        numbers = self._numbers.of(ids)
        for i in rows[numbers >= known].tolist():  # first seen now, in the order numbered
            self._length.append(float(snapshot.length[i]))
            self._width.append(float(snapshot.width[i]))
            self._vclass.append(str(snapshot.vclass[i]))
            self._vtype.append(str(snapshot.vtype[i]))
        self._times.append(float(snapshot.time))
        self._counts.append(len(ids))
        self._rows_of_steps.append(vehicle=numbers.astype(np.int32),
                                   **{name: np.asarray(getattr(snapshot, name))[rows]
                                      for name in ("x", "y", "heading", "speed")})
        for signal, state in (snapshot.tls_states or {}).items():
            if self._signal_last.get(signal) != state:
                self._signal_last[signal] = state
                number = self._signal_ids.setdefault(signal, len(self._signal_ids))
                self._signal_changes.append((float(snapshot.time), number, state))

    def _rows(self, snapshot: SnapshotLike) -> np.ndarray:
        if self.near_ego_m is None:
            return np.arange(len(snapshot.ids))
        ego = np.flatnonzero(snapshot.vclass == EGO_CLASS)
        if not len(ego):
            return ego
        k = ego[0]
        near = np.hypot(snapshot.x - snapshot.x[k], snapshot.y - snapshot.y[k]) <= self.near_ego_m
        return np.flatnonzero(near)

    @property
    def scope(self) -> str:
        return "all" if self.near_ego_m is None else f"near-ego:{self.near_ego_m:g}"

    def write(self, path: Path) -> None:
        """Write everything recorded so far to ``path`` (atomically, deterministic bytes)."""
        changes, column = self._signal_changes, self._rows_of_steps.column
        write_npz(path, {
            "format_version": np.int32(FORMAT_VERSION), "scope": np.str_(self.scope),
            "net_file": np.str_(self.net_file),
            "time": np.array(self._times, dtype=np.float64),
            "step_start": np.concatenate([[0], np.cumsum(self._counts, dtype=np.int64)]).astype(np.int64),
            **{name: column(name) for name in ("vehicle", "x", "y", "heading", "speed")},
            "ids": np.array(list(self._numbers.number), dtype=str), "length": np.array(self._length, dtype=np.float32),
            "width": np.array(self._width, dtype=np.float32), "vclass": np.array(self._vclass, dtype=str),
            "vtype": np.array(self._vtype, dtype=str),
            "signal_ids": np.array(list(self._signal_ids), dtype=str),
            "signal_time": np.array([c[0] for c in changes], dtype=np.float64),
            "signal": np.array([c[1] for c in changes], dtype=np.int32),
            "signal_state": np.array([c[2] for c in changes], dtype=str)})
