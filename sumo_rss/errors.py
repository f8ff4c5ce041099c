"""Errors that the CLI reports as one line and exit code 2 (bad input, not a bug)."""
from __future__ import annotations

from pathlib import Path


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
            text += f", got {got!r}"
        super().__init__(text)


class SessionError(SumoRssError):
    """A simulation session cannot be started or used as asked."""
