"""How an ego drove in one run, read from its run directory, the same way for every controller (sumo,
sumo_restricted, epsilon, mpdm): route travel time, mean speed (whole run and settled), responsibility, lane
changes, the delay of a merge from a lane that ends, and its speed in free flow (from the run's FCD).
Units: s, m, m/s.
"""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..road.network import RoadNetwork
from ..rss.auditor import PARAMS_FILE
from ..rss.formulas import lon_safe_distance_same_dir
from ..rss.params import PARAM_NAMES, RssParams
from ..scenario import EGO_TYPE, ScenarioSpec, VehicleTypeSpec, load_scenario

SETTLED_S = 20.0  # [s] the settled mean speed starts this long after the ego's insertion
LEADER_RANGE = 150.0  # [m] free flow: no car ahead in the ego's lane this near (bumper to bumper) ...
COMFORT_BRAKE = 1.67  # [m/s²] ... nor a slower one within RSS reach (docstring); no lane end or lower speed limit
# within v²/(2·this) ahead
BLINKER_RIGHT, BLINKER_LEFT = 1, 2  # SUMO's signal bits (the FCD's ``signals``)
FREE_SPEED_SHARE = 0.99  # in free flow the ego holds this share of min(desired speed, speed limit)
STEADY_ACCEL = -0.05  # [m/s²] before it first gets there in a free stretch, it may not slow down more than this


@dataclass(frozen=True)
class EgoRunMetrics:
    """One run's ego. ``travel_time_s``: insertion to arrival at its route's end (None: it did not arrive);
    ``merge_delay_s``: from its front bumper's first step on a lane that ends (an acceleration lane) to its first
    step on another lane (None: never on such a lane; inf: it never left it)."""

    depart_s: float
    travel_time_s: float | None
    mean_speed_ms: float
    settled_mean_speed_ms: float | None
    responsible_episodes: int
    responsible_s: float
    collisions: int
    lane_changes: int
    merge_delay_s: float | None

    def as_dict(self) -> dict:
        return asdict(self)


def _trace(run_dir: Path) -> pd.DataFrame:
    return pd.read_csv(run_dir / "ego_trace.csv", keep_default_na=False)


def run_rss_params(run_dir: Path) -> dict[str, RssParams]:
    """The RSS parameters a run was judged with (its rss_params.json), keyed 'class/vType' as there ('ego/ego_type',
    'background/car', ...)."""
    table = json.loads((Path(run_dir) / PARAMS_FILE).read_text(encoding="utf-8"))
    return {key: RssParams(**{name: row[name] for name in PARAM_NAMES}) for key, row in table.items()}


def ego_run_metrics(run_dir: Path, network: RoadNetwork | None = None) -> EgoRunMetrics:
    """The metrics of the ego of the run in ``run_dir`` (``network``: the run's, loaded if not given)."""
    run_dir = Path(run_dir)
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    spec = load_scenario(run_dir / "scenario.toml")
    network = network if network is not None else RoadNetwork.from_file(spec.net_file)
    trace = _trace(run_dir)
    t, v = trace["time_s"].to_numpy(float), trace["speed_ms"].to_numpy(float)
    ego = summary["ego_id"]
    episodes = pd.read_csv(run_dir / "episodes.csv", keep_default_na=False)
    who = episodes["responsible"]
    blamed = ((episodes["vehicle_a"] == ego) & who.isin(["a", "both"])) | \
        ((episodes["vehicle_b"] == ego) & who.isin(["b", "both"]))
    settled = v[t >= t[0] + SETTLED_S]
    lanes = trace["lane_id"].to_numpy(str)
    edge = np.array([lane.rsplit("_", 1)[0] for lane in lanes])
    index = np.array([int(lane.rsplit("_", 1)[1]) for lane in lanes])
    changes = int(np.sum((edge[1:] == edge[:-1]) & (index[1:] != index[:-1])))
    return EgoRunMetrics(
        depart_s=float(t[0]), travel_time_s=_travel_time(t, edge, spec, summary["sim_time_s"]),
        mean_speed_ms=float(v.mean()), settled_mean_speed_ms=float(settled.mean()) if settled.size else None,
        responsible_episodes=int(blamed.sum()), responsible_s=float(episodes["duration_s"][blamed].sum()),
        collisions=sum(ego in (c["collider"], c["victim"]) for c in summary["collision_events"]),
        lane_changes=changes, merge_delay_s=_merge_delay(t, lanes, network))


def _travel_time(t: np.ndarray, edge: np.ndarray, spec: ScenarioSpec, sim_time: float) -> float | None:
    """[s] from the first trace row to the arrival (the step after the last row), if the ego arrived: its trace
    ends before the run does, on its route's last edge."""
    step = spec.step_s
    arrived = t[-1] + step < sim_time - 1e-6 and edge[-1] == spec.ego.route[-1]
    return float(t[-1] + step - t[0]) if arrived else None


def _merge_delay(t: np.ndarray, lanes: np.ndarray, network: RoadNetwork) -> float | None:
    span = merge_span(lanes, network)
    if span is None:
        return None
    first, left = span
    return float(t[left] - t[first]) if left is not None else float("inf")


def merge_span(lanes: np.ndarray, network: RoadNetwork) -> tuple[int, int | None] | None:
    """(the trace row of the ego's first step on a lane that ends, its first row on another lane after it, None if
    it never left it), or None if it was never on such a lane; ``lanes``: the trace's lane ids."""
    ending = network.lane_ends[network.lane_indices(lanes)]
    if not ending.any():
        return None
    first = int(np.argmax(ending))
    left = np.flatnonzero(lanes[first:] != lanes[first])
    return first, (first + int(left[0])) if left.size else None


def free_flow_shortfalls(run_dir: Path, network: RoadNetwork | None = None) -> list[tuple[float, float, float]]:
    """The steps of a run (with FCD) in which the ego was in free flow and did not hold its speed: (time [s], speed,
    target [m/s]). Free flow: no leader, and no lane end or lower speed limit on its lane within its comfortable
    stopping distance v²/(2·COMFORT_BRAKE). Target: min(desired speed, the lane's speed limit). A leader is a car
    whose rear is ahead of the ego's front bumper in its lane along its route (bumper to bumper gap g ≥ 0) with
    g < LEADER_RANGE, or, if slower than u = max(v, target), with g < RSS's safe distance d_min(u, v_lead) +
    (u − v_lead)²/(2·COMFORT_BRAKE) (the distance from which an ego at u braking comfortably just arrives at the
    car's speed at the safe distance: at 33 m/s behind a 27 m/s car 156 + 11 m, more than LEADER_RANGE; read at u,
    not v, so that an ego that has begun to slow for the car still has it as its leader); or a car in a
    neighbouring lane, beside or ahead within LEADER_RANGE, signalling towards the ego's lane (a cut-in). In each stretch of
    free-flow steps the ego must not slow down (beyond STEADY_ACCEL) until it first reaches FREE_SPEED_SHARE of
    the target, and must stay there from then on. For networks whose junctions have no conflicting links
    (highways): a junction ahead is not looked for."""
    run_dir = Path(run_dir)
    spec = load_scenario(run_dir / "scenario.toml")
    network = network if network is not None else RoadNetwork.from_file(spec.net_file)
    offsets = _route_offsets(network, spec.ego.route)
    types = {vt.id: vt for vt in spec.demand.vtypes}
    params = run_rss_params(run_dir)
    ego_params = params[f"ego/{EGO_TYPE}"]
    rows = []  # (time, speed, target, free)
    for time, ego, others in _fcd_steps(run_dir / "fcd.xml", spec.ego.id):
        lane = int(network.lane_indices([ego["lane"]])[0])
        at = _route_position(network, offsets, lane, float(ego["pos"]))
        speed = float(ego["speed"])
        target = min(spec.ego.desired_speed, float(network.lane_speed[lane]))
        led = any(_leads(network, offsets, types, params, (ego_params, spec.ego.vehicle.length), lane, at,
                         max(speed, target), o) for o in others)
        reach = speed * speed / (2.0 * COMFORT_BRAKE)
        free = not led and _clear_ahead(network, lane, float(ego["pos"]), reach, target, spec.ego.route)
        rows.append((time, speed, target, free))
    return _shortfalls(rows)


def _leads(network: RoadNetwork, offsets: dict[int, float], types: dict[str, VehicleTypeSpec],
           params: dict[str, RssParams], ego: tuple[RssParams, float], lane: int, at: float, speed: float,
           other: dict) -> bool:
    """Whether ``other`` (an FCD vehicle) is a leader of an ego (its RSS parameters and length [m]) at ``speed``
    [m/s] whose front bumper is ``at`` m along its route on ``lane`` (:func:`free_flow_shortfalls`; ``params``:
    :func:`run_rss_params`)."""
    ego_params, ego_length = ego
    vtype = types[other["type"]]
    k = int(network.lane_indices([other["lane"]])[0])
    gap = _route_position(network, offsets, k, float(other["pos"])) - vtype.length - at
    side = int(network.lane_index[k]) - int(network.lane_index[lane])
    if side == 0:
        v_lead = float(other["speed"])
        if v_lead >= speed:
            return 0.0 <= gap < LEADER_RANGE
        d_min = float(lon_safe_distance_same_dir(speed, v_lead, ego_params, params[f"background/{vtype.id}"]))
        return 0.0 <= gap < max(LEADER_RANGE, d_min + (speed - v_lead) ** 2 / (2.0 * COMFORT_BRAKE))
    towards = BLINKER_RIGHT if side == 1 else BLINKER_LEFT if side == -1 else 0
    beside_or_ahead = -ego_length < gap + vtype.length and gap < LEADER_RANGE
    return bool(int(other.get("signals", "0")) & towards) and beside_or_ahead


def _shortfalls(rows: list[tuple[float, float, float, bool]]) -> list[tuple[float, float, float]]:
    out, reached, previous = [], False, None
    for time, speed, target, free in rows:
        if not free:
            reached, previous = False, None
            continue
        reached = reached or speed >= FREE_SPEED_SHARE * target
        slowing = previous is not None and speed - previous < STEADY_ACCEL * 0.1
        if (reached and speed < FREE_SPEED_SHARE * target) or (not reached and slowing):
            out.append((time, speed, target))
        previous = speed
    return out


def _fcd_steps(path: Path, ego_id: str) -> Iterator[tuple[float, dict, list[dict]]]:
    """(time, the ego's attributes, the others') per FCD timestep in which the ego is on a lane."""
    for _, elem in ET.iterparse(path, events=("end",)):
        if elem.tag != "timestep":
            continue
        vehicles = [v.attrib for v in elem.findall("vehicle") if v.get("lane")]
        ego = next((v for v in vehicles if v["id"] == ego_id), None)
        if ego is not None:
            yield float(elem.get("time")), ego, [v for v in vehicles if v["id"] != ego_id]
        elem.clear()


def _route_offsets(network: RoadNetwork, route: tuple[str, ...]) -> dict[int, float]:
    """[m] where each route edge starts along the route (its first lane's length summed before it)."""
    offsets, total = {}, 0.0
    for e in network.edge_indices(route):
        offsets[int(e)] = total
        total += float(network.lane_length[np.flatnonzero(network.lane_edge == e)[0]])
    return offsets


def _route_position(network: RoadNetwork, offsets: dict[int, float], lane: int, pos: float) -> float:
    """[m] along the route of a front bumper ``pos`` m along ``lane`` (a junction's lane: counted back from the
    start of the route edge it leads into; -inf off the route)."""
    edge = int(network.lane_edge[lane])
    if edge in offsets:
        return offsets[edge] + pos
    into = int(network.edge_exit[edge])
    return offsets[into] - float(network.lane_length[lane]) + pos if into in offsets else -np.inf


def _clear_ahead(network: RoadNetwork, lane: int, pos: float, reach: float, target: float,
                 route: tuple[str, ...]) -> bool:
    """No lane end and no speed limit below ``target`` within ``reach`` m ahead of ``pos`` on ``lane`` and its
    successors along the route. A lane that leaves the route (one the ego must change out of, as the through lanes
    beside an exit) ends there for the ego; at the route's last edge the ego arrives."""
    route_edges = [int(e) for e in network.edge_indices(route)]
    on_route = set(route_edges)
    left, current = network.lane_length[lane] - pos, lane
    while left < reach:
        if network.lane_ends[current]:
            return False
        nexts = [k for k in network.lane_successors[current]
                 if int(network.edge_exit[network.lane_edge[k]]) in on_route]
        if not nexts:
            return int(network.lane_edge[current]) == route_edges[-1]
        current = nexts[0]
        if network.lane_speed[current] < target - 1e-6:
            return False
        left += float(network.lane_length[current])
    return True


def passed(run_dir: Path, other_id: str, network: RoadNetwork | None = None) -> bool:
    """Whether the ego of a run (with FCD) was ahead of ``other_id`` along the ego's route (front bumpers) at the
    last step both were on the road, having been behind it before (it overtook it)."""
    run_dir = Path(run_dir)
    spec = load_scenario(run_dir / "scenario.toml")
    network = network if network is not None else RoadNetwork.from_file(spec.net_file)
    offsets = _route_offsets(network, spec.ego.route)
    ahead = []
    for _, ego, others in _fcd_steps(run_dir / "fcd.xml", spec.ego.id):
        other = next((o for o in others if o["id"] == other_id), None)
        if other is not None:
            where = [_route_position(network, offsets, int(network.lane_indices([v["lane"]])[0]), float(v["pos"]))
                     for v in (ego, other)]
            ahead.append(where[0] > where[1])
    return bool(ahead) and not ahead[0] and ahead[-1]
