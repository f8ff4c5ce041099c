"""Closed episodes on their way to the records, and the rule that joins a pair's flickering episodes into one.

A pair whose gap hovers around its safe distance is dangerous, safe, dangerous again within a few steps (Monaco:
101 episodes in 140 s for one pair following at 46-47 m, d_min ±0.5 m; 21-30 % of road episodes re-opened within
0.5 s). With joining (the default), an episode that ended safe is held for the pair's response time ρ (the larger of
the two cars'): if the pair is dangerous again within it, the episode goes on (same key, its first t_b, its end the
last one's, blame the union; the owed response is judged afresh from each new danger threshold, exactly as the raw
episodes would be, so joining never changes who is responsible); a collision within it is that episode's. Without
joining (raw episodes) the window is 0: a collision at the very step an episode ended is still its.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .records import EPISODE_COLUMNS, RecordTable

TIME_EPS = 1e-9  # [s]


@dataclass
class _Held:
    record: dict
    end: float  # [s] when the episode ended
    window: float  # [s] how long after its end it can go on
    joinable: bool  # it ended safe (not because a car left the data)


class EpisodeLog:
    """Closed episode records, each held until its join window has passed (:func:`join_records`)."""

    def __init__(self, join: bool = True):
        self.join = join
        self._records = RecordTable(EPISODE_COLUMNS)
        self._held: dict[int, _Held] = {}

    def close(self, key: int, record: dict, time: float, window: float, joinable: bool) -> None:
        """An episode of pair ``key`` ended at ``time`` [s]; ``window`` [s]: the pair's ρ."""
        previous = self._held.pop(key, None)
        if previous is not None:  # not joinable (a car had left the data): it stays as it was
            self._records.append(previous.record)
        self._held[key] = _Held(record, time, window if self.join else 0.0, joinable)

    def resume(self, key: int, time: float) -> dict | None:
        """The record of the episode of pair ``key`` that ended safe within its window before ``time`` (it goes
        on; the caller closes it again), or None (a new episode opens; a held record is stored)."""
        held = self._held.pop(key, None)
        if held is None:
            return None
        if held.joinable and time - held.end <= held.window + TIME_EPS:
            return held.record
        self._records.append(held.record)
        return None

    def collide(self, key: int, time: float) -> dict | None:
        """The record of the episode of pair ``key`` that ended within its window before a collision at ``time``
        (or at that very step), removed from the held ones: the caller marks it and closes it again."""
        held = self._held.get(key)
        if held is None or held.record["collision"] or time - held.end > held.window + TIME_EPS:
            return None
        del self._held[key]
        return held.record

    def expire(self, time: float) -> None:
        """Store every held record whose window has passed before ``time`` [s]."""
        done = [key for key, held in self._held.items() if time - held.end > held.window + TIME_EPS]
        for key in sorted(done):
            self._records.append(self._held.pop(key).record)

    def frame(self) -> pd.DataFrame:
        """Every closed episode so far, the held ones last (EPISODE_COLUMNS)."""
        return self._records.frame(held.record for _, held in sorted(self._held.items()))


def join_records(first: dict, later: dict) -> dict:
    """One record of an episode and its continuation: the first's key, t_b, trigger and owed responses, the later
    one's end, the union of the responsible cars and the smallest margins."""
    responsible = {side for record in (first, later) for side in _sides(record["responsible"])}
    joined = dict(later)
    for name in ("episode_key", "episode_index", "situation", "conflict_area", "t_b_s", "trigger", "owed_a",
                 "owed_b"):
        joined[name] = first[name]
    joined["duration_s"] = later["t_end_s"] - first["t_b_s"]
    joined["responsible"] = "both" if responsible == {"a", "b"} else responsible.pop() if responsible else "none"
    for name in ("min_lon_margin_m", "min_lat_margin_m"):  # NaN (crossings' lateral margin) where both are
        joined[name] = float(np.fmin(first[name], later[name]))
    return joined


def _sides(responsible: str) -> set[str]:
    return {"a", "b"} if responsible == "both" else set() if responsible == "none" else {responsible}
