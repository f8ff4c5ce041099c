"""Typed reading of TOML tables with dotted-path error messages.

A :class:`TableReader` wraps one TOML table. Each accessor consumes a key, checks its type and range and
returns the value (or the default). :meth:`TableReader.finish` rejects every key that was not consumed, so a
misspelt key is an error, never a silent default.
"""
from __future__ import annotations

import difflib
import math
import re
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from .errors import ScenarioError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

_MISSING = object()


def read_toml(path: Path, what: str) -> dict[str, Any]:
    """The tables of a TOML file (UTF-8, with or without a byte-order mark, as Windows editors save it);
    ScenarioError naming the file if it is missing or not TOML."""
    if not path.is_file():
        raise ScenarioError(path, "", f"{what} file not found" + (" (a folder stands there; expected a file)"
                                                                   if path.is_dir() else ""), has_got=False)
    try:
        text = path.read_text(encoding="utf-8-sig")
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(path, "", f"not valid TOML ({exc})", has_got=False) from exc
    except UnicodeDecodeError as exc:
        raise ScenarioError(path, "", "not a UTF-8 text file", has_got=False) from exc
    except ValueError as exc:  # an integer of more than 4300 digits, which Python refuses to convert
        raise _long_integer_error(path, text) from exc


_LONG_INTEGER = re.compile(r"^\s*([^=#]*?)\s*=\s*[-+]?\d[\d_]{" + str(sys.get_int_max_str_digits()) + r",}")


def _long_integer_error(path: Path, text: str) -> ScenarioError:
    """The error for the integer of ``text`` longer than Python converts, naming its line and key."""
    for number, line in enumerate(text.splitlines(), start=1):
        found = _LONG_INTEGER.match(line)
        if found:
            digits = sum(c.isdigit() for c in line[found.end(1):])
            return ScenarioError(path, f"line {number}: {found.group(1).strip() or '<value>'}",
                                 f"expected a number of at most {sys.get_int_max_str_digits()} digits, got one of "
                                 f"{digits} digits", has_got=False)
    return ScenarioError(path, "", f"expected integers of at most {sys.get_int_max_str_digits()} digits",
                         has_got=False)


class TableReader:
    """Reads the keys of one table of ``file`` found at dotted ``path`` (``""`` for the top level)."""

    def __init__(self, data: Any, file: str | Path, path: str = ""):
        self.file = file
        self.path = path
        if not isinstance(data, dict):
            raise ScenarioError(file, path or "<top level>", "expected a table", data)
        self._data = data
        self._seen: set[str] = set()  # keys read
        self._known: set[str] = set()  # keys asked about (read, or tested with has)

    # -- helpers -------------------------------------------------------------------------------------------
    def key_path(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def error(self, key: str, expected: str, got: object = _MISSING) -> ScenarioError:
        if got is _MISSING:
            return ScenarioError(self.file, self.key_path(key), expected, has_got=False)
        return ScenarioError(self.file, self.key_path(key), expected, got)

    def has(self, key: str) -> bool:
        self._known.add(key)
        return key in self._data

    def misspelt(self, keys: Iterable[str]) -> str:
        """' (did you mean X for Y?)' for a key of the table that is close to one of ``keys``, else ''."""
        for given in self._data:
            close = _closest(given, [k for k in keys if k != given])
            if close and given not in self._known:
                return f" (did you mean {close!r} for {given!r}?)"
        return ""

    def _take(self, key: str, default: Any) -> Any:
        self._seen.add(key)
        self._known.add(key)
        if key in self._data:
            return self._data[key]
        if default is _MISSING:
            raise self.error(key, f"required key is missing{self.misspelt([key])}")
        return default

    # -- scalar accessors ----------------------------------------------------------------------------------
    def number(self, key: str, default: Any = _MISSING, *, min: float | None = None, max: float | None = None,
               min_exclusive: bool = False, optional: bool = False) -> float | None:
        """A finite int or float within [min, max] (min excluded when ``min_exclusive``)."""
        value = self._take(key, None if optional and default is _MISSING else default)
        if value is None and optional:
            return None
        form = _range_text("a number", min, max, min_exclusive)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(key, f"expected {form}", value)
        if (min is not None and (value < min or (min_exclusive and value == min))) or \
                (max is not None and value > max):
            raise self.error(key, f"expected {form}", value)
        return float(value)

    def integer(self, key: str, default: Any = _MISSING, *, min: int | None = None,
                max: int | None = None) -> int:
        value = self._take(key, default)
        form = _range_text("an integer", min, max, False)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected {form}", value)
        if (min is not None and value < min) or (max is not None and value > max):
            raise self.error(key, f"expected {form}", value)
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self._take(key, default)
        if not isinstance(value, bool):
            raise self.error(key, "expected true or false", value)
        return value

    def string(self, key: str, default: Any = _MISSING, *, choices: Iterable[str] | None = None) -> str:
        value = self._take(key, default)
        allowed = tuple(choices) if choices is not None else None
        if not isinstance(value, str) or not value:
            expected = f"one of {', '.join(repr(c) for c in allowed)}" if allowed else "a non-empty string"
            raise self.error(key, f"expected {expected}", value)
        if allowed is not None and value not in allowed:
            raise self.error(key, f"expected one of {', '.join(repr(c) for c in allowed)}", value)
        return value

    def string_list(self, key: str, default: Any = _MISSING, *, min_len: int = 1) -> tuple[str, ...]:
        value = self._take(key, default)
        if not isinstance(value, list) or len(value) < min_len or \
                not all(isinstance(v, str) and v for v in value):
            raise self.error(key, f"expected a list of {_at_least(min_len)}non-empty strings", value)
        return tuple(value)

    def number_table(self, key: str) -> dict[str, float]:
        """A table of name = number pairs (free-form model parameters), empty if absent."""
        value = self._take(key, {})
        if not isinstance(value, dict):
            raise self.error(key, "expected a table of name = number", value)
        for name, item in value.items():
            if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(item):
                raise ScenarioError(self.file, f"{self.key_path(key)}.{name}", "expected a number", item)
        return {name: float(item) for name, item in value.items()}

    # -- nested tables -------------------------------------------------------------------------------------
    def table(self, key: str, *, required: bool = False) -> TableReader:
        value = self._take(key, _MISSING if required else {})
        return TableReader(value, self.file, self.key_path(key))

    def table_list(self, key: str, *, min_len: int = 0) -> list[TableReader]:
        value = self._take(key, [])
        if not isinstance(value, list) or len(value) < min_len:
            raise self.error(key, f"expected an array of {_at_least(min_len)}tables ([[{self.key_path(key)}]])",
                             value)
        return [TableReader(item, self.file, f"{self.key_path(key)}[{i}]") for i, item in enumerate(value)]

    def named_tables(self, key: str) -> dict[str, TableReader]:
        """A table whose keys are user-chosen names, each holding a table (e.g. ``[demand.vtypes.car]``)."""
        outer = self.table(key)
        return {name: TableReader(outer._take(name, _MISSING), self.file, outer.key_path(name))
                for name in list(outer._data)}

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        return self._take(key, default)

    def finish(self) -> None:
        """Reject keys that no accessor consumed."""
        unknown = [k for k in self._data if k not in self._seen]
        if unknown:
            known = sorted(self._known - set(self._data) | self._seen)
            close = _closest(unknown[0], known)
            hint = f" (did you mean {close!r}?)" if close else ""
            hint += f"; known keys here: {', '.join(known)}" if known else ""
            raise self.error(unknown[0], f"unknown key{hint}")


def _at_least(count: int) -> str:
    return f"at least {count} " if count else ""


def _range_text(noun: str, lo: float | None, hi: float | None, lo_exclusive: bool) -> str:
    if lo is not None and hi is not None:
        return f"{noun} in {'(' if lo_exclusive else '['}{lo:.15g}, {hi:.15g}]"
    if lo is not None:
        return f"{noun} {'>' if lo_exclusive else '>='} {lo:.15g}"
    if hi is not None:
        return f"{noun} <= {hi:.15g}"
    return noun


def _closest(word: str, candidates: Sequence[str]) -> str | None:
    """The candidate ``word`` was most likely a misspelling of (None if none is close)."""
    close = difflib.get_close_matches(word, candidates, n=1, cutoff=0.75)
    return close[0] if close else None


def one_of(reader: TableReader, keys: Sequence[str]) -> str:
    """The single key of ``keys`` present in the table; an error if none or several are."""
    present = [k for k in keys if reader.has(k)]
    if len(present) != 1:
        hint = reader.misspelt(keys) if not present else ""
        raise reader.error(" | ".join(keys), f"expected exactly one of {', '.join(keys)}{hint}",
                           present or None)
    return present[0]
