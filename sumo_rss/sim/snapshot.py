"""WorldSnapshot: every vehicle on the road at one time step, as a struct of numpy arrays.

Pure numpy (no libsumo): the session builds snapshots from subscriptions, the offline FCD reader from files.
Row ``i`` of every array describes the same vehicle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ..angles import wrap_angle
from ..road_users import BICYCLE_CLASS, PERSON_CLASS  # noqa: F401  (classes beside EGO_CLASS, BACKGROUND_CLASS)
from .persons import PersonSnapshot

EGO_CLASS = "ego"
BACKGROUND_CLASS = "background"


def compass_deg_to_heading(angle_deg: np.ndarray | float) -> np.ndarray | float:
    """SUMO angle (degrees, 0 = north, clockwise) → heading (rad, math convention, 0 = east, in (-π, π])."""
    return wrap_angle(np.radians(90.0 - np.asarray(angle_deg, dtype=float)))


def heading_to_compass_deg(heading: float) -> float:
    """Heading (rad, math convention) → SUMO angle (degrees, 0 = north, clockwise, in [0, 360))."""
    return (90.0 - math.degrees(heading)) % 360.0


@dataclass(frozen=True, eq=False)
class WorldSnapshot:
    """All vehicles on the road at ``time`` [s].

    Positions are the **front-bumper centre** (SUMO's convention). Lateral quantities are + = left.
    ``route_edges[i]`` is the vehicle's planned route (edge ids) and ``route_index[i]`` the index of its
    current edge in it (-1 when unknown, e.g. on an internal junction lane or in an FCD file).
    """

    time: float  # [s]
    ids: np.ndarray  # str
    x: np.ndarray  # [m]
    y: np.ndarray  # [m]
    heading: np.ndarray  # [rad], math convention
    speed: np.ndarray  # [m/s]
    accel: np.ndarray  # [m/s²]
    lat_speed: np.ndarray  # [m/s], + = left
    length: np.ndarray  # [m]
    width: np.ndarray  # [m]
    lane_id: np.ndarray  # str
    edge_id: np.ndarray  # str
    lane_index: np.ndarray  # int
    lane_pos: np.ndarray  # [m] s of the front bumper along the lane
    lat_pos: np.ndarray  # [m] offset of the front-bumper centre from the lane's centre line, + = left (posLat)
    vclass: np.ndarray  # str: 'ego' | 'background' | 'bicycle'
    vtype: np.ndarray  # str: SUMO vType id
    signals: np.ndarray  # int: SUMO signal bit set
    route_index: np.ndarray  # int
    route_edges: tuple[tuple[str, ...], ...] | None = None
    tls_states: dict[str, str] | None = None  # signal id → SUMO state string (one character per link index)
    # [m/s²] how far ``accel`` may be off by how it was measured (from speeds an FCD wrote with few decimals); the
    # audit widens its acceleration tolerance by it
    accel_resolution: float = 0.0
    persons: PersonSnapshot | None = None  # the persons on the network (None: not read, e.g. a run without any)

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    def index_of(self, vehicle_id: str) -> int:
        """Row of ``vehicle_id``; raises ``KeyError`` if it is not on the road."""
        hits = np.flatnonzero(self.ids == vehicle_id)
        if hits.size == 0:
            raise KeyError(vehicle_id)
        return int(hits[0])

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Geometric centres (x, y) [m] of all vehicles (SUMO reports the front-bumper centre)."""
        return (self.x - 0.5 * self.length * np.cos(self.heading),
                self.y - 0.5 * self.length * np.sin(self.heading))

    def array_fields(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self) if isinstance(getattr(self, f.name), np.ndarray)}

    def equals(self, other: WorldSnapshot) -> bool:
        """Exact equality of time, every array and the routes."""
        if self.time != other.time or self.route_edges != other.route_edges or self.tls_states != other.tls_states:
            return False
        if (self.persons is None) != (other.persons is None) or (
                self.persons is not None and not self.persons.equals(other.persons)):  # type: ignore[arg-type]
            return False
        mine, theirs = self.array_fields(), other.array_fields()
        return all(np.array_equal(mine[k], theirs[k]) for k in mine)
