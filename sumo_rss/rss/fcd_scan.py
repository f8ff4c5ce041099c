"""A fast path for the time steps SUMO writes: ``<timestep time="...">`` and one ``<vehicle .../>`` per line, every
vehicle's attributes in the order of the step before, read by one compiled pass over the step's bytes
(:mod:`.fcd_scan_kernel`) instead of expat's callbacks.

A step is taken only if its text is exactly that layout (ASCII, values without references, control characters or
``<``, single spaces, self-closed vehicles), so that every value is the string expat would give; anything else
(persons, containers, comments, another attribute order, damage) is left to expat (:mod:`.fcd_parse`). The pass
only finds where the values are: a column becomes strings when asked for, and a column of plain decimals becomes
floats without strings (:meth:`ScannedStep.numbers`).
"""
from __future__ import annotations

import numpy as np

from .fcd_names import NameTable

STEP_END = b"</timestep>"


class StepLayout:
    """The literal pieces of a time step whose vehicles have the attributes ``names``, in this order."""

    def __init__(self, names: tuple[str, ...]):
        self.names = names
        self._ascii = all(name.isascii() for name in names)  # else no step is read so: the path reads ASCII only
        pieces = [b'<timestep time="', b'">', *(
            (b'<vehicle ' if k == 0 else b'" ') + name.encode("utf-8") + b'="' for k, name in enumerate(names)),
            b'"/>', STEP_END]
        self._literals = np.frombuffer(b"".join(pieces), dtype=np.uint8)
        self._starts = np.cumsum([0] + [len(p) for p in pieces])

    def scan(self, text: bytes) -> ScannedStep | None:
        """The step ``text`` (white space, then one ``<timestep>`` element), or None where it is not exactly this
        layout."""
        from .fcd_scan_kernel import scan_step  # numba: compiled at the first step read so

        if not self._ascii:
            return None
        data = np.frombuffer(text, dtype=np.uint8)
        count, time_start, time_end, offsets = scan_step(data, self._literals, self._starts)
        if count < 0:
            return None
        return ScannedStep(text[time_start:time_end].decode("ascii"), int(count), self.names, text, data, offsets)


class ScannedStep:
    """A time step read by :meth:`StepLayout.scan`: its ``time`` and ``count`` vehicles, each with the attributes
    ``names``, their values where ``offsets`` ([vehicles, attributes, 2]: start, end) says in ``text``."""

    def __init__(self, time: str, count: int, names: tuple[str, ...], text: bytes, data: np.ndarray,
                 offsets: np.ndarray):
        self.time, self.count, self.names = time, count, names
        self._text, self._data, self._offsets = text, data, offsets
        self._decoded: str | None = None

    def column(self, name: str) -> tuple[str, ...]:
        """Attribute ``name`` (one of ``names``) of every vehicle, as written."""
        if self._decoded is None:
            self._decoded = self._text.decode("ascii")
        bounds = self._offsets[:, self.names.index(name)]
        text = self._decoded
        return tuple([text[a:b] for a, b in zip(bounds[:, 0].tolist(), bounds[:, 1].tolist())])

    def numbered(self, name: str, table: NameTable) -> np.ndarray:
        """Attribute ``name`` (one of ``names``) of every vehicle as its number in ``table``
        (:meth:`NameTable.of_bytes`: no string per vehicle)."""
        return table.of_bytes(self._text, self._data, np.ascontiguousarray(self._offsets[:, self.names.index(name)]))

    def numbers(self, name: str) -> np.ndarray | None:
        """Attribute ``name`` of every vehicle as floats where every value is a plain decimal (what ``float`` gives
        for it, to the bit), else None."""
        from .fcd_scan_kernel import exact_decimals

        values, exact = exact_decimals(self._data, np.ascontiguousarray(self._offsets[:, self.names.index(name)]))
        return values if exact else None
