"""PersonSnapshot: every person (pedestrian) of one time step, as a struct of numpy arrays (rss.md §10).

Kept beside a :class:`~sumo_rss.sim.snapshot.WorldSnapshot`'s vehicles (its ``persons``), not among them: persons
have no lane position or route as vehicles have, and only the audit's person situations read them. Row ``i`` of
every array describes the same person. Pure numpy: the session fills it from libsumo, the FCD reader from files.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SUMO_PERSON_SIZE = (0.215, 0.478)  # [m] length, width of SUMO's DEFAULT_PEDTYPE


@dataclass(frozen=True, eq=False)
class PersonSnapshot:
    """Persons at one step: ``x``, ``y`` [m] (SUMO's person position), ``heading`` [rad] (math convention),
    ``speed`` [m/s] along the walking direction, ``edge_id`` (a crossing ``:<junction>_c<k>``, a walking area
    ``:<junction>_w<k>``, or a normal edge: its sidewalk, or its road where it has none), ``vtype``, ``length``,
    ``width`` [m]."""

    ids: np.ndarray  # str
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    edge_id: np.ndarray  # str
    vtype: np.ndarray  # str
    length: np.ndarray
    width: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    @classmethod
    def empty(cls) -> PersonSnapshot:
        none = np.zeros(0)
        return cls(np.zeros(0, dtype=str), none, none, none, none, np.zeros(0, dtype=str), np.zeros(0, dtype=str),
                   none, none)

    def equals(self, other: PersonSnapshot) -> bool:
        """Exact equality of every array."""
        return all(np.array_equal(getattr(self, k), getattr(other, k)) for k in self.__dataclass_fields__)
