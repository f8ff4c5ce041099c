"""A scenario's routes and departures checked against its network: edges that exist and follow one another
through lanes the vehicle's class may use, departure lanes and speeds that SUMO accepts (SUMO stops a run, or
refuses to start it, otherwise)."""
from __future__ import annotations

from .road.topology import EdgeInfo, NetTopology
from .validation import TableReader

DEPART_LANES = ("best", "random", "free", "allowed", "first")


def read_route(t: TableReader, topology: NetTopology) -> tuple[str, ...]:
    """The table's ``route``: edges of the network, each following the one before (for some vehicle class)."""
    route = t.string_list("route")
    for i, edge in enumerate(route):
        if edge not in topology.edges:
            raise t.error(f"route[{i}]", "expected an edge of the network", edge)
        if i and not topology.connected(route[i - 1], edge):
            raise t.error(f"route[{i}]", f"expected an edge reachable from {route[i - 1]!r}", edge)
    return route


def check_route_permits(t: TableReader, route: tuple[str, ...], vclass: str, who: str, topology: NetTopology,
                        depart_lane: str) -> None:
    """SUMO stops the run at a vehicle whose route (or departure lane) its vClass may not use: refused here."""
    what = f"{who} (vClass {vclass!r})"
    lanes = topology.permitted_lanes(route[0], vclass)
    if not lanes:
        raise t.error("route[0]", f"expected an edge with a lane that {what} may use", route[0])
    if depart_lane.isdigit() and int(depart_lane) not in lanes:
        raise t.error("depart_lane", f"expected a lane of {route[0]!r} that {what} may use: "
                                     f"{', '.join(map(str, lanes))}", int(depart_lane))
    for i in range(1, len(route)):
        if not topology.connected(route[i - 1], route[i], vclass):
            raise t.error(f"route[{i}]", f"expected an edge that {what} may reach from {route[i - 1]!r} (no "
                                         "connection between lanes that permit it)", route[i])


def read_depart_lane(t: TableReader, first_edge: str, topology: NetTopology) -> str:
    value = t.raw("depart_lane", "best")
    lanes = topology.edges[first_edge].num_lanes
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < lanes:
        return str(value)
    if isinstance(value, str) and value in DEPART_LANES:
        return value
    raise t.error("depart_lane", f"expected a lane index 0..{lanes - 1} of {first_edge!r} or one of "
                                 f"{', '.join(repr(v) for v in DEPART_LANES)}", value)


def check_depart_speed(t: TableReader, speed: float, edge: EdgeInfo, top_speed: float, what: str,
                       speed_factor: float) -> None:
    """SUMO stops the run when a car departs faster than its vType's maxSpeed (``top_speed``, described by
    ``what``) or than its own speed limit on the lane, ``speed_factor`` x the lane's (a car's drawn factor: with a
    speed_dev, SUMO redraws the factors of the cars it would stop for, biasing them upwards)."""
    if speed > top_speed:
        raise t.error("depart_speed", f"expected at most {top_speed:g} m/s, {what} (SUMO refuses a faster "
                                      "departure)", speed)
    limit = speed_factor * edge.speed
    if speed > limit + 1e-9:
        raise t.error("depart_speed", f"expected at most {limit:g} m/s, speed_factor {speed_factor:g} x the speed "
                                      f"limit of {edge.id!r} (SUMO refuses a faster departure)", speed)
