"""The persons of an FCD time step (SUMO's ``<person id x y angle speed edge type .../>``) as a PersonSnapshot.

A person riding in a vehicle (SUMO writes its ``vehicle``) is no pedestrian and is left out: it moves with that
vehicle, which is audited.
"""
from __future__ import annotations

import itertools
import math
from collections import Counter

import numpy as np

from ..errors import shown
from ..sim.persons import SUMO_PERSON_SIZE, PersonSnapshot
from ..road.net_check import MAX_COORDINATE_M
from ..road.network import RoadNetwork
from ..sim.snapshot import compass_deg_to_heading
from .fcd_checks import MAX_ANGLE_DEG, MAX_SPEED, fcd_error

PERSON_ATTRIBUTES = ("id", "x", "y", "angle", "speed", "edge")  # what SUMO writes of a person by default
# The bounds of a person's numbers (lowest, highest, unit): those of a vehicle's (fcd_checks).
_BOUNDS = {"x": (-MAX_COORDINATE_M, MAX_COORDINATE_M, "m"), "y": (-MAX_COORDINATE_M, MAX_COORDINATE_M, "m"),
           "angle": (-MAX_ANGLE_DEG, MAX_ANGLE_DEG, "degrees"), "speed": (0.0, MAX_SPEED, "m/s")}


def person_snapshot(rows: list[list[str]], sizes: dict[str, tuple[float, float]], where: str) -> PersonSnapshot:
    """The walking persons of ``rows`` (per person: attribute name, value, name, value, ...); ``sizes``: vType →
    (length, width) [m] (SUMO's pedestrian size for a type not in it). ValueError naming ``where``, the person and
    the attribute for one missing, not a finite number or beyond a vehicle's bounds (a speed outside [0, 200] m/s, a
    coordinate beyond 10⁸ m, an angle beyond ±720°), or a person listed twice."""
    persons = [dict(zip(r[0::2], r[1::2])) for r in rows]
    persons = sorted((p for p in persons if not p.get("vehicle")), key=lambda p: p.get("id", ""))  # as a session
    if not persons:
        return PersonSnapshot.empty()
    for p in persons:
        for name in PERSON_ATTRIBUTES:
            if name not in p:
                raise ValueError(f"{where}: person {shown(p.get('id', '?'))} lacks the attribute {name!r} (needed: "
                                   f"{', '.join(PERSON_ATTRIBUTES)}; SUMO writes them by default)")

    if any(not p["id"] for p in persons):
        raise ValueError(f"{where}: person: id: expected SUMO's person id, got ''")
    twice = next((i for i, count in Counter(p["id"] for p in persons).items() if count > 1), None)
    if twice is not None:
        raise ValueError(f"{where}: person {shown(twice)} is listed more than once")

    def numbers(name: str) -> np.ndarray:
        try:
            values = np.array([p[name] for p in persons], dtype=float)
        except ValueError:
            values = np.full(len(persons), np.nan)
        if not np.isfinite(values).all():
            bad = next(p for p in persons if not _finite(p[name]))
            raise ValueError(f"{where}: person {shown(bad['id'])}: {name}: expected a finite number, got "
                               f"{shown(bad[name])}")
        low, high, unit = _BOUNDS[name]
        outside = np.flatnonzero((values < low) | (values > high))
        if outside.size:  # the vehicles' bounds (fcd_checks): absurd numbers only
            bad = persons[int(outside[0])]
            raise ValueError(f"{where}: person {shown(bad['id'])}: {name}: expected a number in [{low:g}, {high:g}] "
                             f"{unit}, got {shown(bad[name])}")
        return values

    types = [p.get("type") or "DEFAULT_PEDTYPE" for p in persons]
    size = np.array(list(map(sizes.get, types, itertools.repeat(SUMO_PERSON_SIZE))), dtype=float).reshape(-1, 2)
    return PersonSnapshot(np.array([p["id"] for p in persons], dtype=str), numbers("x"), numbers("y"),
                          compass_deg_to_heading(numbers("angle")), numbers("speed"),
                          np.array([p["edge"] for p in persons], dtype=str), np.array(types, dtype=str),
                          size[:, 0].copy(), size[:, 1].copy())


def check_person_edges(where: str, persons: PersonSnapshot, network: RoadNetwork) -> None:
    """FcdError naming ``where`` and the first person on an edge that is not in ``network``."""
    unknown = np.flatnonzero(network.find_edges(persons.edge_id) < 0)
    if unknown.size:
        k = int(unknown[0])
        raise fcd_error(f"{where}: person {shown(str(persons.ids[k]))}: edge: expected an edge of "
                         f"{network.path.name}, got {shown(str(persons.edge_id[k]))} (not in it); is --net the "
                         "network of this run?")


def check_distinct_ids(where: str, new_vehicles: np.ndarray, persons_seen: set[str], persons: PersonSnapshot | None,
                       vehicles_seen: dict[str, int]) -> None:
    """FcdError naming ``where`` where a person has the id of a vehicle of the file: the audit and its CSVs tell
    road users apart by their ids alone. ``new_vehicles``: those first seen at this step; ``persons_seen``,
    ``vehicles_seen``: the ids seen so far (this step's vehicles among them)."""
    shared = [v for v in new_vehicles.tolist() if v in persons_seen] if persons_seen else []
    if persons is not None:
        shared += [p for p in persons.ids.tolist() if p in vehicles_seen]
    if shared:
        raise fcd_error(f"{where}: person and vehicle {shown(shared[0])}: id: expected the ids of persons and "
                         "vehicles to differ (the audit tells road users apart by their ids; docs/outputs.md)")


def _finite(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
