"""Checks of the values an FCD reader has parsed for one time step, against physics and the network.

What no vehicle can do or what contradicts the network is an error naming the file, the time step, the vehicle and
the attribute (:class:`~sumo_rss.rss.fcd.FcdError`): a speed of 1e300 m/s would be written into episodes.csv as
-inf, a position 1e12 m off the vehicle's lane overflowed scipy's cKDTree. The bounds are far beyond what SUMO
writes for any vehicle (docs/outputs.md, "Bad input, full disks and interruptions"), so that they never refuse a
real run: they only keep absurd numbers out of the audit and its CSVs.
"""
from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import SumoRssError, shown
from ..road.net_check import MAX_COORDINATE_M
from ..road.network import RoadNetwork

MAX_SPEED = 200.0  # [m/s] 720 km/h: faster than any road or rail vehicle
MIN_STEP_S = 0.001  # [s] SUMO's shortest step length: time steps closer than this are not a SUMO output
MAX_ACCEL = MAX_SPEED / MIN_STEP_S  # [m/s²] from the top speed to a standstill within SUMO's shortest step
MAX_TIME_S = 1e9  # [s] about 32 years of simulated time
MAX_ANGLE_DEG = 720.0  # SUMO writes angles in [0, 360); anything beyond two turns either way is no angle
OFF_LANE_M = 10.0  # [m] a front bumper farther than this beyond its lane's edge is not on that lane
LANE_END_M = 1.0  # [m] how far a lane position may lie before the start or past the end of its lane (rounding)
MAX_SIGNALS = 2**31 - 1  # SUMO's vehicle signals are bits of a 32-bit integer
SIGNALS_FORM = f"an integer in [0, {MAX_SIGNALS}] (SUMO's signal bits)"


@dataclass(frozen=True)
class StepValues:
    """What an FCD reader parsed of one time step: per vehicle, in the order of ``ids`` (None: not in the file)."""

    ids: np.ndarray
    lane: np.ndarray  # lane indices in the network
    x: np.ndarray  # [m] front-bumper centre
    y: np.ndarray  # [m]
    angle: np.ndarray  # [deg] SUMO's navigation angle
    speed: np.ndarray  # [m/s]
    lane_pos: np.ndarray | None = None  # [m] front bumper along the lane ('pos')
    lat_pos: np.ndarray | None = None  # [m] from the lane's centre line ('posLat')
    accel: np.ndarray | None = None  # [m/s²] ('acceleration')
    lat_speed: np.ndarray | None = None  # [m/s] ('speedLat')
    signals: np.ndarray | None = None  # SUMO's signal bits


def check_step(where: str, time: float, previous_time: float | None, step: StepValues, network: RoadNetwork,
               from_centre_line: Callable[[], np.ndarray] | None = None) -> None:
    """Refuse the time step ``time`` [s] (``where``: the file and the step, for the message) where a value is
    beyond what a vehicle can do or contradicts ``network``; FcdError naming the vehicle and the attribute.
    ``from_centre_line()``: [m] how far each front bumper is from its lane's centre line (its nearest point), where
    the caller projects them anyway (asked once the numbers are checked); else worked out here."""
    if not abs(time) <= MAX_TIME_S:
        raise fcd_error(f"{where}: time: expected at most {MAX_TIME_S:g} s, got {time:g}")
    if previous_time is not None and time - previous_time < MIN_STEP_S - 1e-9:
        raise fcd_error(f"{where}: time: expected at least {MIN_STEP_S:g} s after the time step before "
                     f"({previous_time:g} s; SUMO's shortest step), got {time:g}")
    bounds = [("x", step.x, MAX_COORDINATE_M, "m"), ("y", step.y, MAX_COORDINATE_M, "m"),
              ("angle", step.angle, MAX_ANGLE_DEG, "degrees"), ("acceleration", step.accel, MAX_ACCEL, "m/s²"),
              ("speedLat", step.lat_speed, MAX_SPEED, "m/s")]
    for name, values, limit, unit in bounds:
        if values is not None:
            _refuse(where, step.ids, name, values, np.abs(values) <= limit,
                    f"a number in [-{limit:g}, {limit:g}] {unit}")
    _refuse(where, step.ids, "speed", step.speed, (step.speed >= 0.0) & (step.speed <= MAX_SPEED),
            f"a number >= 0 (m/s) and at most {MAX_SPEED:g} m/s")
    if step.signals is not None:
        _refuse(where, step.ids, "signals", step.signals, (step.signals >= 0) & (step.signals <= MAX_SIGNALS),
                SIGNALS_FORM)
    lane, half_width = step.lane, 0.5 * network.lane_width[step.lane]
    if step.lane_pos is not None:
        length = network.lane_length[lane]
        _refuse(where, step.ids, "pos", step.lane_pos,
                (step.lane_pos >= -LANE_END_M) & (step.lane_pos <= length + LANE_END_M),
                f"a position along the vehicle's lane, in [0, its length] (give or take {LANE_END_M:g} m)")
    if step.lat_pos is not None:
        _refuse(where, step.ids, "posLat", step.lat_pos, np.abs(step.lat_pos) <= half_width + OFF_LANE_M,
                f"a lateral position at most {OFF_LANE_M:g} m beyond the edge of the vehicle's lane")
    beyond = (_from_centre_line(network, step, half_width) if from_centre_line is None else from_centre_line()) - \
        half_width
    bad = np.flatnonzero(beyond > OFF_LANE_M)
    if bad.size:
        k = int(bad[0])
        raise fcd_error(f"{where}: vehicle {shown(str(step.ids[k]))}: x, y: expected a position on its lane "
                     f"{shown(str(network.lane_ids[lane[k]]))} (at most {OFF_LANE_M:g} m beyond its edge), got "
                     f"({step.x[k]:.6g}, {step.y[k]:.6g}), {beyond[k]:.6g} m beyond it; is --net the network of "
                     "this run?")


def _refuse(where: str, ids: np.ndarray, name: str, values: np.ndarray, fine: np.ndarray, expected: str) -> None:
    """FcdError naming the first vehicle whose ``name`` is not ``fine`` (a NaN never is)."""
    bad = np.flatnonzero(~fine)
    if bad.size:
        k = int(bad[0])
        raise fcd_error(f"{where}: vehicle {shown(str(ids[k]))}: {name}: expected {expected}, got {values[k]:.6g}")


def fcd_error(message: str) -> SumoRssError:
    from .fcd_inputs import FcdError  # the reader's error (this module is its helper)

    return FcdError(message)


def _from_centre_line(network: RoadNetwork, step: StepValues, half_width: np.ndarray) -> np.ndarray:
    """[m] how far each front bumper is from the centre line of its lane (its nearest point), worked out for the
    vehicles that are not within OFF_LANE_M of the lane's edge at the centre point of their lane position (most are:
    projecting every vehicle onto the whole of its lane costs more). Where a lane's elevation makes its length
    longer than its shape, the point at a lane position is not the centre point SUMO means: the nearest point
    decides then."""
    lane = step.lane
    distance = np.zeros(len(lane))
    if step.lane_pos is not None and len(lane):
        shape_s = step.lane_pos * network.shapes.cumulative[lane, -1] / np.maximum(network.lane_length[lane], 1e-9)
        cx, cy = network.shapes.point_at(lane, shape_s, np.zeros(len(lane)))
        distance = np.hypot(step.x - cx, step.y - cy)
    far = np.flatnonzero(distance - half_width > OFF_LANE_M) if step.lane_pos is not None else np.arange(len(lane))
    if far.size:
        distance[far] = np.abs(network.frenet(lane[far], step.x[far], step.y[far])[1])
    return distance


def pedestrian_lanes(network: RoadNetwork) -> np.ndarray:
    """[lanes] whether only pedestrians may use each lane of ``network`` (a sidewalk, crossing or walking area), as
    its ``allow`` says."""
    from ..road.topology import read_topology

    lanes = read_topology(network.path).lanes
    permissions = [lanes.get(edge, ())[index] if index < len(lanes.get(edge, ())) else None for edge, index in
                   zip(network.edge_ids[network.lane_edge].tolist(), network.lane_index.tolist())]
    return np.array([p is not None and p.allow is not None and p.allow <= {"pedestrian"} for p in permissions],
                    dtype=bool)


def warn_on_walkways(where: str, ids: np.ndarray, lane: np.ndarray, network: RoadNetwork, walkways: np.ndarray
                     ) -> bool:
    """Warn about the first vehicle on a lane only pedestrians may use (``walkways``: :func:`pedestrian_lanes`):
    SUMO puts none there (an FCD of a network without sidewalks audited on one with them, whose lane ids it shares),
    unless a program placed it there ignoring the lane's permissions (TraCI moveToXY), so it is no error. Whether it
    warned."""
    on = np.flatnonzero(walkways[lane])
    if on.size:
        k = int(on[0])
        warnings.warn(f"{where}: vehicle {shown(str(ids[k]))} is on lane {shown(str(network.lane_ids[lane[k]]))}, "
                      f"which only pedestrians may use in {network.path.name}; is --net the network of this run?",
                      stacklevel=5)
    return bool(on.size)
