"""Streaming parse of SUMO FCD files: each ``<timestep>``'s vehicles as columns of attribute strings.

expat is fed the file block by block and keeps, per vehicle, only its attribute list; a finished step turns the
lists into columns in one transposition (SUMO writes every vehicle's attributes in one order; steps where they
differ are read vehicle by vehicle). What the strings mean is :mod:`.fcd`'s business (snapshots, derived values
and their checks), so that both can change independently.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import IO
from xml.parsers import expat

from ..sumo_xml import MALFORMED

BLOCK_BYTES = 1 << 16  # read and parsed at once (progress moves in these steps)
ROOT_TAG = "fcd-export"
UNAUDITED_TAGS = ("container",)  # road users an FCD lists beside vehicles and persons that are not audited


@dataclass
class FcdStep:
    """One ``<timestep>``: its ``time`` as written (None if absent) and its vehicles' attributes (strings)."""

    time: str | None
    vehicles: list[list[str]] = field(default_factory=list)  # per vehicle: name, value, name, value, ...
    unaudited: list[str] = field(default_factory=list)  # the ids of the containers listed in it
    persons: list[list[str]] = field(default_factory=list)  # per person: name, value, name, value, ...
    _columns: dict[str, tuple[str, ...]] | None = field(default=None, repr=False)
    _rows: list[dict[str, str]] | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.vehicles)

    def rows(self) -> list[dict[str, str]]:
        """Every vehicle's attributes by name (for checks and messages that go vehicle by vehicle)."""
        if self._rows is None:
            self._rows = [dict(zip(v[0::2], v[1::2])) for v in self.vehicles]
        return self._rows

    def column(self, name: str) -> tuple[str | None, ...]:
        """Attribute ``name`` of every vehicle (None where a vehicle lacks it)."""
        columns = self._by_name()
        if columns is not None:
            return columns.get(name, (None,) * len(self.vehicles))
        return tuple(r.get(name) for r in self.rows())

    def has(self, name: str) -> bool:
        """Whether every vehicle has attribute ``name`` (False for a step without vehicles)."""
        columns = self._by_name()
        if columns is not None:
            return name in columns and bool(self.vehicles)
        return bool(self.vehicles) and all(name in r for r in self.rows())

    def _by_name(self) -> dict[str, tuple[str, ...]] | None:
        """The columns by attribute name where every vehicle has the same attributes in the same order, else None."""
        if self._columns is None:
            vehicles = self.vehicles
            if len(set(map(len, vehicles))) > 1:
                return None
            transposed = list(zip(*vehicles))  # one name column and one value column per attribute
            names = transposed[0::2]
            if any(column.count(column[0]) != len(column) for column in names):
                return None
            self._columns = {column[0]: values for column, values in zip(names, transposed[1::2])}
        return self._columns


class _Handler:
    """expat callbacks collecting finished steps."""

    def __init__(self) -> None:
        self.root: str | None = None
        self.done: list[FcdStep] = []
        self.started_time: str | None = None  # of the last step begun
        self._step: FcdStep | None = None
        self._depth = 0  # of the element being read (1: the root)
        self._step_depth = 0

    def start(self, name: str, attrs: list[str]) -> None:
        self._depth += 1
        step = self._step
        if name == "vehicle" and step is not None:
            step.vehicles.append(attrs)
        elif self._depth == 1:
            self.root = name
        elif name == "timestep":
            self.started_time = _attribute(attrs, "time")
            self._step = FcdStep(self.started_time)
            self._step_depth = self._depth
        elif step is not None and name == "person" and self._depth == self._step_depth + 1:
            step.persons.append(attrs)
        elif step is not None and name in UNAUDITED_TAGS and self._depth == self._step_depth + 1:
            step.unaudited.append(_attribute(attrs, "id") or "")

    def end(self, name: str) -> None:
        if name == "timestep" and self._depth == self._step_depth and self._step is not None:
            self.done.append(self._step)
            self._step = None
        self._depth -= 1


def _attribute(attrs: list[str], name: str) -> str | None:
    for k in range(0, len(attrs), 2):
        if attrs[k] == name:
            return attrs[k + 1]
    return None


class FcdParser:
    """The steps of an FCD read from ``source`` (a binary file), as they finish. ``started_time``: the ``time`` of
    the last step begun (for messages). A damaged file raises ``xml.etree.ElementTree.ParseError`` (with expat's
    ``code`` and ``position``, as ElementTree's parsers do)."""

    def __init__(self, source: IO[bytes]):
        self.source = source
        self._handler = _Handler()
        self._parser = expat.ParserCreate()
        self._parser.ordered_attributes = True
        self._parser.StartElementHandler = self._handler.start
        self._parser.EndElementHandler = self._handler.end

    @property
    def started_time(self) -> str | None:
        return self._handler.started_time

    def read_root(self) -> str:
        """Read up to the root element; its tag (ParseError for a file without one)."""
        while self._handler.root is None and self._feed():
            pass
        return self._handler.root  # type: ignore[return-value]  (the end of a file without a root raised)

    def __iter__(self) -> Iterator[FcdStep]:
        """The steps, each once finished; a damaged file's error (one of MALFORMED) comes after every step that
        finished before the damage."""
        finished = False
        while True:
            error = None
            try:
                finished = not self._feed()
            except MALFORMED as exc:
                error = exc
            done, self._handler.done = self._handler.done, []
            yield from done
            if error is not None:
                raise error
            if finished:
                return

    def _feed(self) -> bool:
        """Parse the next block (the end of the document once the file is read); False after the end."""
        data = self.source.read(BLOCK_BYTES)
        try:
            self._parser.Parse(data, not data)
        except expat.ExpatError as exc:
            raise _parse_error(exc) from None
        return bool(data)


def _parse_error(exc: expat.ExpatError) -> ET.ParseError:
    """ElementTree's error for expat's (its message, ``code`` and ``position``)."""
    error = ET.ParseError(f"{expat.ErrorString(exc.code)}: line {exc.lineno}, column {exc.offset}")
    error.code, error.position = exc.code, (exc.lineno, exc.offset)
    return error
