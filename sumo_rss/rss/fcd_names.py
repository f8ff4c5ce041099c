"""The names of an FCD (vehicle ids, lane ids, vTypes) as numbers: each distinct name is made a Python string and
numbered once (:class:`.numbering.Numbering`, in order of first appearance), and a time step's names become an array
of numbers without a Python object per vehicle: the fast path's values are looked up by their bytes where they lie
in the step's text (:mod:`.fcd_names_kernel`), and the snapshot's string arrays are gathered from one array of the
names by number."""
from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from .numbering import Numbering

FIRST_SLOTS = 1 << 10  # of the hash table; doubled whenever it is half full


class NameTable:
    """Numbers for the names seen so far (``number``: name → number; ``known`` first, in their order)."""

    def __init__(self, known: Sequence[str] = ()):
        self._numbering = Numbering()
        self._names = np.zeros(0, dtype="<U1")  # [numbers] each number's name
        self._chars = np.zeros(0, dtype=np.int64)  # [numbers] its length in characters
        self._store = np.zeros(0, dtype=np.uint8)  # the names' UTF-8 bytes, one after the other
        self._starts = np.zeros(1, dtype=np.int64)  # [numbers + 1] where each name's bytes start in _store
        self._slots = np.full(FIRST_SLOTS, -1, dtype=np.int64)  # the hash table of the numbers (-1: empty)
        if known:
            self.of(known)

    def __len__(self) -> int:
        return len(self._numbering)

    @property
    def number(self) -> dict[str, int]:
        return self._numbering.number

    def of(self, names: Sequence[str]) -> np.ndarray:
        """[n] int64: the number of each of ``names`` (Python strings); names not seen before are numbered in their
        order here."""
        known = len(self)
        numbers = self._numbering.of(names)
        if len(self) > known:
            self._entered(known)
        return numbers

    def of_bytes(self, text: bytes, data: np.ndarray, bounds: np.ndarray) -> np.ndarray:
        """[n] int64: the number of each name ``text[bounds[j, 0]:bounds[j, 1]]`` (ASCII; ``data``: ``text`` as
        uint8), as :meth:`of` numbers them; a Python string is made only of a name not seen before."""
        from .fcd_names_kernel import find_numbers  # numba: compiled at the first step read by the fast path

        numbers = find_numbers(data, bounds, self._slots, self._store, self._starts)
        new = np.flatnonzero(numbers < 0)
        if new.size:
            numbers[new] = self.of([text[a:b].decode("ascii") for a, b in bounds[new].tolist()])
        return numbers

    def names(self, numbers: np.ndarray) -> np.ndarray:
        """The names of ``numbers`` as a str array, of the width ``np.array`` gives their strings (their longest, at
        least 1)."""
        width = max(int(self._chars[numbers].max(initial=1)), 1)
        names = self._names[numbers]
        return names if names.dtype.itemsize == 4 * width else names.astype(f"<U{width}")

    def added_since(self, count: int) -> list[str]:
        """The names numbered ``count`` and after, in their order."""
        return list(itertools.islice(self.number, count, None))

    def _entered(self, known: int) -> None:
        """Add the names numbered from ``known`` on to the arrays and the hash table."""
        from .fcd_names_kernel import add_numbers

        new = self.added_since(known)
        encoded = [name.encode("utf-8") for name in new]
        self._names = np.concatenate([self._names, np.array(new, dtype=str)])
        self._chars = np.concatenate([self._chars, np.fromiter(map(len, new), np.int64, len(new))])
        self._store = np.concatenate([self._store, np.frombuffer(b"".join(encoded), dtype=np.uint8)])
        self._starts = np.concatenate([self._starts, self._starts[-1] + np.cumsum(list(map(len, encoded)))])
        first = known
        if 2 * len(self) > len(self._slots):
            size = len(self._slots)
            while 2 * len(self) > size:
                size *= 2
            self._slots, first = np.full(size, -1, dtype=np.int64), 0
        add_numbers(self._slots, self._store, self._starts, first, len(self))
