"""A vehicle and a person meeting in a conflict area (a crossing, or a person's wedge over a lane), as junction
situations named in id order (rss.md §10): the intersection test of rss.md §4 with both road users' parameters."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .intersection import (KIND_SAME, KIND_SIGNAL, KIND_YIELD, PRIORITY_A, PRIORITY_B, PRIORITY_SAME,
                           intersection_safety)
from .params import RssParamArrays
from .situations import RULE_ABLE_TO_STOP, RULE_IN_FRONT, RULE_NO_OVERLAP, PairSituations


@dataclass(frozen=True, eq=False)
class Side:
    """One side of each (vehicle, person) pair: its rows (of the step's road users), ids, speeds towards the area
    [m/s], d_enter and d_exit [m] (negative enter: inside) and lengths [m]."""

    row: np.ndarray
    ids: np.ndarray
    speed: np.ndarray
    enter: np.ndarray
    exit: np.ndarray
    length: np.ndarray


def vehicle_person_situations(vehicle: Side, person: Side, vehicle_first: np.ndarray, by_signal: np.ndarray,
                              params: RssParamArrays, area: np.ndarray) -> PairSituations:
    """The pairs' situations: ``vehicle_first`` +1 where the vehicle has priority, -1 the person, 0 neither;
    ``by_signal`` where the signals decided it; ``params`` over the road users' rows; ``area`` the ids."""
    a_is_vehicle = vehicle.ids < person.ids

    def pick(name: str) -> tuple[np.ndarray, np.ndarray]:
        on_vehicle, on_person = getattr(vehicle, name), getattr(person, name)
        return np.where(a_is_vehicle, on_vehicle, on_person), np.where(a_is_vehicle, on_person, on_vehicle)

    (ra, rb), (v_a, v_b), (enter_a, enter_b), (exit_a, exit_b), (length_a, length_b) = (
        pick(name) for name in ("row", "speed", "enter", "exit", "length"))
    priority = np.where(vehicle_first == 0, PRIORITY_SAME,
                        np.where((vehicle_first > 0) == a_is_vehicle, PRIORITY_A, PRIORITY_B))
    kind = np.where(by_signal, KIND_SIGNAL, np.where(priority != PRIORITY_SAME, KIND_YIELD, KIND_SAME))
    safety = intersection_safety(v_a, enter_a, exit_a, length_a, params.take(ra), v_b, enter_b, exit_b, length_b,
                                 params.take(rb), priority, True)
    rules = (safety.able_to_stop * RULE_ABLE_TO_STOP + safety.in_front * RULE_IN_FRONT +
             safety.no_time_overlap * RULE_NO_OVERLAP).astype(np.int8)
    # The yielding one's margin (with equal priority, of the one deeper in trouble), as for two cars.
    a_yields = (priority == PRIORITY_B) | ((priority == PRIORITY_SAME) &
                                           (enter_a - safety.need_a <= enter_b - safety.need_b))
    n = len(ra)
    nan = np.full(n, np.nan)
    return PairSituations(
        a=ra, b=rb, kind=kind, a_is_rear=~safety.a_in_front, a_is_left=np.zeros(n, dtype=bool),
        lon_gap=np.where(a_yields, enter_a, enter_b), lat_gap=nan, v_lon_a=v_a, v_lon_b=v_b,
        v_lat_a=np.zeros(n), v_lat_b=np.zeros(n), lon_d_min=np.where(a_yields, safety.need_a, safety.need_b),
        lat_d_min=nan, lon_safe=safety.safe, lat_safe=np.zeros(n, dtype=bool), rules=rules,
        priority=priority.astype(np.int8),
        in_front=np.where(safety.a_in_front, 1, np.where(safety.b_in_front, 2, 0)).astype(np.int8),
        area=area, enter_a=enter_a, enter_b=enter_b)
