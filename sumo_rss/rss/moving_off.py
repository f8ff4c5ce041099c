"""Cars that move off from standing short of a conflict area (docs/rss.md, "Standing cars at junctions").

At junctions the auditor takes a vehicle whose speed is exactly 0 as not accelerating during its response time
(a_acc = 0 for that step, CARLA's convention, :meth:`~.auditor.ParamResolver.held_standing`): a car standing short
of a conflict area can stop before it, and it does not arrive there. So a pair with such a car is safe while it
stands, and the danger begins when it moves off. The safety of the step before rested on its standing still: it owes
its braking from t_b with no response time (a response time is for reacting to the other car, not to its own start).
"""
from __future__ import annotations

import numpy as np

from ..road_users import PERSON_CLASS
from .sorted_keys import find_sorted


class StandingCars:
    """The road users that stood (speed exactly 0) at the previous step, by uid."""

    def __init__(self) -> None:
        self._uids = np.zeros(0, dtype=np.int64)  # sorted

    def update(self, uids: np.ndarray, speed: np.ndarray) -> None:
        """Remember the step's standing road users (``uids`` and ``speed`` [m/s] per row)."""
        self._uids = np.sort(uids[speed == 0.0])

    def moved_off(self, uids: np.ndarray, vclass: np.ndarray, enter: np.ndarray, speed: np.ndarray, dt: float
                  ) -> np.ndarray:
        """[n, 2] per car of new junction episodes between vehicles (``uids``, ``vclass`` [n, 2]): it stood at the
        step before, short of the conflict area (``enter``: its d_enter now [m], NaN on roads; ``speed`` now
        [m/s]; SUMO moved it ``speed`` · ``dt`` in the step), so the pair was safe only because it stood."""
        stood = find_sorted(self._uids, uids.reshape(-1))[0].reshape(uids.shape)
        vehicles = (vclass != PERSON_CLASS).all(axis=1, keepdims=True)  # crossings of persons are not held
        return stood & vehicles & (enter + speed * dt > 0.0)
