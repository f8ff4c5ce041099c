"""The compiled loops of :mod:`.fcd_names`: an open-addressing hash table (linear probing, FNV-1a over the bytes)
of the names numbered so far, kept as bytes, in which the values of a time step's text are looked up where they
lie, without a Python string per value."""
from __future__ import annotations

import numpy as np

from ..jit import kernel

FNV_OFFSET = np.uint64(14695981039346656037)
FNV_PRIME = np.uint64(1099511628211)


@kernel
def _slot(data, start, end, mask):
    """The first slot of the name ``data[start:end]`` (uint8) in a table of ``mask + 1`` slots."""
    h = FNV_OFFSET
    for i in range(start, end):
        h = (h ^ np.uint64(data[i])) * FNV_PRIME
    return np.int64(h & np.uint64(mask))


@kernel
def _same(data, start, end, store, first, last):
    """Whether ``data[start:end]`` and ``store[first:last]`` are the same bytes."""
    if end - start != last - first:
        return False
    for k in range(end - start):
        if data[start + k] != store[first + k]:
            return False
    return True


@kernel
def find_numbers(data, bounds, slots, store, starts):
    """[n] int64: the number of each name ``data[bounds[j, 0]:bounds[j, 1]]`` (uint8), -1 where not numbered yet;
    ``slots``: the table (a power of two of numbers, -1 empty), name k's bytes ``store[starts[k]:starts[k + 1]]``."""
    mask = slots.size - 1
    out = np.empty(bounds.shape[0], dtype=np.int64)
    for j in range(bounds.shape[0]):
        start, end = bounds[j, 0], bounds[j, 1]
        slot = _slot(data, start, end, mask)
        number = slots[slot]
        while number >= 0 and not _same(data, start, end, store, starts[number], starts[number + 1]):
            slot = (slot + 1) & mask
            number = slots[slot]
        out[j] = number
    return out


@kernel
def add_numbers(slots, store, starts, first, last):
    """Enter the names numbered ``first`` to ``last - 1`` (their bytes in ``store``, as for find_numbers) into
    ``slots``, which has room for them."""
    mask = slots.size - 1
    for number in range(first, last):
        slot = _slot(store, starts[number], starts[number + 1], mask)
        while slots[slot] >= 0:
            slot = (slot + 1) & mask
        slots[slot] = number
