"""The FCD reader: SUMO FCD files → a stream of WorldSnapshots (constant memory).

The file is streamed (:mod:`.fcd_parse`) and every ``<timestep>`` is dropped once read. Vehicle ids, lanes and vTypes
are numbered once per distinct name (:mod:`.fcd_names`). Missing attributes are derived: accelerations from speed
differences, lane position and lateral offset from x, y and the lane shapes, lateral speeds from lateral-position
differences on one edge. Vehicle sizes come from a vType/route file or SUMO's defaults (:mod:`.fcd_inputs`).
"""
from __future__ import annotations

import functools
import math
import warnings
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from ..errors import cut, listed, shown
from ..road.network import RoadNetwork
from ..sim.demand import EGO_TYPE
from ..sim.snapshot import BACKGROUND_CLASS, BICYCLE_CLASS, EGO_CLASS, WorldSnapshot, compass_deg_to_heading
from ..sumo_xml import MALFORMED, bytes_consumed, ends_cut, open_output
from .fcd_checks import SIGNALS_FORM, StepValues, check_step, pedestrian_lanes, warn_on_walkways
from .fcd_inputs import FcdError, VehicleInfo
from .fcd_names import NameTable
from .fcd_parse import FcdParser, FcdStep, OutsideStepError
from .fcd_persons import check_distinct_ids, check_person_edges, person_snapshot
from .situations import against_lane

JUMP_SPEED = 5.0  # [m/s] lateral motion faster than this between two FCD steps is a lane change done in one step
CENTRED = 0.05  # [m] a car this close to its lane's centre line at two steps, in another lane, jumped between them
FINE_DECIMALS = 6  # positions written with this many decimals (sumo --precision 6) give exact lateral speeds
# What the reader remembers of a car from the step before (FcdReader._prev), and what it takes for one not seen then:
# speed [m/s], edge, lane, lateral position in the lane (off-centre) and across the edge [m], lateral speed [m/s].
_UNSEEN = (0.0, -1, -1, 1.0, 0.0, 0.0)
SUMO_DEFAULT_SIZE = (5.0, 1.8)  # [m] length, width of SUMO's default passenger vType (for vTypes SUMO was not given)
NEEDED_ATTRIBUTES = ("needed: id, x, y, angle, speed, lane; SUMO writes them by default, and with "
                     "--fcd-output.attributes they must be listed")


class FcdReader:
    """Iterate over the WorldSnapshots of an FCD file (constant memory)."""

    def __init__(self, path: str | Path, network: RoadNetwork, vehicles: VehicleInfo | None = None,
                 ego_ids: tuple[str, ...] = ()):
        self.path = Path(path)
        self.network = network
        self.vehicles = vehicles or VehicleInfo()
        self.ego_ids = set(ego_ids)
        self._prev = _PreviousStep()
        self._resolution: float | None = None  # [m] of a lateral position difference written with few decimals
        self._speed_decimals: int | None = None  # of the speeds as written (for accelerations worked out from them)
        self._prev_time: float | None = None
        self._warned_jump = False  # about instantaneous lane changes
        self._warned_containers = False  # about containers, which are not audited
        self._warned_walkway = False  # about a vehicle on a lane only pedestrians may use
        self.people: set[str] = set()  # ids of the persons and containers in the file so far
        self._walkers: set[str] = set()  # ids of the persons audited (walking) in the file so far
        self._step: float | None = None  # [s] the file's first step length
        self._warned_step = False  # about unevenly spaced steps
        self.bytes_read = 0  # of the file on disk, up to the last step yielded (progress over its size)
        self._lanes = NameTable(network.lane_ids.tolist())  # a lane's number is its index in the network
        self._ids = NameTable()  # of each vehicle seen (the step before's look-up)
        self._types = NameTable()  # of each vType seen: its row of _type_table
        self._routes = np.zeros(0, dtype=object)  # by vehicle number: its route (VehicleInfo.route_of, () for none)
        self._type_table = np.zeros((0, 3))  # per vType seen: length, width [m], whether of vClass bicycle

    @property
    def vehicles_seen(self) -> dict[str, int]:
        """The ids of the vehicles in the steps read so far (keys; the values are their numbers)."""
        return self._ids.number

    def __iter__(self) -> Iterator[WorldSnapshot]:
        if not self.path.is_file():
            raise FcdError(f"{self.path}: FCD file not found")
        parser = None
        try:
            with open_output(self.path) as source:
                parser = FcdParser(source)
                root = parser.read_root()
                if root != "fcd-export":
                    raise FcdError(f"{self.path}: not an FCD file (root element <{root}>, expected <fcd-export>)")
                last = None  # the last complete time step [s]
                try:
                    for step in parser:
                        last = self._time_of(step)
                        snapshot = self._snapshot(step, last)
                        self.bytes_read = bytes_consumed(source)
                        yield snapshot
                except MALFORMED as exc:
                    if last is None or not ends_cut(exc, source):
                        raise
                    warnings.warn(f"{self.path}: the file breaks off after time step {last:g} s (no end tag "
                                  "</fcd-export>, as when SUMO is killed while writing it): read the time steps up "
                                  f"to {last:g} s", stacklevel=2)
        except OutsideStepError as exc:
            raise FcdError(f"{self.path}: line {exc.line}: <{exc.tag}> outside a <timestep>: expected every <{exc.tag}> "
                           f"inside a <timestep time=\"...\"> element (SUMO writes <fcd-export><timestep time=\"0.00\">"
                           f"<{exc.tag} id=\"...\" .../>...</timestep>...</fcd-export>)") from None
        except MALFORMED as exc:
            time = parser.started_time if parser is not None else None
            where = f"after time step {time} s" if time is not None else "before the first time step"
            raise FcdError(f"{self.path}: malformed or truncated FCD {where} ({exc})") from exc

    def _check_step(self, dt: float, time: float) -> None:
        """Warn once per file when the time steps are not evenly spaced (steps missing, or another output
        period): RSS is judged only at the steps written, and accelerations and lateral speeds derived from
        differences span the longer step."""
        if self._step is None:
            self._step = dt
        elif abs(dt - self._step) > 1e-6 and not self._warned_step:
            self._warned_step = True
            warnings.warn(f"{self.path}: time step {time:g} s comes {dt:g} s after the one before, where the file's "
                          f"steps were {self._step:g} s apart (steps missing, or another output period): RSS is "
                          "judged at the steps written only", stacklevel=3)

    def _projections(self, lane: np.ndarray, x: np.ndarray, y: np.ndarray, heading: np.ndarray, length: np.ndarray,
                     fronts: bool, centres: bool) -> tuple[tuple | None, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """In one projection onto the cars' lanes: the front bumpers (x, y [m]) if ``fronts`` (s, d, heading of
        the lane, as ``RoadNetwork.frenet``), and if ``centres`` those of the cars on an edge with an opposite
        direction (their rows, s along the lane [m] and its heading; for :func:`situations.against_lane`)."""
        k = np.flatnonzero(self.network.edge_opposite[self.network.lane_edge[lane]] >= 0) if centres else \
            np.zeros(0, dtype=int)
        cx, cy = x[k] - 0.5 * length[k] * np.cos(heading[k]), y[k] - 0.5 * length[k] * np.sin(heading[k])
        n = len(lane) if fronts else 0
        if not n and not k.size:  # nothing to project (also a step without vehicles)
            empty = np.zeros(0)
            return ((empty, empty, empty) if fronts else None), (k, empty, empty)
        s, d, lane_heading = self.network.frenet(np.concatenate([lane[:n], lane[k]]), np.concatenate([x[:n], cx]),
                                                 np.concatenate([y[:n], cy]))
        return ((s[:n], d[:n], lane_heading[:n]) if fronts else None), (k, s[n:], lane_heading[n:])

    def _against_lane(self, lane: np.ndarray, heading: np.ndarray, length: np.ndarray,
                      centres: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
        """Whether each car drives against its lane (:func:`situations.against_lane`), from ``centres``
        (:meth:`_projections`)."""
        against = np.zeros(len(lane), dtype=bool)
        k, s, lane_heading = centres
        if k.size:
            against[k] = against_lane(self.network, lane[k], s, lane_heading, heading[k], length[k])
        return against

    def _lateral_resolution(self, xs: Sequence[str | None], from_pos_lat: bool) -> float:
        """[m] the largest error of a lateral movement measured from positions as the file writes them (0 for
        FINE_DECIMALS or more; SUMO's --precision applies to x, y and posLat alike); warns once when it is coarse.
        posLat is rounded itself, an offset worked out from x and y by up to √2 of the rounding."""
        decimals = max(_decimals(x or "") for x in xs[:100])
        if decimals >= FINE_DECIMALS:
            return 0.0
        resolution = 10.0 ** -decimals * (1.0 if from_pos_lat else math.sqrt(2.0))
        warnings.warn(f"{self.path}: positions are written with {decimals} decimals: a car's lateral movement of up to "
                      f"{resolution:.3g} m in a step (its rounding) is read as none and accelerations from speed "
                      f"differences are rounded too; write the FCD with sumo --precision {FINE_DECIMALS} (or with "
                      "speedLat and acceleration) for exact values", stacklevel=3)
        return resolution

    def _warn_lane_jumps(self, ids: np.ndarray, lat_moved: np.ndarray, jumped: np.ndarray, dt: float,
                         time: float) -> None:
        """Warn once per file when cars (``jumped``) moved sideways faster than any car can (``JUMP_SPEED``): SUMO
        changed their lanes in one step (their lateral speed there is taken as 0, as SUMO's own ``speedLat``)."""
        if not self._warned_jump:
            self._warned_jump = True
            k = int(np.flatnonzero(jumped)[0])
            warnings.warn(f"{self.path}: {cut(str(ids[k]))} moves {abs(lat_moved[k]):.2f} m sideways onto another "
                          f"lane in one {dt:g} s step at "
                          f"{time:g} s: its lane changes are instantaneous (SUMO without --lanechange.duration or "
                          "--lateral-resolution); at such steps the lateral speed is taken as 0, as SUMO reports it",
                          stacklevel=3)

    def _type_rows(self, step: FcdStep, ids: np.ndarray) -> np.ndarray:
        """Each vehicle's row of ``_type_table`` (by its vType; without 'type' in the FCD, the route files'
        vehicles and flows tell it; rows added for vTypes not seen before: their sizes, or SUMO's passenger size
        for a vType not defined, with a warning)."""
        rows = step.numbered("type", self._types) if step.has("type") else None
        if rows is None or self._types.number.get("", -1) in rows:
            types = step.column("type")
            rows = self._types.of(tuple(t or self.vehicles.type_of(v) or "DEFAULT_VEHTYPE"
                                        for t, v in zip(types, ids.tolist())))
        if len(self._types) > len(self._type_table):
            new = self._types.added_since(len(self._type_table))
            unknown = set(new) - self.vehicles.sizes.keys() - {""}  # "": a step's empty 'type', replaced above
            if unknown:
                warnings.warn(f"{self.path}: vType {listed(sorted(unknown))} is not defined (give its route or vType "
                              f"file); audited at SUMO's passenger size {SUMO_DEFAULT_SIZE[0]:g} m x "
                              f"{SUMO_DEFAULT_SIZE[1]:g} m", stacklevel=3)
            self._type_table = np.vstack([self._type_table, [(*self.vehicles.sizes.get(t, SUMO_DEFAULT_SIZE),
                                                              float(t in self.vehicles.bicycles)) for t in new]])
        return rows

    def _routes_of(self, numbers: np.ndarray) -> np.ndarray:
        """The route of each vehicle (by its number; ``()`` for a vehicle without one), each vehicle's the same
        tuple at every step."""
        if len(self._ids) > len(self._routes):
            new = self._ids.added_since(len(self._routes))
            routes = np.empty(len(new), dtype=object)
            for k, vehicle in enumerate(new):
                routes[k] = self.vehicles.route_of(vehicle) or ()
            self._routes = np.concatenate([self._routes, routes])
        return self._routes[numbers]

    @functools.cached_property
    def _walkways(self) -> np.ndarray:
        return pedestrian_lanes(self.network)

    def _time_of(self, step: FcdStep) -> float:
        """A time step's ``time`` [s]; FcdError naming the step before where it is not a number."""
        value = step.time
        try:
            time = float(value) if value is not None else math.nan
        except ValueError:
            time = math.nan
        if not math.isfinite(time):
            after = f"after time step {self._prev_time} s" if self._prev_time is not None else "first time step"
            raise FcdError(f"{self.path}: <timestep> ({after}): time: expected a number of seconds, got {shown(value)}")
        return time

    def _snapshot(self, step: FcdStep, time: float) -> WorldSnapshot:
        if self._prev_time is not None and not time > self._prev_time:
            what = "is repeated" if time == self._prev_time else f"comes after {self._prev_time} s"
            raise FcdError(f"{self.path}: time step {time} s {what}: time: expected a time after the step before's "
                           "(SUMO writes every step once, in time order; docs/outputs.md)")
        where = f"{self.path}, time step {time} s"
        self.people.update(step.unaudited)
        if step.unaudited and not self._warned_containers:
            self._warned_containers = True
            warnings.warn(f"{where}: containers are not audited (the RSS model covers vehicles and persons; a "
                          "collision with one is listed with blamed 'none')", stacklevel=3)
        try:
            persons = person_snapshot(step.persons, self.vehicles.sizes, where) if step.persons else None
        except ValueError as exc:
            raise FcdError(str(exc)) from None
        if persons is not None:
            check_person_edges(where, persons, self.network)
            self.people.update(persons.ids.tolist())
            self._walkers.update(persons.ids.tolist())
        if len(step) and not (step.has("id") and step.has("lane")):
            vid, name = next((r.get("id", "?"), name) for r in step.rows() for name in ("id", "lane") if name not in r)
            raise FcdError(f"{where}: vehicle {shown(vid)} lacks the attribute {name!r} ({NEEDED_ATTRIBUTES})")
        known = len(self._ids)
        number, lane = step.numbered("id", self._ids), step.numbered("lane", self._lanes)
        ids, lane_id = self._ids.names(number), self._lanes.names(lane)
        for name, table, numbers in (("id", self._ids, number), ("lane", self._lanes, lane)):
            if table.number.get("", -1) in numbers:
                k = int(np.argmax(numbers == table.number[""]))
                raise FcdError(f"{where}: vehicle {shown(str(ids[k]) or '?')} (vehicle {k + 1} of the step): {name}: "
                               f"expected SUMO's {'vehicle' if name == 'id' else 'lane'} id, got ''")
        _check_listed_once(where, number, ids)
        x, y, angle, speed = (_numbers(step, name, where) for name in ("x", "y", "angle", "speed"))
        if np.any(lane >= len(self.network.lane_ids)):
            missing = sorted(set(lane_id[lane >= len(self.network.lane_ids)].tolist()))
            raise FcdError(f"{where}: lanes not in {self.network.path.name}: {listed(missing)}; is --net the network "
                           "of this run?")
        if not self._warned_walkway:
            self._warned_walkway = warn_on_walkways(where, ids, lane, self.network, self._walkways)
        kind = self._type_rows(step, ids)
        vtype = self._types.names(kind)
        length, width, bicycle = (self._type_table[kind, c] for c in range(3))
        heading = compass_deg_to_heading(angle)

        def optional(name: str) -> np.ndarray | None:
            return _numbers(step, name, where) if step.has(name) else None

        lane_pos, lat_pos = optional("pos"), optional("posLat")
        accel, lat_speed = optional("acceleration"), optional("speedLat")
        signals = _numbers(step, "signals", where, integer=SIGNALS_FORM, default="0")

        @functools.cache  # made once, after check_step has checked the values they need (inside it or after it)
        def projections() -> tuple[tuple | None, tuple[np.ndarray, np.ndarray, np.ndarray]]:
            return self._projections(lane, x, y, heading, length, lane_pos is None or lat_pos is None,
                                     lat_speed is None)

        check_step(where, time, self._prev_time, StepValues(ids, lane, x, y, angle, speed, lane_pos, lat_pos, accel,
                                                            lat_speed, signals), self.network,
                   (lambda: np.abs(projections()[0][1])) if lane_pos is None or lat_pos is None else None)
        if self._resolution is None and len(step) and not step.has("speedLat"):
            self._resolution = self._lateral_resolution(step.column("x"), lat_pos is not None)
        fronts, centres = projections()
        if fronts is not None:  # SUMO's pos and posLat are those of the front-bumper centre
            s_f, d_f, _ = fronts
            # SUMO measures pos along the lane's own length (with elevation), not its 2-D shape's.
            lane_pos = self.network.shapes.lane_pos(lane, s_f) if lane_pos is None else lane_pos
            lat_pos = d_f if lat_pos is None else lat_pos
        edge = self.network.lane_edge[lane]
        edge_lat = self.network.lane_offset[lane] + lat_pos
        dt = time - self._prev_time if self._prev_time is not None else None
        if dt is not None:
            self._check_step(dt, time)
        check_distinct_ids(where, ids[number >= known], self._walkers, persons, self._ids.number)
        seen, prev = self._prev.of(number, len(self._ids))
        prev_speed, prev_edge, prev_lane, prev_lat_pos, prev_edge_lat, prev_lat_speed = prev.T
        same_edge = seen & (prev_edge == edge)
        lat_moved = np.where(same_edge, edge_lat - prev_edge_lat, 0.0)  # [m]
        # A car that moves sideways faster than any car can, or from one lane's centre line to another's, changed
        # its lane in one step (SUMO's default; at a 1 s step a lane width is only 3.5 m/s).
        centred = same_edge & (np.abs(lat_pos) <= CENTRED) & (np.abs(prev_lat_pos) <= CENTRED)
        jumped = (np.abs(lat_moved) > JUMP_SPEED * dt) | (centred & (prev_lane != lane)) if dt else \
            np.zeros(len(ids), bool)
        if (jumped & (prev_lane != lane)).any():  # a jump within a lane (SUMO's own, on one lane) is no lane change
            self._warn_lane_jumps(ids, lat_moved, jumped & (prev_lane != lane), dt, time)
        accel_resolution = 0.0
        if accel is None:
            accel = np.where(seen, (speed - prev_speed) / dt, 0.0) if dt else np.zeros(len(ids))
            # Two speeds each rounded to the file's decimals: the difference is off by up to 10^-N m/s.
            if self._speed_decimals is None and len(step):
                self._speed_decimals = max(_decimals(v) for v in step.column("speed")[:100])
            decimals = FINE_DECIMALS if self._speed_decimals is None else self._speed_decimals
            accel_resolution = 10.0 ** -decimals / dt if dt and decimals < FINE_DECIMALS else 0.0
        if lat_speed is None:  # a lane changed in one step has no lateral speed: SUMO writes speedLat 0 for it
            # A movement within the positions' rounding is none; a car entering a new edge keeps its last speed.
            moved = np.where(np.abs(lat_moved) > (self._resolution or 0.0), lat_moved, 0.0)
            across = np.where(jumped, 0.0, np.where(same_edge | ~seen, moved / dt, prev_lat_speed)) if dt else \
                np.zeros(len(ids))
            # SUMO's speedLat is the car's own (+ = left of its travel); a car overtaking through the oncoming lane
            # has its posLat in that lane's frame, so its movement there is the other way round.
            lat_speed = np.where(self._against_lane(lane, heading, length, centres), -across, across)
        else:
            across = np.zeros(len(ids))  # not needed: SUMO wrote the lateral speeds
        self._prev.remember(number, np.column_stack([speed, edge, lane, lat_pos, edge_lat, across]))
        self._prev_time = time
        is_ego = (np.isin(ids, sorted(self.ego_ids)) if self.ego_ids else False) | (vtype == EGO_TYPE)
        routes = tuple(self._routes_of(number))
        return WorldSnapshot(
            time=time, ids=ids, x=x, y=y, heading=heading, speed=speed, accel=accel, lat_speed=lat_speed,
            length=length, width=width, lane_id=lane_id, edge_id=self.network.edge_ids[edge],
            lane_index=self.network.lane_index[lane], lane_pos=lane_pos, lat_pos=lat_pos,
            vclass=np.where(is_ego, EGO_CLASS, np.where(bicycle > 0.0, BICYCLE_CLASS, BACKGROUND_CLASS)), vtype=vtype,
            signals=signals,
            route_index=np.full(len(ids), -1, dtype=int), route_edges=routes if any(routes) else None,
            accel_resolution=accel_resolution, persons=persons)


def _numbers(step: FcdStep, name: str, where: str, *, integer: str = "", default: str | None = None
             ) -> np.ndarray:
    """Attribute ``name`` of every vehicle of a time step as finite floats (or, with ``integer``, the expected form
    of its integers, as integers), ``default`` where a vehicle lacks it (None: required); FcdError naming the
    vehicle and the value."""
    kind = int if integer else float
    exact = None if integer else step.numbers(name)
    if exact is not None:  # plain decimals: finite
        return exact
    column = step.column(name)
    if default is not None and column.count(None) == len(column):  # no vehicle has it (SUMO's signals by default)
        return np.full(len(column), kind(default))
    try:
        if default is not None and not step.has(name):
            column = tuple(default if v is None else v for v in column)
        values = np.fromiter(map(int, column), int, len(column)) if integer else np.array(column, dtype=float)
        if integer or np.isfinite(values).all():
            return values
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer beyond 64 bits
        pass
    rows = step.rows()
    bad = next(r for r in rows if not _is_number(r.get(name, default), kind))
    if bad.get(name, default) is None:
        raise FcdError(f"{where}: vehicle {shown(bad.get('id', '?'))} lacks the attribute {name!r} "
                       f"({NEEDED_ATTRIBUTES})")
    raise FcdError(f"{where}: vehicle {shown(bad.get('id', '?'))}: {name}: expected "
                   f"{integer or 'a finite number'}, got {shown(bad[name])}")


class _PreviousStep:
    """What the reader remembers of the cars of the step before, as ``_UNSEEN`` lists it, by the cars' numbers in
    the file (:class:`.fcd_names.NameTable`)."""

    def __init__(self) -> None:
        self.seen = np.zeros(0, dtype=bool)  # [numbers] whether the car was in the step before
        self.values = np.zeros((0, len(_UNSEEN)))  # [numbers, len(_UNSEEN)] its values then
        self.numbers = np.zeros(0, dtype=np.int64)  # of the cars of the step before

    def of(self, numbers: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
        """(whether each car was seen the step before, its values then or ``_UNSEEN``); ``count``: the numbers
        given so far."""
        if count > len(self.seen):  # room for twice the numbers so far
            grown = max(2 * count, 64)
            self.seen = np.concatenate([self.seen, np.zeros(grown - len(self.seen), dtype=bool)])
            self.values = np.concatenate([self.values, np.zeros((grown - len(self.values), len(_UNSEEN)))])
        seen = self.seen[numbers]
        return seen, np.where(seen[:, None], self.values[numbers], np.array(_UNSEEN, dtype=float))

    def remember(self, numbers: np.ndarray, values: np.ndarray) -> None:
        """Keep ``values`` ([n, len(_UNSEEN)]) of the cars ``numbers`` for the next step."""
        self.seen[self.numbers] = False
        self.seen[numbers] = True
        self.values[numbers] = values
        self.numbers = numbers


def _check_listed_once(where: str, numbers: np.ndarray, ids: np.ndarray) -> None:
    """FcdError naming the first vehicle listed twice in a step (``numbers``: of its ``ids``)."""
    place = np.empty(int(numbers.max(initial=-1)) + 1, dtype=np.int64)
    rows = np.arange(len(numbers))
    place[numbers] = rows  # each number's place: a row of it, the only one where no number is repeated
    if (place[numbers] != rows).any():
        twice = next(v for v, count in Counter(ids.tolist()).items() if count > 1)
        raise FcdError(f"{where}: vehicle {shown(twice)} is listed more than once")


def _decimals(text: str) -> int:
    """Digits after the decimal point of a number as written (FINE_DECIMALS for an exponent form)."""
    if "e" in text or "E" in text:
        return FINE_DECIMALS
    return len(text) - text.index(".") - 1 if "." in text else 0


def _is_number(text: str | None, kind: type) -> bool:
    try:
        return text is not None and math.isfinite(kind(text)) and (kind is float or abs(kind(text)) < 2**63)
    except ValueError:
        return False
