"""The batch CSVs as ``sumo-rss report`` reads them, checked: every column the report uses is there, and the cells
of number columns are finite numbers (empty only where a run writes empty cells), those of word columns one of
their words. A batch folder edited by hand or damaged on disk is an error naming the file, the column, the line and
what is expected, never a traceback from pandas or matplotlib."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SumoRssError, shown
from ..rss.auditor import COLLISION_COLUMNS
from ..rss.episode_states import PAIR_STATE_COLUMNS
from ..rss.records import EPISODE_COLUMNS, OCCLUSION_COLUMNS, RESPONSIBLE_VALUES, RULE5_COLUMNS, VIOLATION_COLUMNS

RUN_KEYS = ["run_id", "scenario", "variant", "seed"]  # the first columns of every concatenated batch CSV
COLUMNS = {  # the columns of each batch CSV (rule 5's, appended later, are not required: older batches still read)
    "episodes": RUN_KEYS + [c for c in EPISODE_COLUMNS[1:] if c not in RULE5_COLUMNS],
    "violations": RUN_KEYS + VIOLATION_COLUMNS[1:],
    "collisions": RUN_KEYS + [c for c in COLLISION_COLUMNS[1:] if c != "could_have_avoided"],
    "pair_states": RUN_KEYS + PAIR_STATE_COLUMNS[1:],
    "occlusion": RUN_KEYS + OCCLUSION_COLUMNS[1:],  # rule 4 runs only
    "batch_summary": RUN_KEYS + ["status"],  # those the report uses
}
# Number columns: True where a run writes empty cells (a junction episode has no lateral margin or gap).
NUMBERS = {
    "episodes": {"seed": False, "episode_index": False, "t_b_s": False, "t_end_s": False, "duration_s": False,
                 "min_lon_margin_m": True, "min_lat_margin_m": True},
    "violations": {"seed": False, "bound": False, "worst_actual": False, "excess": False, "t_start_s": False,
                   "t_end_s": False},
    "collisions": {"seed": False, "time_s": False},
    "pair_states": {"seed": False, "time_s": False, "lon_gap_m": False, "lon_d_min_m": False, "lat_gap_m": True,
                    "lat_d_min_m": True},
    "occlusion": {"seed": False, "t_b_s": False, "exposure_a_s": True, "exposure_b_s": True},
    "ego_trace": {"time_s": False, "speed_ms": False},
    "batch_summary": {"seed": False},
}
WORDS = {"episodes": {"responsible": RESPONSIBLE_VALUES, "collision": ("True", "False")},
         "occlusion": {"occluded_at_t_b": ("True", "False")},
         "batch_summary": {"status": ("ok", "failed", "missing", "interrupted")}}


def check_table(table: pd.DataFrame, path: Path, name: str, columns: list[str] | None = None) -> pd.DataFrame:
    """``table`` (read from ``path``) if every one of ``columns`` (default: the batch CSV ``name``'s) is present and
    its number and word columns hold what a run writes; SumoRssError naming the file, column, line and expected form
    otherwise."""
    expected = COLUMNS.get(name, []) if columns is None else columns
    missing = [c for c in expected if c not in table.columns]
    if missing:
        raise SumoRssError(f"{path}: column {missing[0]!r} is missing (expected the columns {', '.join(expected)}, as "
                           "'sumo-rss batch' writes them)")
    for column, empty_allowed in NUMBERS.get(name, {}).items():
        text = table[column].astype(str)
        numbers = pd.to_numeric(table[column], errors="coerce").astype(float)
        bad = ~np.isfinite(numbers.to_numpy()) & ~((text.str.strip() == "").to_numpy() & empty_allowed)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise SumoRssError(f"{path}: line {row + 2}: column {column!r}: expected a finite number"
                               f"{' or an empty cell' if empty_allowed else ''}, got {shown(text.iloc[row])}")
    for column, words in WORDS.get(name, {}).items():
        bad = ~table[column].astype(str).isin(words).to_numpy()
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise SumoRssError(f"{path}: line {row + 2}: column {column!r}: expected one of {', '.join(words)}, got "
                               f"{shown(str(table[column].iloc[row]))}")
    return table
