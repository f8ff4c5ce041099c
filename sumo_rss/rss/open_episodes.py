"""The open episodes of a run (one struct of arrays, sorted by pair key) and the constraints of a proper response
that they track per car."""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np


class Constraint(str, Enum):
    """One rule of a proper response (values go into violations.csv)."""

    ACCEL_DURING_RESPONSE = "lon-accel-during-response-time"  # a ≤ a_acc during ρ
    BRAKE_AFTER_RESPONSE = "lon-brake-after-response-time"  # a ≤ −b (b_min or b_corr) after ρ, until stopped
    BRAKE_BEYOND_MAX = "lon-brake-beyond-max"  # front car: a ≥ −b_max
    LATERAL_ENVELOPE = "lat-speed-envelope"  # lateral speed towards the other within the braking envelope


CONSTRAINTS = tuple(Constraint)
N_CONSTRAINTS = len(CONSTRAINTS)


@dataclass
class OpenEpisodes:
    """Open episodes, sorted by key (struct of arrays)."""

    keys: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    serial: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # 0, 1, ... in opening order
    a_id: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    b_id: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    uids: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))  # of (a, b)
    a_class: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    b_class: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    t_b: np.ndarray = field(default_factory=lambda: np.zeros(0))
    t_last: np.ndarray = field(default_factory=lambda: np.zeros(0))
    window: np.ndarray = field(default_factory=lambda: np.zeros(0))  # [s] the pair's ρ: how long it may be joined
    must_brake: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    moved_off: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))  # owes braking from t_b
    front_limited: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    brake_correct: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    owed_lat: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    trigger: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    roles: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=object))
    owed: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=object))
    area: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    a_left: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  # a is left of b (last seen apart)
    in_line: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  # centres within μ/2 across
    u0: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # lateral speed towards the other at t_b
    lat_settled: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))  # ≤ 0 after ρ once
    min_lon_margin: np.ndarray = field(default_factory=lambda: np.zeros(0))
    min_lat_margin: np.ndarray = field(default_factory=lambda: np.zeros(0))
    responsible: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    # Junctions: whether each car has had its front bumper in the conflict area, has stood still short of it, and at
    # the last step seen was short of it braking hard enough to stop before it.
    entered: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    stood_short: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    stopping: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=bool))
    active: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, N_CONSTRAINTS), dtype=bool))
    v_start: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, N_CONSTRAINTS)))
    v_last: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, N_CONSTRAINTS)))
    v_worst: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, N_CONSTRAINTS)))
    v_bound: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, N_CONSTRAINTS)))
    v_excess: np.ndarray = field(default_factory=lambda: np.full((0, 2, N_CONSTRAINTS), -np.inf))

    def take(self, index: np.ndarray) -> OpenEpisodes:
        """The episodes at ``index`` (integer positions). ``ndarray.take`` along the first axis: fancy indexing of
        the [n, 2] and [n, 2, 4] fields cost ~30 µs each for 2,850 episodes, take 2-6 µs."""
        return OpenEpisodes(**{name: value.take(index, axis=0) for name, value in vars(self).items()})

    @staticmethod
    def concat(parts: list[OpenEpisodes]) -> OpenEpisodes:
        names = vars(parts[0]).keys()
        return OpenEpisodes(**{n: np.concatenate([getattr(p, n) for p in parts]) for n in names})

    def __len__(self) -> int:
        return int(self.keys.shape[0])
