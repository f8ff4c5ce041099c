"""Columns of rows appended step by step (what a run or an audit records for the viewer), kept in memory or spooled
to files on disk.

An audit records every vehicle at every step (``trajectories.npz``) and every episode's steps
(``episode_states.npz``): kept in memory, that grows with the length of the run (Bologna's acosta, 600 s: 2.4 M
vehicle-steps and 2.0 M episode-steps, 1.14 GB of peak memory with the copies made to write them; 326 MB spooled).
Given a folder, a :class:`ColumnSpool` appends each column's rows to a file of its own (raw, native byte order)
whenever a few MB have gathered, so its memory is the buffer; the files are read back chunk by chunk when the
recording is written (:func:`sumo_rss.files.write_npz` streams a :class:`SpooledColumn`).
"""
from __future__ import annotations

import math
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import OutputError
from .files import output_error

BUFFER_BYTES = 4 << 20  # [bytes] gathered in memory before a spool appends its columns to their files
CHUNK_BYTES = 16 << 20  # [bytes] of a column read back at once


@dataclass(frozen=True)
class SpooledColumn:
    """A column on disk: ``rows`` rows, each of ``row_shape`` values of ``dtype``, in ``path``. ``np.asarray``
    reads it whole; :meth:`chunks` a few MB at a time."""

    path: Path
    dtype: np.dtype
    row_shape: tuple[int, ...]
    rows: int

    @property
    def shape(self) -> tuple[int, ...]:
        return (self.rows, *self.row_shape)

    def chunks(self) -> Iterator[np.ndarray]:
        """The rows in order, in arrays of at most CHUNK_BYTES."""
        per_row = math.prod(self.row_shape)
        step = max(1, CHUNK_BYTES // max(1, self.dtype.itemsize * per_row))
        with open(self.path, "rb") as source:
            for start in range(0, self.rows, step):
                count = min(step, self.rows - start)
                yield np.fromfile(source, self.dtype, count * per_row).reshape(count, *self.row_shape)

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> np.ndarray:
        whole = np.fromfile(self.path, self.dtype, self.rows * math.prod(self.row_shape)).reshape(self.shape)
        return whole if dtype is None else whole.astype(dtype, copy=False)


class ColumnSpool:
    """Rows of the named ``columns`` (name → dtype, or (dtype, shape of one row)), appended a batch at a time
    (:meth:`append`). Without ``folder`` they stay in memory; with one, they go to files in a new folder inside it
    (whoever made ``folder`` removes it) whenever BUFFER_BYTES have gathered. ``label``: the file they are recorded
    for, named where the spool cannot be written."""

    def __init__(self, columns: Mapping[str, np.dtype | type | tuple[np.dtype | type, tuple[int, ...]]],
                 folder: Path | None = None, label: str = "the recording"):
        shapes = {name: spec if isinstance(spec, tuple) else (spec, ()) for name, spec in columns.items()}
        self._dtype = {name: np.dtype(dtype) for name, (dtype, _) in shapes.items()}
        self._row_shape = {name: tuple(shape) for name, (_, shape) in shapes.items()}
        self._buffered: dict[str, list[np.ndarray]] = {name: [] for name in shapes}
        self._buffered_rows = self._buffered_bytes = self._written_rows = 0
        self._files: dict[str, Path] | None = None
        self._label = label
        if folder is not None:
            try:
                own = Path(tempfile.mkdtemp(prefix="spool-", dir=folder))
            except OSError as exc:
                raise self._error(Path(folder), exc) from None
            self._files = {name: own / f"{name}.bin" for name in shapes}
            for path in self._files.values():
                self._write(path, b"")

    def __len__(self) -> int:
        return self._written_rows + self._buffered_rows

    def append(self, **values: np.ndarray) -> None:
        """One batch of rows: every column, each with the same number of rows."""
        rows = {name: np.ascontiguousarray(values[name], dtype=dtype) for name, dtype in self._dtype.items()}
        count = {len(value) for value in rows.values()}
        if len(count) != 1 or any(value.shape[1:] != self._row_shape[name] for name, value in rows.items()):
            raise ValueError(f"expected rows of {self._row_shape} for each of the columns, got "
                             f"{ {name: value.shape for name, value in rows.items()} }")
        for name, value in rows.items():
            self._buffered[name].append(value)
            self._buffered_bytes += value.nbytes
        self._buffered_rows += count.pop()
        if self._files is not None and self._buffered_bytes >= BUFFER_BYTES:
            self._flush()

    def column(self, name: str) -> np.ndarray | SpooledColumn:
        """Every row of column ``name``: an array, or (spooled) its file."""
        if self._files is None:
            return self._joined(name)
        self._flush()
        return SpooledColumn(self._files[name], self._dtype[name], self._row_shape[name], self._written_rows)

    def _joined(self, name: str) -> np.ndarray:
        parts = self._buffered[name]
        return np.concatenate(parts) if parts else np.zeros((0, *self._row_shape[name]), dtype=self._dtype[name])

    def _flush(self) -> None:
        if not self._buffered_rows or self._files is None:
            return
        for name, path in self._files.items():
            self._write(path, self._joined(name).tobytes(), append=True)
            self._buffered[name] = []
        self._written_rows += self._buffered_rows
        self._buffered_rows = self._buffered_bytes = 0

    def _write(self, path: Path, data: bytes, append: bool = False) -> None:
        try:
            with open(path, "ab" if append else "wb") as target:
                target.write(data)
        except OSError as exc:
            raise self._error(path.parent, exc) from None

    def _error(self, folder: Path, exc: OSError) -> OutputError:
        """What cannot be written, as the file the rows are for, and where they were spooled."""
        error = output_error(Path(self._label), OSError(exc.errno, exc.strerror))
        return OutputError(f"{error} (its rows go to {folder} while they are recorded)")
