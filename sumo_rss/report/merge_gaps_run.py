"""The earliest RSS-legal merge of a finished run's ego (:mod:`.merge_gaps`) against the merge it made
(``sumo-rss merge-gaps``, :mod:`.merge_gaps_command`), read from the run folder (``ego_trace.csv``, ``fcd.xml`` of
``sumo-rss run --fcd``, ``rss_params.json``, ``scenario.toml``), and how much the motorway's cars reacted to the
ego. Units: s, m, m/s, m/s².
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SumoRssError
from ..road.network import RoadNetwork
from ..rss.params import PARAM_NAMES, RssParamArrays, RssParams
from ..scenario import EGO_TYPE, ScenarioSpec, load_scenario
from .ego_metrics import merge_span, run_rss_params
from .merge_gaps import EarliestMerge, EgoLimits, GapSearch, TargetLane, earliest_merge

CHAIN_REACH = 400.0  # [m] target-lane cars this far before the acceleration lane's start or beyond its end are kept
REACTION_RANGE = 100.0  # [m] a car reacts to the ego if the ego is the nearest thing ahead of it within this gap
REACTION_SLACK = 0.1  # [m/s²] braking beyond sigma·accel (Krauss's dawdling) by more than this is a reaction
SLACK_REACTION = 1.0  # [s] of the verdict's slack on top of the change time (the planner's reaction)


@dataclass(frozen=True)
class MergeGapReport:
    """One run: ``entered_s`` the ego's first step on the acceleration lane, ``earliest`` the earliest legal merge,
    ``completed_s`` its first step on another lane (inf: never); ``reacting_cars`` motorway cars that braked for
    it (beyond dawdling) or left the target lane with it ahead, ``hardest_reaction`` their hardest braking [m/s²],
    ``gap_reacted`` whether the cars just ahead of and behind the earliest legal merge had reacted by its start
    (its gap is then partly the ego's doing, and might not have been there for an ego elsewhere); ``same_gap``
    whether the ego completed its merge behind the same car (:func:`_same_gap`: it merged into the first legal
    gap, later and further along)."""

    run: str
    entered_s: float
    earliest: EarliestMerge
    completed_s: float
    reacting_cars: int
    hardest_reaction: float
    gap_reacted: bool
    same_gap: bool

    def missed_s(self) -> float:
        """[s] actual completion minus the earliest legal start (inf: no legal start within the record)."""
        start = self.earliest.start_s
        return self.completed_s - start if start is not None else -math.inf

    def explained(self, change_s: float) -> bool:
        """No legal merge started more than ``change_s`` + SLACK_REACTION before the actual completion."""
        return self.missed_s() <= change_s + SLACK_REACTION


def target_chain(network: RoadNetwork, lane: int) -> dict[int, float]:
    """Where each lane of the target lane's chain starts [m] (the target lane, left of ``lane``, at 0; its unique
    predecessors back and successors on, each until CHAIN_REACH beyond)."""
    target = int(network.lane_left[lane])
    if target < 0:
        raise SumoRssError(f"lane {network.lane_ids[lane]} has no lane to its left to merge into")
    predecessors = {k: [j for j, nexts in enumerate(network.lane_successors) if k in nexts]
                    for k in range(len(network.lane_ids))}
    chain, at, k = {target: 0.0}, 0.0, target
    while len(predecessors[k]) == 1 and at > -CHAIN_REACH:
        k = predecessors[k][0]
        at -= float(network.lane_length[k])
        chain[k] = at
    at, k = float(network.lane_length[target]), target
    while len(network.lane_successors[k]) == 1 and at < float(network.lane_length[target]) + CHAIN_REACH:
        k = network.lane_successors[k][0]
        chain[k] = at
        at += float(network.lane_length[k])
    return chain


def merge_gap_report(run_dir: Path, search: GapSearch = GapSearch()) -> MergeGapReport:
    """The earliest legal merge of the run in ``run_dir`` against its actual one."""
    run_dir = Path(run_dir)
    for name in ("ego_trace.csv", "fcd.xml", "rss_params.json", "scenario.toml"):
        if not (run_dir / name).is_file():
            raise SumoRssError(f"{run_dir}: no {name} (a run of 'sumo-rss run --fcd' with an ego)")
    spec = load_scenario(run_dir / "scenario.toml")
    network = RoadNetwork.from_file(spec.net_file)
    trace = pd.read_csv(run_dir / "ego_trace.csv", keep_default_na=False)
    t, lanes = trace["time_s"].to_numpy(float), trace["lane_id"].to_numpy(str)
    span = merge_span(lanes, network)
    if span is None:
        raise SumoRssError(f"{run_dir}: the ego was never on a lane that ends")
    first, left = span
    acc = int(network.lane_indices(lanes[first:first + 1])[0])
    chain = target_chain(network, acc)
    target = int(network.lane_left[acc])
    scale = float(network.lane_length[target] / network.lane_length[acc])
    ego_front = trace["lane_pos_m"].to_numpy(float)[first] * scale
    rss = run_rss_params(run_dir)
    lane, ids, reaction = _read_target_lane(run_dir / "fcd.xml", network, chain, spec, rss, (trace, acc, scale))
    ego_params = rss[f"ego/{EGO_TYPE}"]
    limits = EgoLimits.planner(float(network.lane_speed[acc]))
    earliest = earliest_merge(lane, float(t[first]), ego_front, float(trace["speed_ms"].to_numpy(float)[first]),
                              spec.ego.vehicle.length, ego_params, limits, search)
    completed = float(t[left]) if left is not None else math.inf
    cars, hardest = reaction.count(float(t[first]), completed)
    gap = _gap_cars(lane, ids, earliest.start_s, earliest.front_m) if earliest.start_s is not None else (None, None)
    reacted = any(car in gap and time <= earliest.start_s for time, car, _ in reaction.events)
    merged = network.lane_indices(lanes[left:left + 1])[0] if left is not None else -1
    taken = _gap_cars(lane, ids, completed, chain[merged] + float(trace["lane_pos_m"].iloc[left])) \
        if merged in chain else (None, None)
    return MergeGapReport(f"{run_dir.parent.name}/{run_dir.name}", float(t[first]), earliest, completed, cars,
                          hardest, reacted, _same_gap(gap, taken))


def _same_gap(gap: tuple[str | None, str | None], taken: tuple[str | None, str | None]) -> bool:
    """Whether two (car ahead, car behind) pairs bound the same gap: the same car ahead (a car may have merged in
    behind it meanwhile), or none ahead and the same car behind."""
    if gap[0] is not None or taken[0] is not None:
        return gap[0] == taken[0]
    return gap[1] is not None and gap[1] == taken[1]


def _gap_cars(lane: TargetLane, ids: list[list[str]], time: float, front: float) -> tuple[str | None, str | None]:
    """The ids of the target-lane cars nearest ahead of and behind front bumper ``front`` [m] at ``time`` [s]
    (None: none)."""
    i = int(np.argmin(np.abs(lane.times - time)))
    fronts = lane.front[i, :len(ids[i])]
    return tuple(ids[i][int(np.flatnonzero(side)[np.argmin(np.abs(fronts[side] - front))])] if side.any() else None
                 for side in (fronts > front, fronts <= front))


@dataclass
class _Reactions:
    """Per car id: the times it braked for the ego (beyond dawdling) or left the target lane with the ego ahead."""

    events: list[tuple[float, str, float]]  # (time, car id, its acceleration)

    def count(self, begin: float, end: float) -> tuple[int, float]:
        inside = [(car, a) for time, car, a in self.events if begin <= time <= end]
        return len({car for car, _ in inside}), min((a for _, a in inside), default=0.0)


def _read_target_lane(fcd: Path, network: RoadNetwork, chain: dict[int, float], spec: ScenarioSpec, rss: dict[str, RssParams],
                      ego: tuple[pd.DataFrame, int, float]) -> tuple[TargetLane, list[list[str]], _Reactions]:
    """The target lane's cars per FCD step, their ids per step (in the slots' order) and their reactions to the ego
    while it is on the acceleration lane; ``ego`` = (its trace, the lane, the target lane's length over the
    lane's)."""
    trace, acc, scale = ego
    ego_lane = dict(zip(np.round(trace["time_s"].to_numpy(float), 3), zip(trace["lane_id"], trace["lane_pos_m"])))
    vtypes = {v.id: v for v in spec.demand.vtypes}
    lane_of = {network.lane_ids[k]: k for k in chain}
    end = float(network.lane_length[int(network.lane_left[acc])])
    times, rows, events, previous = [], [], [], {}
    for _, elem in ET.iterparse(fcd, events=("end",)):
        if elem.tag != "timestep":
            continue
        time = round(float(elem.get("time")), 3)
        step = []  # (front, speed, type, id, accel)
        for v in elem.iter("vehicle"):
            k = lane_of.get(v.get("lane"))
            if k is not None and v.get("id") != spec.ego.id:
                front = chain[k] + float(v.get("pos"))
                if -CHAIN_REACH <= front <= end + CHAIN_REACH:
                    step.append((front, float(v.get("speed")), v.get("type"), v.get("id"),
                                 float(v.get("acceleration", 0.0))))
        elem.clear()
        times.append(time)
        rows.append(step)
        at = ego_lane.get(time)
        if at is not None and network.lane_indices([at[0]])[0] == acc:
            events += _reactions(time, step, float(at[1]) * scale,
                                 spec.ego.vehicle.length, vtypes, previous)
        previous = {car[3]: car for car in step}
    width = max((len(r) for r in rows), default=0) or 1
    front = np.full((len(rows), width), np.nan)
    speed, length = np.zeros_like(front), np.zeros_like(front)
    table = {name: np.full_like(front, getattr(RssParams(), name)) for name in PARAM_NAMES}  # empty: any valid row
    for i, step in enumerate(rows):
        for j, (f, v, vtype, _, _) in enumerate(step):
            front[i, j], speed[i, j], length[i, j] = f, v, vtypes[vtype].length
            for name in PARAM_NAMES:
                table[name][i, j] = getattr(rss[f"background/{vtype}"], name)
    params = RssParamArrays(*(table[name] for name in PARAM_NAMES))
    lane = TargetLane(np.array(times), front, speed, length, params, end)
    return lane, [[car[3] for car in step] for step in rows], _Reactions(events)


def _reactions(time: float, step: list, ego_front: float, ego_length: float, vtypes: dict,
               previous: dict) -> list[tuple[float, str, float]]:
    """The step's cars that braked beyond dawdling with the ego the nearest ahead within REACTION_RANGE, and those
    of the previous step that left the target lane then."""
    out = []
    rears = sorted(f - vtypes[vt].length for f, _, vt, _, _ in step)
    here = {car[3] for car in step}
    for f, _, vt, car, a in step + [c for c in previous.values() if c[3] not in here]:
        gap = ego_front - ego_length - f
        nearest = 0.0 <= gap <= REACTION_RANGE and not any(f < r < ego_front - ego_length for r in rears)
        dawdle = vtypes[vt].sigma * vtypes[vt].accel + REACTION_SLACK
        if nearest and (car not in here or a < -dawdle):
            out.append((time, car, a if car in here else 0.0))
    return out
