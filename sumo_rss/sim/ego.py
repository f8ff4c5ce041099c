"""Actuation of the ego through libsumo: hand it to an external planner and place it each step, or leave it to
SUMO's own models within the limits of an RSS guard (``controller = "sumo_restricted"``)."""
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
# Restricted: SUMO's checks (safe speed, acceleration, right of way, red lights) stay on for a speed cap, except
# 'regard maximum deceleration', so that a cap may brake beyond the vType's decel (the guard's emergency braking).
SPEED_MODE_RESTRICTED = 27
# Restricted: SUMO makes no lane change of its own, but still computes the ones it wants (getLaneChangeState);
# requested changes respect the other drivers' speed and braking gaps, as SUMO's default mode treats them.
LANE_CHANGE_MODE_ON_REQUEST = 512
LCA_LEFT, LCA_RIGHT, LCA_BLOCKED, LCA_CHANGING = 0x2, 0x4, 0x3E00, 0x40000000  # SUMO's lane-change state bits


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


class LaneShadows:
    """Frees the lane a placed ego has left of its leftover shadow. With ``--lanechange.duration`` a car placed by
    ``moveToXY`` whose lane changes while its body still overlaps the lane it leaves stays an obstacle in that lane:
    the cars behind there stop behind where it was, or follow it, for as long as it stays in its new lane (SUMO 1.28;
    docs/planner.md, "Standing at the end of a deceleration lane"). Moving the ego back into that lane by ``moveTo``
    just before the step's ``moveToXY`` (which puts it where it goes) frees it; done once per change, when the ego's
    body is inside its new lane with ``SHADOW_CLEARANCE`` to spare (else SUMO would give it a shadow again)."""

    SHADOW_CLEARANCE = 0.1  # [m]

    def __init__(self, vehicle_id: str):
        self.vehicle_id = vehicle_id
        self._lane = ""  # the ego's lane at the last placement
        self._left: str | None = None  # the lane it left with a shadow there, not yet freed

    def before_placing(self) -> None:
        """Call before each :func:`place` of the ego."""
        v = self.vehicle_id
        lane = libsumo.vehicle.getLaneID(v)
        if not lane or lane.startswith(":"):
            self._lane = lane
            return
        lat, half = libsumo.vehicle.getLateralLanePosition(v), 0.5 * libsumo.vehicle.getWidth(v)
        edge = lane.rsplit("_", 1)[0]
        if lane != self._lane and self._lane.rsplit("_", 1)[0] == edge:
            self._left = self._lane  # a change within the edge (SUMO numbers an edge's lanes <edge>_<index>)
        self._lane = lane
        if self._left is None or abs(lat) + half > 0.5 * libsumo.lane.getWidth(lane) - self.SHADOW_CLEARANCE:
            return
        position = libsumo.vehicle.getLanePosition(v)
        if position <= libsumo.lane.getLength(self._left):
            libsumo.vehicle.moveTo(v, self._left, position)
        self._left = None


def release(vehicle_id: str) -> None:
    """Hand ``vehicle_id`` back to SUMO's own models (used when it reaches the end of its route: SUMO lets it
    arrive and removes it, which a vehicle placed by moveToXY never does on its own)."""
    libsumo.vehicle.setSpeedMode(vehicle_id, SPEED_MODE_DEFAULT)
    libsumo.vehicle.setLaneChangeMode(vehicle_id, LANE_CHANGE_MODE_DEFAULT)
    libsumo.vehicle.setSpeed(vehicle_id, SPEED_RELEASE)


def restrict(vehicle_id: str) -> None:
    """Leave ``vehicle_id`` to SUMO's models under external limits: speed caps (:func:`cap_speed`) and, where
    :func:`own_lane_changes` says so, lane changes only on request (:func:`change_lane`)."""
    libsumo.vehicle.setSpeedMode(vehicle_id, SPEED_MODE_RESTRICTED)


def own_lane_changes(vehicle_id: str, allowed: bool) -> None:
    """Let SUMO's lane-change model change lanes on its own (its default mode), or only on request."""
    libsumo.vehicle.setLaneChangeMode(vehicle_id, LANE_CHANGE_MODE_DEFAULT if allowed else LANE_CHANGE_MODE_ON_REQUEST)


def cap_speed(vehicle_id: str, speed: float | None) -> None:
    """At most ``speed`` [m/s] at the end of the coming step (SUMO's own model may choose less); None: no cap."""
    libsumo.vehicle.setSpeed(vehicle_id, SPEED_RELEASE if speed is None else max(speed, 0.0))


def wanted_lane_change(vehicle_id: str) -> int:
    """The lane change SUMO's lane-change model wants now and finds unblocked: +1 left, -1 right, 0 none (also
    while a change is under way)."""
    for direction, bit in ((1, LCA_LEFT), (-1, LCA_RIGHT)):
        state = libsumo.vehicle.getLaneChangeState(vehicle_id, direction)[0]  # without TraCI's influence
        if state & bit and not state & (LCA_BLOCKED | LCA_CHANGING):
            return direction
    return 0


def change_lane(vehicle_id: str, direction: int, hold_s: float) -> None:
    """Ask SUMO to change one lane to the left (+1) or right (-1), holding the new lane for ``hold_s`` [s]."""
    libsumo.vehicle.changeLane(vehicle_id, libsumo.vehicle.getLaneIndex(vehicle_id) + direction, hold_s)
