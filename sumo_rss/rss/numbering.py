"""Numbers for the names of road users and vTypes: 0, 1, ... in order of first appearance, so that per-step
look-ups work on integers instead of strings."""
from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np


class Numbering:
    """The number of every name seen so far (``number``: name → number, in order of first appearance)."""

    def __init__(self) -> None:
        self.number: dict[str, int] = {}

    def __len__(self) -> int:
        return len(self.number)

    def of(self, names: Sequence[str]) -> np.ndarray:
        """[n] int64: the number of each of ``names`` (Python strings: faster to hash than numpy's, one by one);
        names not seen before are numbered in their order here."""
        numbers = np.fromiter(map(self.number.get, names, itertools.repeat(-1)), dtype=np.int64, count=len(names))
        if (numbers < 0).any():
            for name in names:
                self.number.setdefault(name, len(self.number))
            numbers = np.fromiter(map(self.number.__getitem__, names), dtype=np.int64, count=len(names))
        return numbers
