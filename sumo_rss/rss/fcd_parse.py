"""Streaming parse of SUMO FCD files: each ``<timestep>``'s vehicles as columns of attribute strings.

The file is read block by block. A time step in SUMO's own layout (every vehicle on its line, its attributes in the
order of the step before) is read by :mod:`.fcd_scan`'s compiled pass, which finds where its values are (columns of
strings made when asked for, plain decimals read as floats without strings); everything else
goes to expat, which keeps, per vehicle, only its attribute list, and a finished step turns the lists into columns in
one transposition (steps whose vehicles' attributes differ are read vehicle by vehicle). expat sees every byte of the
file but the steps taken by the fast path, whose line breaks it is given instead: it checks the document as a
whole, and its errors name the lines of the file. What the strings mean is :mod:`.fcd`'s business (snapshots,
derived values and their checks), so that both can change independently.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import IO
from xml.parsers import expat

import numpy as np

from ..sumo_xml import MALFORMED
from .fcd_names import NameTable
from .fcd_scan import STEP_END, ScannedStep, StepLayout

BLOCK_BYTES = 1 << 16  # read and parsed at once (progress moves in these steps)
MAX_PENDING = 1 << 26  # [bytes] held back for the fast path at most, waiting for a step's end
FAST_ENCODINGS = ("utf-8", "utf8", "us-ascii", "ascii")  # declared encodings in which ASCII text reads as itself
ROOT_TAG = "fcd-export"
UNAUDITED_TAGS = ("container",)  # road users an FCD lists beside vehicles and persons that are not audited
ROAD_USER_TAGS = ("vehicle", "person", *UNAUDITED_TAGS)  # each belongs inside a <timestep>


class OutsideStepError(ValueError):
    """A road user's element (``tag``) outside every ``<timestep>``, at ``line`` of the file."""

    def __init__(self, tag: str, line: int):
        super().__init__(f"line {line}: <{tag}> outside a <timestep>")
        self.tag, self.line = tag, line


@dataclass
class FcdStep:
    """One ``<timestep>``: its ``time`` as written (None if absent) and its vehicles' attributes (strings)."""

    time: str | None
    vehicles: list[list[str]] = field(default_factory=list)  # per vehicle: name, value, name, value, ...
    unaudited: list[str] = field(default_factory=list)  # the ids of the containers listed in it
    persons: list[list[str]] = field(default_factory=list)  # per person: name, value, name, value, ...
    _scanned: ScannedStep | None = field(default=None, repr=False)  # a step read by the fast path
    _columns: dict[str, tuple[str, ...]] | None = field(default=None, repr=False)
    _rows: list[dict[str, str]] | None = field(default=None, repr=False)

    @classmethod
    def of_scan(cls, scanned: ScannedStep) -> FcdStep:
        """A step read by the fast path (every vehicle with the attributes ``scanned.names``)."""
        return cls(scanned.time, _scanned=scanned, _columns={})

    def __len__(self) -> int:
        return len(self.vehicles) if self._scanned is None else self._scanned.count

    def rows(self) -> list[dict[str, str]]:
        """Every vehicle's attributes by name (for checks and messages that go vehicle by vehicle)."""
        if self._rows is None:
            if self._scanned is not None:
                names = self._scanned.names if len(self) else ()
                columns = [self.column(name) for name in names]
                self._rows = [dict(zip(names, values)) for values in zip(*columns)] if names else \
                    [{} for _ in range(len(self))]
            else:
                self._rows = [dict(zip(v[0::2], v[1::2])) for v in self.vehicles]
        return self._rows

    def column(self, name: str) -> tuple[str | None, ...]:
        """Attribute ``name`` of every vehicle (None where a vehicle lacks it)."""
        scanned = self._scanned
        if scanned is not None:
            if not self.has(name):
                return (None,) * len(self)
            if name not in self._columns:
                self._columns[name] = scanned.column(name)
            return self._columns[name]
        columns = self._by_name()
        if columns is not None:
            return columns.get(name, (None,) * len(self))
        return tuple(r.get(name) for r in self.rows())

    def numbered(self, name: str, table: NameTable) -> np.ndarray:
        """Attribute ``name`` of every vehicle as its number in ``table`` (:meth:`NameTable.of`); every vehicle must
        have it (a step without vehicles: none)."""
        if self._scanned is not None and self.has(name):
            return self._scanned.numbered(name, table)
        return table.of(self.column(name))

    def numbers(self, name: str) -> np.ndarray | None:
        """Attribute ``name`` of every vehicle as floats, to the bit what ``float`` gives for each, where the fast
        path read the step and every value is a plain decimal (:meth:`ScannedStep.numbers`); else None."""
        return self._scanned.numbers(name) if self._scanned is not None and self.has(name) else None

    def has(self, name: str) -> bool:
        """Whether every vehicle has attribute ``name`` (False for a step without vehicles)."""
        if self._scanned is not None:
            return len(self) > 0 and name in self._scanned.names
        columns = self._by_name()
        if columns is not None:
            return name in columns and len(self) > 0
        return len(self) > 0 and all(name in r for r in self.rows())

    def _by_name(self) -> dict[str, tuple[str, ...]] | None:
        """The columns by attribute name where every vehicle has the same attributes in the same order, else None
        (a step expat read)."""
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

    def __init__(self, position: Callable[[], int], line: Callable[[], int]) -> None:
        self.root: str | None = None
        self.done: list[FcdStep] = []
        self.started_time: str | None = None  # of the last step begun
        self.closed_at = -1  # where the end tag of the last step closed at the root's level begins [bytes given]
        self._position = position  # of the event being handled [bytes given to expat]
        self._line = line  # of the event being handled (the file's: expat is given the fast path's line breaks)
        self._step: FcdStep | None = None
        self._depth = 0  # of the element being read (1: the root)
        self._step_depth = 0

    @property
    def at_root(self) -> bool:
        """Whether no element but the root is open."""
        return self._depth == 1

    def start(self, name: str, attrs: list[str]) -> None:
        self._depth += 1
        step = self._step
        if name == "vehicle" and step is not None:
            step.vehicles.append(attrs)
        elif self._depth == 1:
            self.root = name
        elif step is None and name in ROAD_USER_TAGS and self.root == ROOT_TAG:  # (other files: the reader says so)
            raise OutsideStepError(name, self._line())
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
            if self._depth == 2:
                self.closed_at = self._position()
        self._depth -= 1


def _attribute(attrs: list[str], name: str) -> str | None:
    for k in range(0, len(attrs), 2):
        if attrs[k] == name:
            return attrs[k + 1]
    return None


class FcdParser:
    """The steps of an FCD read from ``source`` (a binary file), as they finish. ``started_time``: the ``time`` of
    the last step begun (for messages). A damaged file raises ``xml.etree.ElementTree.ParseError`` (with expat's
    ``code`` and ``position``, as ElementTree's parsers do); a vehicle, person or container outside every time step
    :class:`OutsideStepError`."""

    def __init__(self, source: IO[bytes]):
        self.source = source
        self._parser = expat.ParserCreate()
        self._handler = _Handler(lambda: self._parser.CurrentByteIndex, lambda: self._parser.CurrentLineNumber)
        self._parser.ordered_attributes = True
        self._parser.StartElementHandler = self._handler.start
        self._parser.EndElementHandler = self._handler.end
        self._parser.XmlDeclHandler = self._declared
        self._parser.StartDoctypeDeclHandler = self._doctype
        self._pending = b""  # read from the file, not parsed yet
        self._given = 0  # bytes given to expat
        self._fast = True  # False for a document the fast path cannot read (a DTD, another encoding)
        self._clean = False  # expat has just closed a step at the root's level: the fast path may read the next
        self._layouts: dict[tuple[str, ...], StepLayout] = {}
        self._layout: StepLayout | None = None  # of the last step expat read

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
        """Read and parse the next block (the end of the document once the file is read); False after the end."""
        data = self.source.read(BLOCK_BYTES)
        if not data:
            pending, self._pending = self._pending, b""
            self._expat(pending, final=True)
            return False
        self._pending += data
        self._split()
        return True

    def _split(self) -> None:
        """Parse the pending bytes up to the end of their last complete step: each step in SUMO's layout by the
        fast path (expat given its line breaks), the rest by expat."""
        pending, start = self._pending, 0
        while True:
            if not self._clean:  # expat reads up to the last step's end, then may have closed a step there
                end = pending.rfind(STEP_END, start)
                if end < 0:
                    if self._handler.root is None or len(pending) - start > MAX_PENDING:
                        self._expat(pending[start:])
                        start = len(pending)
                    break
                start = self._expat_step(pending[start:end + len(STEP_END)], start)
                continue
            end = pending.find(STEP_END, start)
            if end < 0:
                if len(pending) - start > MAX_PENDING:  # no step's end in sight: not SUMO's layout
                    self._expat(pending[start:])
                    start, self._clean = len(pending), False
                break
            text = pending[start:end + len(STEP_END)]
            step = self._read_fast(text)
            if step is None:
                start = self._expat_step(text, start)
            else:
                self._expat(b"\n" * text.count(b"\n"))
                self._handler.started_time = step.time
                self._handler.done.append(step)
                start += len(text)
        self._pending = pending[start:]

    def _expat_step(self, text: bytes, start: int) -> int:
        """Give expat ``text`` (at ``start`` of the pending bytes), which ends with a step's end tag; whether the
        fast path may read the next step follows: expat closed a step at the root's level with that tag. The
        pending bytes' position after ``text``."""
        self._expat(text)
        self._clean = self._fast and self._handler.closed_at == self._given - len(STEP_END) and \
            self._handler.at_root
        if self._clean and self._handler.done:
            step = self._handler.done[-1]
            if step.vehicles and step._by_name() is not None:  # every vehicle's attributes in one order
                names = tuple(step.vehicles[0][0::2])
                self._layout = self._layouts.get(names) or self._layouts.setdefault(names, StepLayout(names))
        return start + len(text)

    def _read_fast(self, text: bytes) -> FcdStep | None:
        """The step ``text`` (white space, then one ``<timestep>`` element) by the fast path; None where it is not
        in the layout of the step before."""
        if self._layout is None:
            return None
        scanned = self._layout.scan(text)
        return None if scanned is None else FcdStep.of_scan(scanned)

    def _expat(self, data: bytes, final: bool = False) -> None:
        self._given += len(data)
        try:
            self._parser.Parse(data, final)
        except expat.ExpatError as exc:
            raise _parse_error(exc) from None

    def _declared(self, version: str, encoding: str | None, standalone: int) -> None:
        if encoding is not None and encoding.lower() not in FAST_ENCODINGS:
            self._fast = False

    def _doctype(self, *declaration: object) -> None:
        self._fast = False  # a DTD can give attributes defaults and entities: expat reads the whole file


def _parse_error(exc: expat.ExpatError) -> ET.ParseError:
    """ElementTree's error for expat's (its message, ``code`` and ``position``)."""
    error = ET.ParseError(f"{expat.ErrorString(exc.code)}: line {exc.lineno}, column {exc.offset}")
    error.code, error.position = exc.code, (exc.lineno, exc.offset)
    return error
