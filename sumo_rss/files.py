"""Atomic writes (temp file in the same folder + rename): a reader sees the old file or the whole new one."""
from __future__ import annotations

import io
import json
import os
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

CSV_FLOAT_FORMAT = "%.6f"  # every CSV the project writes: 6 decimals, so the same run gives the same bytes


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path next to ``path`` to write to; renamed onto ``path`` when the block ends without error."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_json(path: Path, data: object) -> None:
    """``data`` as indented JSON with sorted keys (numpy scalars and arrays as their Python values)."""
    write_text(path, json.dumps(data, indent=2, sort_keys=True, default=_plain) + "\n")


def read_json_object(path: Path) -> dict | None:
    """The JSON object in ``path``; None where the file is missing, unreadable, not JSON or not an object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _plain(value: object) -> object:
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise TypeError(f"expected JSON data, got {type(value).__name__}: {value!r}")


def write_csv(frame: pd.DataFrame, path: Path) -> None:
    """``frame`` without its index, floats with CSV_FLOAT_FORMAT, '\\n' line ends."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, float_format=CSV_FLOAT_FORMAT, lineterminator="\n")


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """``arrays`` as a compressed ``.npz`` (``numpy.load`` reads it), written atomically and byte for byte the same
    for the same arrays: every member has a fixed time stamp (``numpy.savez`` stamps the current time). Arrays of
    Python objects are refused (they would need pickle to read)."""
    with atomic_path(path) as tmp, zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, value in arrays.items():
            value = np.asarray(value)
            if value.dtype.hasobject:
                raise TypeError(f"{path.name}: {name}: expected an array of numbers or strings, got objects")
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, value, allow_pickle=False)
            member = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(member, buffer.getvalue())
