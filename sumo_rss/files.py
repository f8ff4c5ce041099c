"""Atomic writes (temp file in the same folder + rename): a reader sees the old file or the whole new one.

Writing errors (disk full, file too large, a file where a folder must be, not writable) are raised as
:class:`~sumo_rss.errors.OutputError` naming the file and what is expected, never as a bare ``[Errno 28]``.
"""
from __future__ import annotations

import csv
import errno
import io
import json
import math
import os
import shutil
import tempfile
import zipfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import OutputError, SumoRssError

CSV_FLOAT_FORMAT = "%.6f"  # every CSV the project writes: 6 decimals, so the same run gives the same bytes
SANE_MAGNITUDE = 1e10  # no number written into a CSV is larger (positions are at most 1e8 m, times 1e9 s)
_REASONS = {  # what an OSError while writing means for the user
    errno.ENOSPC: "no space left on its disk (free some, or write elsewhere)",
    errno.EDQUOT: "the disk quota is exhausted (free some space, or write elsewhere)",
    errno.EFBIG: "the file grew beyond the file-size limit of this process (ulimit -f)",
    errno.EACCES: "permission denied (expected a folder this user may write to)",
    errno.EPERM: "operation not permitted (expected a folder this user may write to)",
    errno.EROFS: "its file system is read-only",
    errno.EISDIR: "a folder stands there (expected a file, or nothing)",
    errno.ENAMETOOLONG: "the file name is too long",
    errno.EIO: "an input/output error of its disk",
}


def output_error(path: Path, exc: OSError) -> OutputError:
    """``exc``, raised while writing ``path``, as a message naming the file (or the file that stands where a
    folder must be) and what is expected."""
    path = _final_name(Path(exc.filename) if isinstance(exc.filename, str) and exc.filename else Path(path))
    if exc.errno in (errno.ENOTDIR, errno.EEXIST):
        blocking = next((p for p in (path, *path.parents) if p.exists() and not p.is_dir()), None)
        if blocking is not None:
            return OutputError(f"{path}: cannot be written: {blocking} is a file (expected a folder there)")
    reason = _REASONS.get(exc.errno, exc.strerror or str(exc))
    return OutputError(f"{path}: cannot be written: {reason}")


def _final_name(path: Path) -> Path:
    """The file a temporary path of :func:`atomic_path` or :func:`write_file_set` is written for (``.x.tmp`` → x;
    a temporary of a temporary too)."""
    name = path.name
    while name.startswith(".") and name.endswith(".tmp") and len(name) > len("..tmp"):
        name = name[1:-len(".tmp")]
    return path.with_name(name)


def check_output_folder(folder: Path, option: str, files: tuple[str, ...] = ()) -> None:
    """Before the work starts: that ``folder`` (given as ``option``, e.g. '--out') is a folder or can be created
    as one, that it may be written to, and that none of the ``files`` to be written into it is a folder.
    OutputError naming the option and what is expected otherwise; nothing is created."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{option} must be a folder; {folder} is a file")
    existing = next((p for p in (folder, *folder.parents) if p.exists()), Path("."))
    if not existing.is_dir():
        raise OutputError(f"{option} {folder}: {existing} is a file (expected a folder there)")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {folder}: {existing} is not writable (expected a folder this user may write "
                          "to)")
    for name in files:
        if (folder / name).is_dir():
            raise OutputError(f"{option} {folder}: {folder / name} is a folder (expected a file there, or nothing: "
                              f"the results are written as {name})")


def make_folder(folder: Path) -> None:
    """``folder`` and its parents, as needed; OutputError naming what is in the way."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(folder, exc) from None


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path next to ``path`` to write to; renamed onto ``path`` when the block ends without error."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        try:
            yield tmp
            os.replace(tmp, path)
        except OSError as exc:
            raise output_error(path, exc) from exc
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def scratch_folder(out: Path) -> Iterator[Path]:
    """A hidden temporary folder inside the output folder ``out`` (made if missing) for what a long piece of work
    spools to disk before its results are written (:mod:`sumo_rss.spool`); removed with its files when the block
    ends, however it ends, and ``out`` too where it was made for the work and nothing was written into it."""
    out = Path(out)
    made = not out.exists()
    make_folder(out)
    try:
        folder = Path(tempfile.mkdtemp(prefix=".spool-", dir=out))
    except OSError as exc:
        raise output_error(out / ".spool", exc) from None
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        if made and not any(out.iterdir()):
            out.rmdir()


def write_file_set(writers: Mapping[Path, Callable[[Path], None]]) -> None:
    """Write several files as a set: each writer writes its file's temporary path; only when every one has
    succeeded are they renamed into place, so a failure (disk full, a folder in the way) leaves every file as it
    was: none of the new ones, no temporary files."""
    temporaries = {path: path.with_name(f".{path.name}.tmp") for path in writers}
    try:
        for path, tmp in temporaries.items():
            if path.is_dir():
                raise OutputError(f"{path}: cannot be written: a folder stands there (expected a file, or nothing)")
            try:
                writers[path](tmp)
            except OSError as exc:
                raise output_error(path, exc) from exc
        for path, tmp in temporaries.items():
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise output_error(path, exc) from exc
    finally:
        for tmp in temporaries.values():
            tmp.unlink(missing_ok=True)


def write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def json_text(data: object) -> str:
    """``data`` as indented JSON with sorted keys (numpy scalars and arrays as their Python values)."""
    return json.dumps(data, indent=2, sort_keys=True, default=_plain) + "\n"


def write_json(path: Path, data: object) -> None:
    """``data`` as :func:`json_text`."""
    write_text(path, json_text(data))


def read_json_object(path: Path) -> dict | None:
    """The JSON object in ``path``; None where the file is missing, unreadable, not JSON or not an object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def read_csv_table(path: Path, writer: str, **read_csv: object) -> pd.DataFrame:
    """The CSV file ``path`` as pandas reads it with the options ``read_csv``; SumoRssError naming the file where it
    is not a CSV file as ``writer`` (e.g. ``'sumo-rss batch'``) writes it, or where its last row is cut off: pandas
    would fill the missing cells of a file that a copy or a full disk cut mid-row with empty ones. Every CSV
    sumo-rss writes ends with a line end; a last line without one (a file edited by hand) is accepted where it has
    all the header's cells."""
    try:
        table = pd.read_csv(path, **read_csv)
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise SumoRssError(f"{path}: not a CSV file as {writer} writes it ({' '.join(str(exc).split())})") from None
    cells = _last_line_cells(path)
    if cells is not None and cells < len(table.columns):
        raise SumoRssError(f"{path}: line {len(table) + 1}: expected {len(table.columns)} cells (one per column of "
                           f"the header, as {writer} writes them), got {cells} and no line end: the file is cut off "
                           "mid-row")
    return table


CSV_TAIL_BYTES = 1 << 16  # read of a CSV's end to find its last line (rows are far shorter)


def _last_line_cells(path: Path) -> int | None:
    """How many cells the last line of the CSV file ``path`` has where it does not end with a line end (None where
    it does, or the file is empty)."""
    with open(path, "rb") as source:
        size = source.seek(0, os.SEEK_END)
        source.seek(max(0, size - CSV_TAIL_BYTES))
        tail = source.read()
    if not tail or tail.endswith((b"\n", b"\r")):
        return None
    last = tail.rsplit(b"\n", 1)[-1].decode("utf-8", "replace")
    return len(next(csv.reader([last]), []))


def read_npz(path: Path, what: str) -> dict[str, np.ndarray]:
    """The arrays of the .npz file ``path``; SumoRssError naming the file where it is not ``what`` (e.g. ``'an
    episode-state file as sumo-rss writes it'``): not a zip archive at all (numpy would say it holds pickled data and
    suggest loading it unsafely), or a damaged one."""
    if path.is_file() and not zipfile.is_zipfile(path):
        raise SumoRssError(f"{path}: not {what} (not a .npz archive: not a zip file)")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {name: data[name] for name in data.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise SumoRssError(f"{path}: not {what} ({exc})") from None


def _plain(value: object) -> object:
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise TypeError(f"expected JSON data, got {type(value).__name__}: {value!r}")


def csv_writer(frame: pd.DataFrame) -> Callable[[Path], None]:
    """A function writing ``frame`` to a path without its index, floats with CSV_FLOAT_FORMAT, '\\n' line ends;
    ValueError instead where a number is infinite or beyond SANE_MAGNITUDE (the inputs are checked so that none
    is: one that got through is a bug, and no absurd number is ever written into a CSV)."""
    def write(path: Path) -> None:
        numbers = frame.select_dtypes(include="number")
        absurd = ~(numbers.abs() <= SANE_MAGNITUDE) & numbers.notna()
        if absurd.to_numpy().any():
            column = absurd.any().idxmax()
            row = int(absurd[column].to_numpy().argmax())
            raise ValueError(f"{path.with_name(path.name.removeprefix('.').removesuffix('.tmp'))}: not written: line "
                             f"{row + 2}, column {column!r} would be {float(numbers[column].iloc[row]):g}")
        frame.to_csv(path, index=False, float_format=CSV_FLOAT_FORMAT, lineterminator="\n")
    return write


def write_csv(frame: pd.DataFrame, path: Path) -> None:
    """``frame`` as :func:`csv_writer` writes it, atomically."""
    with atomic_path(path) as tmp:
        csv_writer(frame)(tmp)


NPZ_COMPRESS_LEVEL = 1  # zlib's fastest: acosta's 600 s audit writes 181 MB of arrays into 70.6 MB in 10.2 s, 67.4 MB in 14.6 s at level 6


def write_npz(path: Path, arrays: Mapping[str, object]) -> None:
    """``arrays`` as a compressed ``.npz`` (``numpy.load`` reads it), written atomically and byte for byte the same
    for the same arrays: every member has a fixed time stamp (``numpy.savez`` stamps the current time). A value is
    an array, a function returning one (called when its member is written, so that only one is in memory at a
    time) or a column spooled on disk (:class:`~sumo_rss.spool.SpooledColumn`: streamed a chunk at a time, the same
    bytes as its array). Arrays of Python objects are refused (they would need pickle to read)."""
    with atomic_path(path) as tmp, zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, value in arrays.items():
            member = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_DEFLATED
            # Python 3.11 has no public way to give a ZipInfo its level (3.13: ZipInfo.compress_level);
            # ZipFile.open(member, "w") reads this attribute.
            member._compresslevel = NPZ_COMPRESS_LEVEL
            if hasattr(value, "chunks"):
                _write_npy_chunks(archive, member, value)
                continue
            value = np.asarray(value() if callable(value) else value)
            if value.dtype.hasobject:
                raise TypeError(f"{path.name}: {name}: expected an array of numbers or strings, got objects")
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, value, allow_pickle=False)
            archive.writestr(member, buffer.getvalue())


def _write_npy_chunks(archive: zipfile.ZipFile, member: zipfile.ZipInfo, column) -> None:
    """A spooled column as the ``.npy`` member ``member``, chunk by chunk: the bytes ``numpy.lib.format.write_array``
    writes for its array (the same header, then the rows in order)."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": np.lib.format.dtype_to_descr(column.dtype),
                                                  "fortran_order": False, "shape": column.shape})
    # As ZipFile.writestr does: the size known up front decides whether the member needs ZIP64 records.
    member.file_size = header.tell() + column.dtype.itemsize * math.prod(column.shape)
    with archive.open(member, "w") as target:
        target.write(header.getvalue())
        for chunk in column.chunks():
            target.write(chunk.tobytes())
