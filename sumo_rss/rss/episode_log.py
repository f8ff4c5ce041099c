"""Closed episodes on their way to the records, and the rule that joins a pair's flickering episodes into one.

A pair whose gap hovers around its safe distance is dangerous, safe, dangerous again within a few steps (Monaco:
101 episodes in 140 s for one pair following at 46-47 m, d_min ±0.5 m; 21-30 % of road episodes re-opened within
0.5 s). With joining (the default), an episode that ended safe is held for the pair's response time ρ (the larger of
the two cars'): if the pair is dangerous again within it, the episode goes on (same key, its first t_b, its end the
last one's, blame the union; the owed response is judged afresh from each new danger threshold, exactly as the raw
episodes would be); a collision within it is that episode's. One judgement looks at the joined episode as a whole:
a car owing braking at a junction complied if it stayed out of the conflict area (:class:`EpisodeParts`), so the
blame of its earlier parts is cleared when it stands short at the end. Without joining (raw episodes) the window is 0: a
collision at the very step an episode ended is still its.

Violation rows wait with their episode's record and are stored with it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .records import EPISODE_COLUMNS, VIOLATION_COLUMNS, RecordTable

TIME_EPS = 1e-9  # [s]


@dataclass
class EpisodeParts:
    """The parts of one (joined) episode as the stay-out rule judges them, per car (column 0: vehicle_a, 1:
    vehicle_b). A car responsible in a part while owing braking at a junction ('excusable' there) is cleared of it,
    with its violation rows of those parts, if over the whole episode its front bumper never entered the conflict
    area and at the end of the last part it stood short of the area or was braking hard enough to stop before it."""

    entered: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=bool))  # in the area in some part
    pending: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=bool))  # responsible where excusable
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=bool))  # responsible elsewhere
    cleared: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=bool))  # stayed out, as of the last part
    rows: list[tuple[int, bool, dict]] = field(default_factory=list)  # (car, excusable, violation row)

    def add(self, rows: list[tuple[int, dict]], responsible: np.ndarray, excusable: np.ndarray,
            entered: np.ndarray, stays_out: np.ndarray) -> None:
        """One more part: its violation rows (car, row), and per car whether it was ``responsible``, owed braking at
        a junction under the stay-out rule (``excusable``), ``entered`` the area, and at the part's end stood short
        or was stopping before the area (``stays_out``)."""
        self.entered |= entered
        self.pending |= responsible & excusable
        self.fixed |= responsible & ~excusable
        self.cleared = stays_out & ~self.entered
        self.rows.extend((car, bool(excusable[car]), row) for car, row in rows)

    @property
    def responsible(self) -> np.ndarray:
        """[2] who is responsible for the episode so far."""
        return self.fixed | (self.pending & ~self.cleared)

    def violations(self) -> list[dict]:
        """The violation rows that stand (those of a cleared car where it was excusable are dropped)."""
        return [row for car, excusable, row in self.rows if not (excusable and self.cleared[car])]


@dataclass
class _Held:
    record: dict
    parts: EpisodeParts
    end: float  # [s] when the episode ended
    window: float  # [s] how long after its end it can go on
    joinable: bool  # it ended safe (not because a car left the data)


class EpisodeLog:
    """Closed episode records with their violation rows, each held until its join window has passed
    (:func:`join_records`)."""

    def __init__(self, join: bool = True):
        self.join = join
        self._records = RecordTable(EPISODE_COLUMNS)
        self._violations = RecordTable(VIOLATION_COLUMNS)
        self._held: dict[int, _Held] = {}

    def close(self, key: int, record: dict, parts: EpisodeParts, time: float, window: float,
              joinable: bool) -> None:
        """An episode of pair ``key`` ended at ``time`` [s]; ``window`` [s]: the pair's ρ."""
        previous = self._held.pop(key, None)
        if previous is not None:  # not joinable (a car had left the data): it stays as it was
            self._store(previous)
        self._held[key] = _Held(record, parts, time, window if self.join else 0.0, joinable)

    def resume(self, key: int, time: float) -> tuple[dict, EpisodeParts] | None:
        """The record and parts of the episode of pair ``key`` that ended safe within its window before ``time``
        (it goes on; the caller closes it again), or None (a new episode opens; a held record is stored)."""
        held = self._held.pop(key, None)
        if held is None:
            return None
        if held.joinable and time - held.end <= held.window + TIME_EPS:
            return held.record, held.parts
        self._store(held)
        return None

    def collide(self, key: int, time: float) -> tuple[dict, EpisodeParts] | None:
        """The record and parts of the episode of pair ``key`` that ended within its window before a collision at
        ``time`` (or at that very step), removed from the held ones: the caller marks it and closes it again."""
        held = self._held.get(key)
        if held is None or held.record["collision"] or time - held.end > held.window + TIME_EPS:
            return None
        del self._held[key]
        return held.record, held.parts

    def expire(self, time: float) -> None:
        """Store every held record whose window has passed before ``time`` [s]."""
        done = [key for key, held in self._held.items() if time - held.end > held.window + TIME_EPS]
        for key in sorted(done):
            self._store(self._held.pop(key))

    def frame(self) -> pd.DataFrame:
        """Every closed episode so far, the held ones last (EPISODE_COLUMNS)."""
        return self._records.frame(held.record for _, held in sorted(self._held.items()))

    def violation_frame(self) -> pd.DataFrame:
        """The violation rows of every closed episode so far, the held ones' last (VIOLATION_COLUMNS)."""
        return self._violations.frame(row for _, held in sorted(self._held.items())
                                      for row in held.parts.violations())

    def _store(self, held: _Held) -> None:
        self._records.append(held.record)
        self._violations.extend(held.parts.violations())


def join_records(first: dict, later: dict) -> dict:
    """One record of an episode and its continuation: the first's key, t_b, trigger and owed responses, the later
    one's end and responsible cars (the later record's verdict is the whole episode's: :class:`EpisodeParts`) and
    the smallest margins."""
    joined = dict(later)
    for name in ("episode_key", "episode_index", "situation", "conflict_area", "t_b_s", "trigger", "owed_a",
                 "owed_b"):
        joined[name] = first[name]
    joined["duration_s"] = later["t_end_s"] - first["t_b_s"]
    for name in ("min_lon_margin_m", "min_lat_margin_m"):  # NaN (crossings' lateral margin) where both are
        joined[name] = float(np.fmin(first[name], later[name]))
    return joined
