"""Atomic writes (temp file in the same folder + rename): a reader sees the old file or the whole new one."""
from __future__ import annotations

import json
import os
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
