"""A fast path for the time steps SUMO writes: ``<timestep time="...">`` and one ``<vehicle .../>`` per line, every
vehicle's attributes in the order of the step before, read by two regular expressions instead of expat's callbacks.

A step is taken only if its text is exactly that layout (ASCII, values without references, control characters or
``<``, single spaces, self-closed vehicles), so that every value is the string expat would give; anything else
(persons, containers, comments, another attribute order, damage) is left to expat (:mod:`.fcd_parse`).
"""
from __future__ import annotations

import re

SPACE = "[ \t\r\n]*"  # XML's white space between elements
# An attribute value expat gives as written: no reference (&...;), no white space it would normalise, no '<'.
VALUE = '[^"&<\x00-\x1f]*'
STEP_END = b"</timestep>"


class StepLayout:
    """The regular expressions of a time step whose vehicles have the attributes ``names``, in this order."""

    def __init__(self, names: tuple[str, ...]):
        self.names = names
        captured = " ".join(f'{re.escape(name)}="({VALUE})"' for name in names)
        matched = " ".join(f'{re.escape(name)}="{VALUE}"' for name in names)
        self._vehicle = re.compile(f"<vehicle {captured}/>")
        self._step = re.compile(f'{SPACE}<timestep time="({VALUE})">(?:{SPACE}<vehicle {matched}/>)*{SPACE}</timestep>')

    def columns(self, text: str) -> tuple[str, dict[str, tuple[str, ...]], int] | None:
        """(the step's time, its vehicles' attribute columns by name, the number of vehicles) of ``text`` (white
        space, then one ``<timestep>`` element), or None where it is not exactly this layout."""
        whole = self._step.fullmatch(text)
        if whole is None:
            return None
        rows = self._vehicle.findall(text)
        if len(self.names) == 1:  # findall gives the one group's strings themselves
            return whole.group(1), ({self.names[0]: tuple(rows)} if rows else {}), len(rows)
        return whole.group(1), dict(zip(self.names, zip(*rows))), len(rows)
