"""Errors that the CLI reports as one line and exit code 2 (bad input, not a bug)."""
from __future__ import annotations

from pathlib import Path

SHOWN_CHARACTERS = 60  # a value echoed in a message is cut to about this many characters


def cut(text: str) -> str:
    """``text`` for a message, cut where it is long (a 5000-digit attribute is not echoed in full): its first
    characters, then how long it was."""
    if len(text) <= SHOWN_CHARACTERS:
        return text
    return f"{text[:SHOWN_CHARACTERS - 20]}... ({len(text)} characters)"


def shown(value: object) -> str:
    """``repr(value)``, :func:`cut`."""
    return cut(repr(value))


def listed(items: list[str], most: int = 3) -> str:
    """The first ``most`` of ``items`` (each :func:`cut`), comma-separated, and how many more there are."""
    more = f" and {len(items) - most} more" if len(items) > most else ""
    return ", ".join(cut(str(item)) for item in items[:most]) + more


class SumoRssError(Exception):
    """Base of the errors caused by user input; the CLI prints them without a traceback."""


class ScenarioError(SumoRssError):
    """A scenario (or batch) file is invalid.

    The message names the file, the dotted key path inside it and the expected form, e.g.
    ``scenarios/x.toml: demand.flows[0].veh_per_hour: expected a number >= 0, got -5``.
    """

    def __init__(self, file: str | Path, key: str, expected: str, got: object = None, *, has_got: bool = True):
        self.file = str(file)
        self.key = key
        self.expected = expected
        self.got = got
        where = f"{self.file}: {key}" if key else self.file
        text = f"{where}: {expected}"
        if has_got:
            text += f", got {shown(got)}"
        super().__init__(text)


class SessionError(SumoRssError):
    """A simulation session cannot be started or used as asked."""


class OutputError(SumoRssError):
    """A result file or folder cannot be written (not a folder, not writable, disk full, file too large): the
    message names it and what is expected."""
