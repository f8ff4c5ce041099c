"""A value for every pair of links through one junction, indexed like an [links, links] array.

Links of different junctions never conflict, so the table is block-diagonal: one block per junction, stored
flat. Memory is the sum of the squared link counts of the junctions (MoST's Monaco: 7,137 links, ~0.1 M
entries), where a dense array would hold every link pair of the network (51 M entries per table). The pairs whose
value is set (the conflicting ones) are also listed (:class:`LinkPairList`): per-pair quantities become arrays over
pair numbers, gathered per step with fancy indexing.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class LinkBlocks:
    """Where each link's row lies in the flat blocks: links are numbered junction by junction."""

    junction: np.ndarray  # [L] number of each link's junction
    local: np.ndarray  # [L] index of the link among its junction's
    base: np.ndarray  # [J] start of the junction's block in a flat table
    size: np.ndarray  # [J] number of the junction's links

    @classmethod
    def of(cls, junction_of_link: list[str]) -> LinkBlocks:
        """The blocks of links sorted by junction (``junction_of_link[k]``: the junction of link k)."""
        names, junction = np.unique(np.asarray(junction_of_link, dtype=str), return_inverse=True)
        junction = junction.ravel() if len(junction_of_link) else np.zeros(0, dtype=int)
        if np.any(np.diff(junction) < 0):
            raise ValueError("links must be numbered junction by junction")
        size = np.bincount(junction, minlength=len(names))
        first = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(int)
        base = np.concatenate([[0], np.cumsum(size * size)[:-1]]).astype(int)
        return cls(junction, np.arange(len(junction)) - first[junction], base, size)

    @property
    def cells(self) -> int:
        return int(np.sum(self.size * self.size))

    def flat(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(index into a flat table, whether the links are of one junction) of link pairs (a, b)."""
        ja, jb = self.junction[a], self.junction[b]
        same = ja == jb
        return np.where(same, self.base[ja] + self.local[a] * self.size[ja] + self.local[b], 0), same


@dataclass(frozen=True, eq=False)
class LinkPairs:
    """A value per pair of links of one junction, ``fill`` for links of different junctions. Indexed as the dense
    [L, L] array it stands for: ``t[a, b]`` (ints, index arrays, boolean masks or slices, broadcast as numpy
    does) and ``t[a]`` (a's row)."""

    blocks: LinkBlocks
    values: np.ndarray  # flat, blocks.cells long
    fill: Any

    @classmethod
    def full(cls, blocks: LinkBlocks, fill: Any, dtype: Any) -> LinkPairs:
        return cls(blocks, np.full(blocks.cells, fill, dtype=dtype), fill)

    @property
    def shape(self) -> tuple[int, int]:
        n = len(self.blocks.junction)
        return n, n

    def set(self, a: int, b: int, value: Any) -> None:
        """Set the value of the pair (a, b) (links of one junction)."""
        index, same = self.blocks.flat(np.array([a]), np.array([b]))
        if not same[0]:
            raise ValueError(f"links {a} and {b} are of different junctions")
        self.values[index[0]] = value

    def __getitem__(self, key: Any) -> np.ndarray:
        rows, cols = key if isinstance(key, tuple) else (key, slice(None))
        every = np.arange(len(self.blocks.junction))
        a, b = np.broadcast_arrays(every[rows], every[cols])
        index, same = self.blocks.flat(a, b)
        return np.where(same, self.values[index], self.fill)[()]  # a scalar for a scalar pair, as numpy gives

    def pairs(self) -> LinkPairList:
        """Every pair of links whose value is not ``fill``, as a list (see :class:`LinkPairList`)."""
        blocks = self.blocks
        flat = np.flatnonzero(self.values != self.fill)
        junction = np.searchsorted(blocks.base, flat, side="right") - 1
        size = blocks.size[junction]
        first = np.concatenate([[0], np.cumsum(blocks.size)[:-1]]).astype(int)[junction]  # its junction's first link
        local = flat - blocks.base[junction]
        a, b = first + local // size, first + local % size
        back = blocks.base[junction] + (local % size) * size + local // size  # flat index of (b, a)
        at = np.minimum(np.searchsorted(flat, back), max(len(flat) - 1, 0))
        reverse = np.where(flat[at] == back, at, -1) if len(flat) else np.zeros(0, dtype=int)
        indptr = np.searchsorted(a, np.arange(len(blocks.junction) + 1))
        return LinkPairList(indptr, a, b, flat, reverse)


@dataclass(frozen=True, eq=False)
class LinkPairList:
    """The link pairs (a, b) of a :class:`LinkPairs` table whose value is set, numbered in (a, b) order: pair k is
    (``link[k]``, ``other[k]``); link a's pairs are ``indptr[a]:indptr[a + 1]``. A per-pair quantity is then an array
    over k, gathered from any table of the same blocks at ``flat`` (``values[flat]``)."""

    indptr: np.ndarray  # [L + 1]
    link: np.ndarray  # [K] the first link of each pair
    other: np.ndarray  # [K] the second link
    flat: np.ndarray  # [K] index into the flat tables
    reverse: np.ndarray  # [K] the number of the pair (other, link), -1 if it is not set

    def __len__(self) -> int:
        return int(self.link.shape[0])

    def of(self, links: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(index into ``links``, pair number) of every pair starting at each of ``links``, in the order of
        ``links``, then of the pairs."""
        return expand_ranges(self.indptr[links], self.indptr[links + 1])


def expand_ranges(start: np.ndarray, stop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, value) of every value of the ranges ``start[i]:stop[i]`` laid end to end: ``owner`` is i."""
    count = np.maximum(stop - start, 0)
    owner = np.repeat(np.arange(len(count)), count)
    offset = np.cumsum(count) - count
    return owner, np.arange(int(count.sum())) - offset[owner] + start[owner]
