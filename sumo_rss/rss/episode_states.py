"""Every step of the danger episodes, as the auditor saw them: the gaps and safe distances of the pair, and the owed
responses' bounds with each car's actual value (``pair_states.csv`` for the ego's episodes, ``episode_states.npz``
for every episode: what the viewer charts for a selected pair).

One row per episode and step from ``t_b`` to its last dangerous step, collected once per step as arrays (no Python
loop over pairs); memory grows with the summed duration of the episodes (~90 bytes per episode-step).
"""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SumoRssError
from ..files import write_npz
from .responsibility import ResponsibilityTracker
from .situations import PairSituations

STATE_FILE = "episode_states.npz"
PAIR_STATE_COLUMNS = ["run_id", "episode_key", "time_s", "lon_gap_m", "lon_d_min_m", "lat_gap_m", "lat_d_min_m",
                      "dangerous"]
_GAPS = ("lon_gap", "lon_d_min", "lat_gap", "lat_d_min")
_BOUNDS = ("accel", "accel_max", "accel_min", "lat_speed", "lat_speed_max")  # JudgedStep's, per car


@dataclass(frozen=True, eq=False)
class EpisodeStates:
    """The recorded steps, rows grouped by episode (in order of ``episode_keys``) and in time order within one:
    episode ``k``'s rows are ``episode_start[k]:episode_start[k + 1]``. Per row: ``time`` [s], ``lon_gap``,
    ``lon_d_min``, ``lat_gap``, ``lat_d_min`` [m] (as in pair_states.csv; lateral NaN at a junction), and per car
    (column 0: vehicle_a, 1: vehicle_b) ``accel`` [m/s²] with its owed bounds ``accel_max`` / ``accel_min`` and
    ``lat_speed`` (towards the other car) [m/s] with ``lat_speed_max``; a bound is NaN where it does not apply (the
    step at t_b is not judged)."""

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

    @classmethod
    def read(cls, path: Path) -> EpisodeStates:
        """Load what :meth:`write` wrote; SumoRssError naming the file where it is not such a file."""
        names = [f.name for f in fields(cls)]
        try:
            with np.load(path, allow_pickle=False) as data:
                return cls(**{name: data[name] for name in names})
        except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
            raise SumoRssError(f"{path}: not an episode-state file as sumo-rss writes it ({exc})") from None

    def rows(self) -> dict[str, tuple[int, int]]:
        """Episode key → (first row, end row)."""
        return {key: (int(s), int(e)) for key, s, e in zip(self.episode_keys.tolist(), self.episode_start[:-1],
                                                          self.episode_start[1:])}

    def write(self, path: Path) -> None:
        """As ``.npz`` (float32 values: 0.1 mm on a 1 km gap), deterministic bytes."""
        write_npz(path, {f.name: getattr(self, f.name).astype(np.float32) if f.name not in ("episode_keys",
                                                                                          "episode_start", "time")
                         else getattr(self, f.name) for f in fields(self)})


class EpisodeStateTrace:
    """Collects the states of the open episodes after every step of a :class:`ResponsibilityTracker`: those that
    involve a car of ``vclass`` (pair_states.csv), and with ``every_episode`` all of them."""

    def __init__(self, vclass: str | None, every_episode: bool):
        self.vclass = vclass
        self.every_episode = every_episode
        self._steps: list[tuple[np.ndarray, ...]] = []

    def step(self, time: float, tracker: ResponsibilityTracker, keys: np.ndarray, situations: PairSituations) -> None:
        """After ``tracker.step``: ``keys`` and ``situations`` of that step (every open episode's pair is in them)."""
        pair_keys, serials, involves = tracker.open_episodes(self.vclass)
        if not self.every_episode:
            pair_keys, serials, involves = pair_keys[involves], serials[involves], involves[involves]
        if not len(serials):
            return
        order = np.argsort(keys)
        rows = order[np.searchsorted(keys, pair_keys, sorter=order)]
        bounds = np.full((len(_BOUNDS), len(serials), 2), np.nan)
        judged = tracker.judged
        if judged is not None and len(judged.serial):
            by_serial = np.argsort(judged.serial)
            at = np.clip(np.searchsorted(judged.serial, serials, sorter=by_serial), 0, len(by_serial) - 1)
            pos = by_serial[at]
            hit = judged.serial[pos] == serials  # episodes opened at this step were not judged
            for k, name in enumerate(_BOUNDS):
                bounds[k, hit] = getattr(judged, name)[pos[hit]]
        self._steps.append((serials, involves, np.full(len(serials), time), situations.lon_gap[rows],
                            situations.lon_d_min[rows], situations.lat_gap[rows], situations.lat_d_min[rows],
                            situations.dangerous[rows], *bounds))

    def _columns(self) -> dict[str, np.ndarray]:
        names = ("serial", "involves", "time", *_GAPS, "dangerous", *_BOUNDS)
        if not self._steps:
            empty = {name: np.zeros(0) for name in names}
            empty.update({name: np.zeros((0, 2)) for name in _BOUNDS})
            return empty
        return {name: np.concatenate(parts) for name, parts in zip(names, zip(*self._steps))}

    def pair_states(self, run_id: str, serial_keys: dict[int, str]) -> pd.DataFrame:
        """pair_states.csv: the steps of the episodes involving ``vclass``, step by step (PAIR_STATE_COLUMNS)."""
        c = self._columns()
        mine = c["involves"].astype(bool)
        table = {"run_id": run_id, "episode_key": [serial_keys[int(s)] for s in c["serial"][mine]]}
        table.update({name: c[field][mine] for name, field in zip(PAIR_STATE_COLUMNS[2:],
                                                                   ("time", *_GAPS, "dangerous"))})
        return pd.DataFrame(table, columns=PAIR_STATE_COLUMNS)

    def episode_states(self, serial_keys: dict[int, str]) -> EpisodeStates:
        """Every recorded step, grouped by episode (episodes in the order they opened)."""
        c = self._columns()
        order = np.argsort(c["serial"], kind="stable")  # within an episode the steps stay in time order
        serial = c["serial"][order].astype(np.int64)
        first = np.r_[True, serial[1:] != serial[:-1]] if len(serial) else np.zeros(0, dtype=bool)
        start = np.r_[np.flatnonzero(first), len(serial)].astype(np.int64)
        keys = np.array([serial_keys[int(s)] for s in serial[first]], dtype=str)
        return EpisodeStates(keys, start, c["time"][order], *(c[name][order] for name in _GAPS),
                             *(c[name][order] for name in _BOUNDS))
