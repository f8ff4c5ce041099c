"""Actuation of the ego through libsumo: hand it to an external planner and place it each step."""
from __future__ import annotations

import libsumo

from ..trajectory import TrajectoryState
from .snapshot import heading_to_compass_deg

SPEED_MODE_EXTERNAL = 32  # SUMO bit set: only 'regard maximum deceleration' stays on; no safe-speed checks
LANE_CHANGE_MODE_NONE = 0  # SUMO performs no lane changes of its own
KEEP_ROUTE_EXACT = 2  # moveToXY: exact position (incl. lateral), any edge; the route is adapted
SPEED_MODE_DEFAULT = 31  # SUMO's own safe-speed checks
LANE_CHANGE_MODE_DEFAULT = 1621  # SUMO's own lane-change model (its default)
SPEED_RELEASE = -1.0  # setSpeed value that hands the speed back to SUMO's car-following model


def take_control(vehicle_id: str) -> None:
    """Switch off SUMO's own longitudinal safety and lane changing for ``vehicle_id``."""
    libsumo.vehicle.setSpeedMode(vehicle_id, SPEED_MODE_EXTERNAL)
    libsumo.vehicle.setLaneChangeMode(vehicle_id, LANE_CHANGE_MODE_NONE)


def place(vehicle_id: str, state: TrajectoryState) -> None:
    """Put ``vehicle_id`` at ``state`` in the coming simulation step (front-bumper centre, heading, speed)."""
    libsumo.vehicle.moveToXY(vehicle_id, "", -1, state.x, state.y, angle=heading_to_compass_deg(state.heading),
                             keepRoute=KEEP_ROUTE_EXACT)
    libsumo.vehicle.setPreviousSpeed(vehicle_id, state.speed, state.accel)
    libsumo.vehicle.setSpeed(vehicle_id, state.speed)


def release(vehicle_id: str) -> None:
    """Hand ``vehicle_id`` back to SUMO's own models (used when it reaches the end of its route: SUMO lets it
    arrive and removes it, which a vehicle placed by moveToXY never does on its own)."""
    libsumo.vehicle.setSpeedMode(vehicle_id, SPEED_MODE_DEFAULT)
    libsumo.vehicle.setLaneChangeMode(vehicle_id, LANE_CHANGE_MODE_DEFAULT)
    libsumo.vehicle.setSpeed(vehicle_id, SPEED_RELEASE)
