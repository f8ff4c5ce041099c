"""The rows a run's audit collects (closed episodes, violations), kept compactly: a long run closes tens of episodes
per simulated second, and one Python dict per row (~2 KB with its strings) would grow a 24 h run to gigabytes."""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import pandas as pd

RESPONSIBLE_VALUES = ("a", "b", "both", "none")  # episodes.csv's 'responsible': the cars with a violation
# Rule 5 (rss.md §8, docs/rss.md): the columns episodes.csv gained last, their values where an episode is not asked,
# and the constraint of its violations.
RULE5_COLUMNS = ("evasive_checked", "evasive_last_s", "rule5_responsible")
EPISODE_COLUMNS = ["run_id", "episode_key", "vehicle_a", "vehicle_b", "class_a", "class_b", "episode_index",
                   "situation", "conflict_area", "t_b_s", "t_end_s", "duration_s", "trigger", "owed_a", "owed_b",
                   "responsible",
                   "min_lon_margin_m", "min_lat_margin_m", "collision", "collider", "victim", "ended_by",
                   *RULE5_COLUMNS]
RULE5_UNCHECKED = {"evasive_checked": False, "evasive_last_s": float("nan"), "rule5_responsible": ""}
EVASIVE_CONSTRAINT = "evasive-effort"
# Rule 4 (rss.md §9, docs/rss.md): occlusion.csv's columns (one row per episode whose cars could not see each other
# at some step; episodes.csv keeps its columns) and the constraint of a hidden car's unreasonable speed.
OCCLUSION_COLUMNS = ["run_id", "episode_key", "vehicle_a", "vehicle_b", "episode_index", "situation", "t_b_s",
                     "exposure_a_s", "exposure_b_s", "occluded_at_t_b"]
OCCLUSION_CONSTRAINT = "occluded-unreasonable-speed"
VIOLATION_COLUMNS = ["run_id", "episode_key", "vehicle_id", "vehicle_class", "role", "constraint", "bound",
                     "worst_actual", "excess", "t_start_s", "t_end_s"]

CHUNK_ROWS = 4096


class RecordTable:
    """Rows of fixed columns in append order. Every ``chunk_rows`` rows become one DataFrame (8 bytes per number
    or string reference); equal strings within a chunk share one object (vehicle ids, classes, constraint names
    repeat in most rows)."""

    def __init__(self, columns: Sequence[str], chunk_rows: int = CHUNK_ROWS):
        self.columns = list(columns)
        self.chunk_rows = chunk_rows
        self._rows: list[tuple] = []
        self._chunks: list[pd.DataFrame] = []
        self._strings: dict[str, str] = {}

    def append(self, record: Mapping[str, object]) -> None:
        """Add one row (a mapping with at least every column)."""
        strings = self._strings  # one list comprehension: a generator calling a method per value took 1.5x as long
        self._rows.append(tuple([strings.setdefault(value, value) if isinstance(value, str) else value
                                 for value in map(record.__getitem__, self.columns)]))
        if len(self._rows) >= self.chunk_rows:
            self._chunks.append(self._frame(self._rows))
            self._rows, self._strings = [], {}

    def extend(self, records: Iterable[Mapping[str, object]]) -> None:
        for record in records:
            self.append(record)

    def frame(self, pending: Iterable[Mapping[str, object]] = ()) -> pd.DataFrame:
        """Every row so far, followed by ``pending`` rows (not stored), as one DataFrame with ``columns``."""
        tail = self._rows + [tuple(r[c] for c in self.columns) for r in pending]
        parts = self._chunks + ([self._frame(tail)] if tail else [])
        if not parts:
            return pd.DataFrame(columns=self.columns)
        return pd.concat(parts, ignore_index=True)

    def __len__(self) -> int:
        return len(self._chunks) * self.chunk_rows + len(self._rows)  # every chunk holds chunk_rows rows

    def _frame(self, rows: list[tuple]) -> pd.DataFrame:
        return pd.DataFrame.from_records(rows, columns=self.columns)
