"""Every step of the danger episodes, as the auditor saw them: the gaps and safe distances of the pair, and the owed
responses' bounds with each car's actual value (``pair_states.csv`` for the ego's episodes, ``episode_states.npz``
for every episode: what the viewer charts for a selected pair).

One row per episode and step from ``t_b`` to its last dangerous step, collected once per step as arrays (no Python
loop over pairs); memory grows with the summed duration of the episodes (~66 bytes per episode-step), up to a bound,
unless the rows are spooled to disk as they come (:mod:`sumo_rss.spool`; ``sumo-rss audit`` does).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, fields
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SumoRssError
from ..files import read_npz, write_npz
from ..spool import ColumnSpool, SpooledColumn
from .responsibility import ResponsibilityTracker
from .situations import PairSituations

STATE_FILE = "episode_states.npz"
PAIR_STATE_COLUMNS = ["run_id", "episode_key", "time_s", "lon_gap_m", "lon_d_min_m", "lat_gap_m", "lat_d_min_m",
                      "dangerous"]
# Episode-steps kept of the episodes without the traced class (~260 MB; a 300 s highway_dense run has 0.73 M).
MAX_OTHER_ROWS = 4_000_000
_GAPS = ("lon_gap", "lon_d_min", "lat_gap", "lat_d_min")
_BOUNDS = ("accel", "accel_max", "accel_min", "lat_speed", "lat_speed_max")  # JudgedStep's, per car


@dataclass(frozen=True, eq=False)
class EpisodeStates:
    """The recorded steps, rows grouped by episode (in order of ``episode_keys``) and in time order within one:
    episode ``k``'s rows are ``episode_start[k]:episode_start[k + 1]``. Per row: ``time`` [s], ``lon_gap``,
    ``lon_d_min``, ``lat_gap``, ``lat_d_min`` [m] (as in pair_states.csv; lateral NaN at a junction), and per car
    (column 0: vehicle_a, 1: vehicle_b) ``accel`` [m/s²] with its owed bounds ``accel_max`` / ``accel_min`` and
    ``lat_speed`` (towards the other car) [m/s] with ``lat_speed_max``; a bound is NaN where it does not apply (the
    step at t_b is not judged). The per-row columns of a spooled recording are :class:`EpisodeRows`, read from disk
    when converted (``np.asarray``)."""

    episode_keys: np.ndarray
    episode_start: np.ndarray
    time: np.ndarray
    lon_gap: np.ndarray
    lon_d_min: np.ndarray
    lat_gap: np.ndarray
    lat_d_min: np.ndarray
    accel: np.ndarray
    accel_max: np.ndarray
    accel_min: np.ndarray
    lat_speed: np.ndarray
    lat_speed_max: np.ndarray
    cut_at: float = np.nan  # [s] from here on only the ego's episodes were recorded (EpisodeStateTrace); NaN: none

    @classmethod
    def read(cls, path: Path) -> EpisodeStates:
        """Load what :meth:`write` wrote; SumoRssError naming the file where it is not such a file."""
        names = [f.name for f in fields(cls)]
        what = "an episode-state file as sumo-rss writes it"
        data = read_npz(path, what)
        missing = [name for name in names if name not in data]
        if missing:
            raise SumoRssError(f"{path}: not {what} (no array {missing[0]!r})")
        return cls(**{name: data[name] for name in names[:-1]}, cut_at=float(data["cut_at"]))

    def rows(self) -> dict[str, tuple[int, int]]:
        """Episode key → (first row, end row)."""
        return {key: (int(s), int(e)) for key, s, e in zip(self.episode_keys.tolist(), self.episode_start[:-1],
                                                          self.episode_start[1:])}

    def write(self, path: Path) -> None:
        """As ``.npz`` (float32 values: 0.1 mm on a 1 km gap), deterministic bytes; one column in memory at a time."""
        kept = ("episode_keys", "episode_start", "time", "cut_at")
        write_npz(path, {f.name: partial(np.asarray, getattr(self, f.name), None if f.name in kept else np.float32)
                         for f in fields(self)})


@dataclass(frozen=True, eq=False)
class EpisodeRows:
    """One column of the recorded steps in episode order: rows ``order`` of the concatenated ``parts`` (arrays or
    spooled columns), read and reordered when converted (``np.asarray``)."""

    parts: tuple[np.ndarray | SpooledColumn, ...]
    order: np.ndarray

    def __len__(self) -> int:
        return len(self.order)

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> np.ndarray:
        rows = np.concatenate([np.asarray(part) for part in self.parts])[self.order]
        return rows if dtype is None else rows.astype(dtype, copy=False)


class EpisodeStateTrace:
    """Collects the states of the open episodes after every step of a :class:`ResponsibilityTracker`: those that
    involve a car of ``vclass`` (pair_states.csv, in full precision), and with ``every_episode`` the others too
    (float32), up to ``max_rows`` of them: from the step that would pass it on, only ``vclass``'s episodes are kept
    (``cut_at``, with a warning), so a long run's memory stays bounded (~66 bytes per episode-step). ``spool``: a
    folder the rows go to as they come (:mod:`sumo_rss.spool`), memory then holds a few MB of them until they are
    written (:meth:`episode_states`: then one column at a time, and 16 bytes per row to put them in episode order)."""

    def __init__(self, vclass: str | None, every_episode: bool, max_rows: int | None = None,
                 spool: Path | None = None):
        self.vclass = vclass
        self.every_episode = every_episode
        self.max_rows = MAX_OTHER_ROWS if max_rows is None else max_rows
        self.cut_at: float | None = None  # [s] the first step whose other episodes were not kept
        self.spooled = spool is not None
        # Per row: time, serial, gaps, dangerous, bounds (car a, car b); the vclass's episodes in full precision.
        self._mine, self._others = (ColumnSpool({"time": np.float64, "serial": np.int64,
                                                 **{name: dtype for name in _GAPS}, "dangerous": bool,
                                                 **{name: (np.float32, (2,)) for name in _BOUNDS}}, spool,
                                                STATE_FILE)
                                    for dtype in (np.float64, np.float32))
        self._other_rows = 0

    def step(self, time: float, tracker: ResponsibilityTracker, keys: np.ndarray, situations: PairSituations) -> None:
        """After ``tracker.step``: ``keys`` and ``situations`` of that step (every open episode's pair is in them)."""
        pair_keys, serials, involves = tracker.open_episodes(self.vclass)
        if self.vclass is None:
            involves = np.zeros(len(serials), dtype=bool)
        others = ~involves if self.every_episode else np.zeros(len(serials), dtype=bool)
        if others.sum() and self.cut_at is None and self._other_rows + others.sum() > self.max_rows:
            self.cut_at = time
            warnings.warn(f"the step-by-step states of more than {self.max_rows:,} episode-steps: from {time:g} s on "
                          f"only those of the {self.vclass or 'no'} class's episodes are kept (episode_states.npz)",
                          stacklevel=3)
        if self.cut_at is not None:
            others[:] = False
        kept = involves | others
        if not kept.any():
            return
        pair_keys, serials, involves = pair_keys[kept], serials[kept], involves[kept]
        order = np.argsort(keys)
        rows = order[np.searchsorted(keys, pair_keys, sorter=order)]
        bounds = np.full((len(_BOUNDS), len(serials), 2), np.nan, dtype=np.float32)
        judged = tracker.judged
        if judged is not None and len(judged.serial):
            by_serial = np.argsort(judged.serial)
            at = np.clip(np.searchsorted(judged.serial, serials, sorter=by_serial), 0, len(by_serial) - 1)
            pos = by_serial[at]
            hit = judged.serial[pos] == serials  # episodes opened at this step were not judged
            for k, name in enumerate(_BOUNDS):
                bounds[k, hit] = getattr(judged, name)[pos[hit]]
        for spool, part in ((self._mine, involves), (self._others, ~involves)):
            if part.any():
                spool.append(time=np.full(int(part.sum()), time), serial=serials[part],
                             **{name: getattr(situations, name)[rows][part] for name in _GAPS},
                             dangerous=situations.dangerous[rows][part],
                             **{name: bounds[k, part] for k, name in enumerate(_BOUNDS)})
        self._other_rows += int((~involves).sum())

    def pair_states(self, run_id: str, serial_keys: dict[int, str]) -> pd.DataFrame:
        """pair_states.csv: the steps of the episodes involving ``vclass``, step by step (PAIR_STATE_COLUMNS)."""
        c = {name: np.asarray(self._mine.column(name)) for name in ("serial", "time", *_GAPS, "dangerous")}
        table = {"run_id": run_id, "episode_key": [serial_keys[int(s)] for s in c["serial"]]}
        table.update({name: c[field] for name, field in zip(PAIR_STATE_COLUMNS[2:], ("time", *_GAPS, "dangerous"))})
        return pd.DataFrame(table, columns=PAIR_STATE_COLUMNS)

    def episode_states(self, serial_keys: dict[int, str]) -> EpisodeStates:
        """Every recorded step, grouped by episode (episodes in the order they opened); spooled, its per-row columns
        stay on disk until written (:class:`EpisodeRows`)."""
        parts = (self._mine, self._others)
        serial = np.concatenate([np.asarray(part.column("serial")) for part in parts])
        order = np.argsort(serial, kind="stable")  # an episode's steps are all in one part, in time order
        serial = serial[order]
        first = np.r_[True, serial[1:] != serial[:-1]] if len(serial) else np.zeros(0, dtype=bool)
        start = np.r_[np.flatnonzero(first), len(serial)].astype(np.int64)
        keys = np.array([serial_keys[int(s)] for s in serial[first]], dtype=str)
        columns = {name: EpisodeRows(tuple(part.column(name) for part in parts), order)
                   for name in ("time", *_GAPS, *_BOUNDS)}
        if not self.spooled:
            columns = {name: np.asarray(rows) for name, rows in columns.items()}
        return EpisodeStates(keys, start, **columns, cut_at=np.nan if self.cut_at is None else self.cut_at)
