"""The persons of a running simulation, read from libsumo subscriptions into a PersonSnapshot each step.

Values are rounded as SUMO writes them to the FCD (``as_written``), so the online audit sees the numbers an offline
audit of the run's FCD reads. A person riding in a vehicle is no pedestrian and is left out (as the FCD reader
leaves it out).
"""
from __future__ import annotations

from collections.abc import Callable

import libsumo
import numpy as np
from libsumo import constants as tc

from .persons import PersonSnapshot
from .snapshot import compass_deg_to_heading

_VARS = (tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED, tc.VAR_ROAD_ID, tc.VAR_VEHICLE)


class PersonFeed:
    """Subscribes to every person that departs and builds the step's PersonSnapshot."""

    def __init__(self, rounding: Callable[[np.ndarray], np.ndarray]):
        self._round = rounding  # the session's as_written: values as the FCD writes them
        self._static: dict[str, tuple[str, float, float]] = {}  # person → (vType, length [m], width [m])

    def step(self) -> None:
        """After a simulation step: subscribe to the persons that departed, forget those that arrived."""
        p = libsumo.person
        for pid in libsumo.simulation.getDepartedPersonIDList():
            p.subscribe(pid, _VARS)
            self._static[pid] = (p.getTypeID(pid), p.getLength(pid), p.getWidth(pid))
        for pid in libsumo.simulation.getArrivedPersonIDList():
            self._static.pop(pid, None)

    def snapshot(self) -> PersonSnapshot | None:
        """The walking persons now (None when there are none)."""
        if not self._static:
            return None
        results = libsumo.person.getAllSubscriptionResults()
        ids = sorted(pid for pid, r in results.items() if pid in self._static and not r[tc.VAR_VEHICLE])
        if not ids:
            return None
        rows = [results[pid] for pid in ids]
        static = [self._static[pid] for pid in ids]
        n = len(ids)
        xy = self._round(np.array([r[tc.VAR_POSITION] for r in rows], dtype=float).reshape(n, 2))
        return PersonSnapshot(
            np.array(ids, dtype=str), xy[:, 0], xy[:, 1],
            compass_deg_to_heading(self._round(np.array([r[tc.VAR_ANGLE] for r in rows], dtype=float))),
            self._round(np.array([r[tc.VAR_SPEED] for r in rows], dtype=float)),
            np.array([r[tc.VAR_ROAD_ID] for r in rows], dtype=str), np.array([s[0] for s in static], dtype=str),
            np.array([s[1] for s in static], dtype=float), np.array([s[2] for s in static], dtype=float))
