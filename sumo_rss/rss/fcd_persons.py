"""The persons of an FCD time step (SUMO's ``<person id x y angle speed edge type .../>``) as a PersonSnapshot.

A person riding in a vehicle (SUMO writes its ``vehicle``) is no pedestrian and is left out: it moves with that
vehicle, which is audited.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from ..errors import shown
from ..sim.persons import SUMO_PERSON_SIZE, PersonSnapshot
from ..sim.snapshot import compass_deg_to_heading

PERSON_ATTRIBUTES = ("id", "x", "y", "angle", "speed", "edge")  # what SUMO writes of a person by default


def person_snapshot(rows: list[list[str]], sizes: dict[str, tuple[float, float]], where: str) -> PersonSnapshot:
    """The walking persons of ``rows`` (per person: attribute name, value, name, value, ...); ``sizes``: vType →
    (length, width) [m] (SUMO's pedestrian size for a type not in it). ValueError naming ``where``, the person and
    the attribute for one missing or not a finite number."""
    persons = [dict(zip(r[0::2], r[1::2])) for r in rows]
    persons = sorted((p for p in persons if not p.get("vehicle")), key=lambda p: p.get("id", ""))  # as a session
    if not persons:
        return PersonSnapshot.empty()
    for p in persons:
        for name in PERSON_ATTRIBUTES:
            if name not in p:
                raise ValueError(f"{where}: person {shown(p.get('id', '?'))} lacks the attribute {name!r} (needed: "
                                   f"{', '.join(PERSON_ATTRIBUTES)}; SUMO writes them by default)")

    def numbers(name: str) -> np.ndarray:
        try:
            values = np.array([p[name] for p in persons], dtype=float)
        except ValueError:
            values = np.full(len(persons), np.nan)
        if not np.isfinite(values).all():
            bad = next(p for p in persons if not _finite(p[name]))
            raise ValueError(f"{where}: person {shown(bad['id'])}: {name}: expected a finite number, got "
                               f"{shown(bad[name])}")
        return values

    types = [p.get("type") or "DEFAULT_PEDTYPE" for p in persons]
    size = np.array(list(map(sizes.get, types, itertools.repeat(SUMO_PERSON_SIZE))), dtype=float).reshape(-1, 2)
    return PersonSnapshot(np.array([p["id"] for p in persons], dtype=str), numbers("x"), numbers("y"),
                          compass_deg_to_heading(numbers("angle")), numbers("speed"),
                          np.array([p["edge"] for p in persons], dtype=str), np.array(types, dtype=str),
                          size[:, 0].copy(), size[:, 1].copy())


def _finite(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
