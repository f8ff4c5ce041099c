"""What a vehicle owes in its open episodes (:class:`OwedResponses`), for a proper-response guard
(:mod:`sumo_rss.planner.guard`) to restrict its command to."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .open_episodes import OpenEpisodes
from .situations import SAME_DIRECTION_CODES


@dataclass(frozen=True, eq=False)
class OwedResponses:
    """What one vehicle owes in its open episodes (one row per episode), for a proper-response guard."""

    t_b: np.ndarray  # [s] danger threshold time
    must_brake: np.ndarray  # bool: longitudinal braking owed after ρ
    brake_correct: np.ndarray  # bool: the braking owed is b_corr (opposite direction, correct lane)
    front_limited: np.ndarray  # bool: must not brake harder than b_max
    owed_lat: np.ndarray  # bool: lateral response owed (not while the cars are in line: neither side is towards)
    other_is_left: np.ndarray  # bool: the other car is on this car's left (as they are now)
    u0: np.ndarray  # [m/s] this car's lateral speed towards the other at t_b
    other_id: np.ndarray  # the other car's id
    same_direction: np.ndarray  # bool: one car follows the other (same direction or merge)
    lat_settled: np.ndarray  # bool: this car's speed towards the other has been ≤ 0 from ρ on (it must stay there)
    # bool: the lateral response is owed in the episode, in line now or not (judged at any step where the cars
    # are apart: ``in_line``); None: as ``owed_lat``
    lat_duty: np.ndarray | None = None
    # bool: the braking is owed from t_b, without a response time (moved off from standing, moving_off.py); None:
    # never
    no_response_time: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.lat_duty is None:
            object.__setattr__(self, "lat_duty", self.owed_lat)
        if self.no_response_time is None:
            object.__setattr__(self, "no_response_time", np.zeros(len(self.t_b), dtype=bool))

    def __len__(self) -> int:
        return int(self.t_b.shape[0])

    def without_lon_duty(self) -> frozenset[str]:
        """The cars going this car's way that it owes no longitudinal braking in an open episode: the episode did
        not start longitudinally for it (e.g. the other car cut in), so closing the gap is not its duty."""
        return frozenset(self.other_id[self.same_direction & ~self.must_brake].tolist())


def owed_in(e: OpenEpisodes, vehicle_id: str) -> OwedResponses:
    """The responses ``vehicle_id`` owes in the open episodes ``e``."""
    as_a, as_b = e.a_id == vehicle_id, e.b_id == vehicle_id
    idx = np.flatnonzero(as_a | as_b)
    car = np.where(as_a[idx], 0, 1)
    return OwedResponses(
        t_b=e.t_b[idx], must_brake=e.must_brake[idx, car], brake_correct=e.brake_correct[idx, car],
        front_limited=e.front_limited[idx, car], owed_lat=e.owed_lat[idx] & ~e.in_line[idx],
        other_is_left=np.where(car == 0, ~e.a_left[idx], e.a_left[idx]), u0=e.u0[idx, car],
        other_id=np.where(car == 0, e.b_id[idx], e.a_id[idx]),
        same_direction=np.isin(e.kind[idx], SAME_DIRECTION_CODES), lat_settled=e.lat_settled[idx, car],
        lat_duty=e.owed_lat[idx], no_response_time=e.moved_off[idx, car])
