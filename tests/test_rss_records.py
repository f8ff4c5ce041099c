"""The audit's result rows (closed episodes, violations) kept in chunks: the same table as one DataFrame built from
the rows, in append order, at a fraction of the memory of one dict per row."""
from __future__ import annotations

import tracemalloc

import pandas as pd

from sumo_rss.rss.records import EPISODE_COLUMNS, RULE5_UNCHECKED, RecordTable

COLUMNS = ["vehicle", "t_s", "index", "collision"]


def _rows(n: int) -> list[dict]:
    # Strings built at run time (as ids read from a snapshot are): equal values, distinct objects.
    return [{"vehicle": "".join(["car.", str(i % 3)]), "t_s": 0.1 * i, "index": i, "collision": i % 4 == 0}
            for i in range(n)]


def test_rows_across_chunks_and_pending_rows_make_the_table_of_all_rows_in_order():
    table = RecordTable(COLUMNS, chunk_rows=3)
    table.extend(_rows(7))
    pending = _rows(9)[7:]
    frame = table.frame(pending)
    pd.testing.assert_frame_equal(frame, pd.DataFrame(_rows(9), columns=COLUMNS))
    assert len(table) == 7 and len(table.frame()) == 7  # pending rows are not stored


def test_an_empty_table_has_the_columns():
    assert list(RecordTable(COLUMNS).frame().columns) == COLUMNS


def test_equal_strings_in_a_chunk_share_one_object():
    table = RecordTable(COLUMNS, chunk_rows=100)
    table.extend(_rows(6))
    vehicles = table.frame()["vehicle"]
    assert vehicles[0] is vehicles[3] and vehicles[1] is vehicles[4]


def test_an_episode_row_costs_a_few_hundred_bytes():
    """A closed episode as the tracker makes it: 25 fields, a unique key, ids repeated across episodes. One dict
    per row cost ~1.2 kB here; a 24 h highway run closes ~2 million episodes."""
    def episode(i: int) -> dict:
        a, b = f"flow_{i % 40}.{i % 300}", f"flow_{(i + 7) % 40}.{i % 200}"
        return {"run_id": "highway_dense-s0", "episode_key": f"{a}|{b}|{i % 5}", "vehicle_a": a, "vehicle_b": b,
                "class_a": "background", "class_b": "background", "episode_index": i % 5,
                "situation": "same-direction", "conflict_area": "", "t_b_s": 0.1 * i, "t_end_s": 0.1 * i + 1.0,
                "duration_s": 1.0, "trigger": "lon", "owed_a": "lon:brake-min", "owed_b": "none",
                "responsible": "none", "min_lon_margin_m": -1.5, "min_lat_margin_m": -0.2, "collision": False,
                "collider": "", "victim": "", "ended_by": "safe", **RULE5_UNCHECKED}

    n = 20_000
    tracemalloc.start()
    try:
        table = RecordTable(EPISODE_COLUMNS)
        for i in range(n):
            table.append(episode(i))
        per_row = tracemalloc.get_traced_memory()[0] / n
    finally:
        tracemalloc.stop()
    assert len(table) == n and per_row < 500.0
