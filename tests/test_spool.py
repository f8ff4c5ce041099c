"""Recordings spooled to disk (sumo_rss.spool): the same files as kept in memory, a bounded buffer, and a scratch
folder that leaves nothing behind. That an audit's spooled recordings equal a run's in-memory ones on real traffic:
tests/test_view_data.py (the audit spools, the run does not)."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss import spool as spool_module
from sumo_rss.files import scratch_folder, write_npz
from sumo_rss.spool import ColumnSpool, SpooledColumn

COLUMNS = {"vehicle": np.int32, "x": np.float32, "bounds": (np.float32, (2,)), "dangerous": bool}


def _batches(seed: int = 3, steps: int = 400):
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        n = int(rng.integers(0, 40))  # steps without a row too
        yield {"vehicle": rng.integers(0, 1000, n), "x": rng.normal(0.0, 1e3, n), "bounds": rng.normal(size=(n, 2)),
               "dangerous": rng.random(n) < 0.3}


@pytest.fixture
def small_buffers(monkeypatch):
    """Buffers and read-back chunks of a few rows: many flushes and chunks, and rows split across them."""
    monkeypatch.setattr(spool_module, "BUFFER_BYTES", 1000)
    monkeypatch.setattr(spool_module, "CHUNK_BYTES", 700)


def test_a_spooled_recording_writes_the_bytes_of_the_same_recording_kept_in_memory(tmp_path, small_buffers):
    memory, disk = ColumnSpool(COLUMNS), ColumnSpool(COLUMNS, tmp_path)
    expected = {name: [] for name in COLUMNS}
    for batch in _batches():
        memory.append(**batch)
        disk.append(**batch)
        for name, values in batch.items():
            dtype = COLUMNS[name][0] if isinstance(COLUMNS[name], tuple) else COLUMNS[name]
            expected[name].append(np.asarray(values, dtype=dtype))
    assert len(memory) == len(disk) == sum(len(v) for v in expected["x"]) > 5000
    for name in COLUMNS:
        column = disk.column(name)
        assert isinstance(column, SpooledColumn) and column.shape == memory.column(name).shape
        assert np.array_equal(np.asarray(column), np.concatenate(expected[name]))
        assert len(list(column.chunks())) > 5  # read back a few rows at a time
    write_npz(tmp_path / "memory.npz", {name: memory.column(name) for name in COLUMNS})
    write_npz(tmp_path / "disk.npz", {name: disk.column(name) for name in COLUMNS})
    assert (tmp_path / "memory.npz").read_bytes() == (tmp_path / "disk.npz").read_bytes()
    with np.load(tmp_path / "disk.npz") as data:
        assert data["bounds"].dtype == np.float32 and data["bounds"].shape == (len(disk), 2)
        assert np.array_equal(data["dangerous"], np.concatenate(expected["dangerous"]))


def test_an_empty_spool_writes_empty_columns_of_its_types(tmp_path):
    disk = ColumnSpool(COLUMNS, tmp_path)
    write_npz(tmp_path / "empty.npz", {name: disk.column(name) for name in COLUMNS})
    with np.load(tmp_path / "empty.npz") as data:
        assert data["bounds"].shape == (0, 2) and data["vehicle"].dtype == np.int32 and len(data["x"]) == 0


def test_a_spool_holds_at_most_its_buffer_in_memory_and_the_rest_in_its_files(tmp_path, small_buffers):
    disk = ColumnSpool(COLUMNS, tmp_path)
    largest_batch = 40 * (4 + 4 + 8 + 1)  # [bytes] of the rows of one batch
    for batch in _batches():
        disk.append(**batch)
        assert disk._buffered_bytes < spool_module.BUFFER_BYTES + largest_batch
    on_disk = sum(path.stat().st_size for path in tmp_path.glob("spool-*/*.bin"))
    assert on_disk + disk._buffered_bytes == len(disk) * (4 + 4 + 8 + 1)
    assert on_disk > 50 * spool_module.BUFFER_BYTES


def test_rows_of_another_shape_are_refused(tmp_path):
    disk = ColumnSpool(COLUMNS, tmp_path)
    with pytest.raises(ValueError, match="rows of"):
        disk.append(vehicle=[1, 2], x=[1.0, 2.0], bounds=[1.0, 2.0], dangerous=[True, False])
    with pytest.raises(ValueError, match="rows of"):
        disk.append(vehicle=[1, 2], x=[1.0], bounds=[[1.0, 2.0]] * 2, dangerous=[True, False])


def test_the_scratch_folder_goes_and_the_output_folder_made_for_it_too_unless_written_into(tmp_path):
    out = tmp_path / "audit"
    with scratch_folder(out) as folder:
        assert folder.parent == out and folder.name.startswith(".")
        ColumnSpool(COLUMNS, folder).append(vehicle=[1], x=[1.0], bounds=[[1.0, 2.0]], dangerous=[True])
    assert not out.exists()  # made for the work, nothing written: gone
    with pytest.raises(KeyboardInterrupt), scratch_folder(out) as folder:
        (out / "episodes.csv").write_text("x\n")
        raise KeyboardInterrupt
    assert [p.name for p in out.iterdir()] == ["episodes.csv"]  # the results stay, the scratch folder does not
    with scratch_folder(out) as folder:
        pass
    assert [p.name for p in out.iterdir()] == ["episodes.csv"]  # a folder that was there stays
