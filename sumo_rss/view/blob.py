"""The page's binary data: typed arrays packed one after the other, then gzip'ed (viewer.js ``arrays`` reads them).

Each array is stored with its bytes shuffled into planes (every value's first byte, then every second byte, ...):
the high bytes of slowly changing numbers repeat, and gzip packs them ~2x better than interleaved. A smooth series
(a vehicle's positions) may be stored as differences to the previous element of the same key, and float values as
integer multiples of a unit (missing values as the type's minimum).
"""
from __future__ import annotations

import gzip
from dataclasses import dataclass, field

import numpy as np

JS_TYPES = {np.dtype(np.float64): "f8", np.dtype(np.float32): "f4", np.dtype(np.int32): "i4",
            np.dtype(np.uint32): "u4", np.dtype(np.int16): "i2", np.dtype(np.uint16): "u2", np.dtype(np.uint8): "u1"}


def previous_of(keys: np.ndarray) -> np.ndarray:
    """Per element, the index of the last element before it with the same key (-1: the key's first)."""
    order = np.lexsort((np.arange(len(keys)), keys))
    previous = np.full(len(keys), -1, dtype=np.int64)
    same = keys[order][1:] == keys[order][:-1]
    previous[order[1:][same]] = order[:-1][same]
    return previous


@dataclass
class Blob:
    """The arrays added so far; ``index`` gives each one's [type, byte offset, length, options] for the page
    (options: ``unit``: quantised floats, read back as float32 × unit; ``delta_by``: stored as differences along
    the named key array, added before it)."""

    parts: list[bytes] = field(default_factory=list)
    index: dict[str, list] = field(default_factory=dict)
    keys: dict[str, np.ndarray] = field(default_factory=dict)  # the arrays added by :meth:`add`, as given
    size: int = 0

    def add(self, name: str, array: np.ndarray, delta_by: str | None = None) -> None:
        """``array`` as it is (a type of JS_TYPES); ``delta_by``: as differences to the previous element with the
        same value of the array of that name (integer types; wrapping around as the type does)."""
        array = np.ascontiguousarray(array)
        self.keys[name] = array
        options: dict = {}
        if delta_by is not None:
            before = previous_of(self.keys[delta_by])
            wide = array.astype(np.int64)
            array = np.where(before >= 0, wide - wide[np.maximum(before, 0)], wide).astype(array.dtype)
            options["delta_by"] = delta_by
        self._append(name, array, options)

    def add_quantised(self, name: str, values: np.ndarray, unit: float, dtype: type = np.int32) -> None:
        """Float ``values`` as ``dtype`` multiples of ``unit`` (NaN as the type's minimum, beyond its range clipped)."""
        values = np.asarray(values, dtype=np.float64)
        info = np.iinfo(dtype)
        scaled = np.clip(np.round(np.where(np.isnan(values), 0.0, values) / unit), info.min + 1, info.max)
        self._append(name, np.where(np.isnan(values), info.min, scaled).astype(dtype), {"unit": unit})

    def _append(self, name: str, array: np.ndarray, options: dict) -> None:
        little = array.astype(array.dtype.newbyteorder("<"), copy=False)
        data = little.view(np.uint8).reshape(-1, array.dtype.itemsize).T.tobytes()  # byte planes
        self.index[name] = [JS_TYPES[array.dtype], self.size, int(array.size), options]
        padding = -len(data) % 8
        self.parts.append(data + b"\0" * padding)
        self.size += len(data) + padding

    def compressed(self) -> bytes:
        """The gzip of the blob (no time stamp: the same run gives the same page)."""
        return gzip.compress(b"".join(self.parts), compresslevel=6, mtime=0)
