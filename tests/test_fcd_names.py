"""The FCD reader's name table (rss/fcd_names.py): names looked up by their bytes in a step's text get the numbers
Numbering gives their strings, in order of first appearance, also past the hash table's growth and among names that
share a prefix; the string arrays it gives are those numpy makes of the strings (the same width)."""
from __future__ import annotations

import random

import numpy as np

from sumo_rss.rss.fcd_names import FIRST_SLOTS, NameTable
from sumo_rss.rss.numbering import Numbering


def _as_text(names: list[str]) -> tuple[bytes, np.ndarray, np.ndarray]:
    """``names`` quoted one after the other, as a step's text, and where each lies in it ([n, 2] start, end)."""
    text, bounds = b"", []
    for name in names:
        text += b' id="'
        bounds.append((len(text), len(text) + len(name)))
        text += name.encode("ascii") + b'"'
    return text, np.frombuffer(text, dtype=np.uint8), np.array(bounds, dtype=np.int64).reshape(-1, 2)


def test_names_by_their_bytes_are_numbered_as_their_strings_in_order_of_first_appearance():
    rng = random.Random(7)
    pool = [f"flow_{k}.{j}" for k in range(60) for j in range(70)] + ["", "a", "a_", "flow_1"]  # > FIRST_SLOTS / 2
    table, numbering = NameTable(["known_0", "known_1"]), Numbering()
    numbering.of(["known_0", "known_1"])
    for step in range(40):
        names = rng.sample(pool, 300) + rng.sample(pool, 3)  # repeats within a step too
        if step % 2:
            numbers = table.of(names)
        else:
            numbers = table.of_bytes(*_as_text(names))
        assert numbers.tolist() == numbering.of(names).tolist()
        names_array = table.names(numbers)
        assert names_array.dtype == np.array(names, dtype=str).dtype and names_array.tolist() == names
    assert len(table) > FIRST_SLOTS  # the hash table grew (twice)
    assert table.of_bytes(*_as_text(["known_1", "nowhere"])).tolist() == [1, len(numbering)]


def test_a_step_without_names_gives_the_width_numpy_gives():
    table = NameTable(["lane_0"])
    empty = table.of_bytes(*_as_text([]))
    assert empty.tolist() == [] and table.names(empty).dtype == np.array((), dtype=str).dtype
    assert table.names(table.of([""])).dtype == np.array(("",), dtype=str).dtype
    assert table.names(table.of(["é_non_ascii"])).tolist() == ["é_non_ascii"]  # read by expat, not by bytes
