"""Auditor: watches every vehicle pair of a run, step by step, and reports danger episodes, violations of the
proper response and blame (rss.md §3-§6).

``observe`` reads like the paper: per-vehicle frame → candidate pairs → situations → safety → responsibility.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..files import csv_writer, json_text, make_folder, write_file_set
from ..road.junctions import JunctionModel
from ..road.network import RoadNetwork
from ..road.routes import RouteTable
from ..sim.snapshot import EGO_CLASS, WorldSnapshot
from .episode_states import STATE_FILE, EpisodeStates, EpisodeStateTrace
from .evasive_track import Rule5Tracker
from .occlusion import OccluderEdges, OcclusionParams
from .occlusion_track import OcclusionTracker
from .params import BICYCLE, PERSON, EvasiveParams, RssParamArrays, RssParams, resolve_params
from .records import VIOLATION_COLUMNS
from .owed_responses import OwedResponses
from .responsibility import ResponsibilityTracker
from .step_input import AREA_KEY, EPS_ACCEL, AreaRules, StepInput
from .intersection import KIND_SIGNAL, intersection_situations
from .numbering import Numbering
from .person_situations import PersonAudit
from .signals import SignalRule
from .situations import PairSituations, evaluate, vehicle_frame

INTERSECTION_KEY = np.int64(1) << np.int64(62)  # marks a pair's intersection situation (its own episodes)

COLLISION_COLUMNS = ["run_id", "time_s", "collider", "victim", "sumo_type", "blamed", "episode_key",
                     "could_have_avoided"]


@dataclass(frozen=True)
class CollisionInput:
    """A collision at the current step, as SUMO reports it (a session's ``CollisionEvent`` has these fields too and
    may be passed as it is)."""

    time: float  # [s]
    collider: str
    victim: str
    kind: str


class ParamResolver:
    """RSS parameters per (vehicle class, vType), resolved once and cached (rss.md §1). With ``hold_standing``
    (CARLA's RSS sensor does this), a car standing still in a snapshot is not assumed to accelerate during its
    response time (a_acc = 0 in :meth:`arrays`): a car waiting at a red light 1 m before a junction is not counted
    as able to enter it within ρ."""

    def __init__(self, preset: str = "ad_rss", role_overrides: Mapping[str, Mapping[str, float]] | None = None,
                 vtype_overrides: Mapping[str, Mapping[str, float]] | None = None,
                 vtype_dynamics: Mapping[str, tuple[float, float]] | None = None, hold_standing: bool = False):
        self.preset = preset
        self.hold_standing = hold_standing
        self.role_overrides = dict(role_overrides or {})
        self.vtype_overrides = dict(vtype_overrides or {})
        self.vtype_dynamics = dict(vtype_dynamics or {})  # vType id → (tau [s], decel [m/s²])
        self._cache: dict[tuple[str, str], RssParams] = {}

    def get(self, vclass: str, vtype: str) -> RssParams:
        key = (vclass, vtype)
        if key not in self._cache:
            role = vclass if vclass in (EGO_CLASS, BICYCLE, PERSON) else "background"
            tau, decel = self.vtype_dynamics.get(vtype, (1.0, 4.5))
            self._cache[key] = resolve_params(self.preset, role, None if role == "ego" else vtype,
                                              role_overrides=self.role_overrides,
                                              vtype_overrides=self.vtype_overrides, tau=tau, decel=decel)
        return self._cache[key]

    def resolved(self) -> dict[str, dict[str, float]]:
        """Every parameter set used so far, keyed 'class/vType' (written next to the results); with
        ``hold_standing`` each set also says so (its a_acc is 0 whenever that car stands)."""
        held = {"hold_standing": True} if self.hold_standing else {}
        return {f"{c}/{t}": {**p.to_dict(), **held} for (c, t), p in sorted(self._cache.items())}

    def arrays(self, snapshot: WorldSnapshot, held: bool = True) -> RssParamArrays:
        """Every vehicle's parameters; ``held=False``: without ``hold_standing``'s a_acc = 0 for standing cars
        (:meth:`hold` gives them)."""
        table = self.of(snapshot.vclass, snapshot.vtype)
        return self.hold(table, snapshot.speed) if held else table

    def of(self, vclass: np.ndarray, vtype: np.ndarray) -> RssParamArrays:
        """The parameters of road users of classes ``vclass`` and vTypes ``vtype`` (one row each)."""
        keys = np.char.add(np.char.add(vclass.astype(str), "\x1f"), vtype.astype(str))
        unique, inverse = np.unique(keys, return_inverse=True)
        return RssParamArrays.stack([self.get(*k.split("\x1f", 1)) for k in unique]).take(inverse.reshape(-1))

    def hold(self, table: RssParamArrays, speed: np.ndarray) -> RssParamArrays:
        """``table`` (:meth:`arrays` or :meth:`of`, not held) with ``hold_standing`` applied, for road users at
        ``speed`` [m/s]."""
        return self.held_standing(table, speed) if self.hold_standing else table

    @staticmethod
    def held_standing(table: RssParamArrays, speed: np.ndarray) -> RssParamArrays:
        """``table`` with a_acc = 0 for the road users standing still (``speed`` [m/s] exactly 0): what junction
        situations always use (:mod:`.moving_off`), and every situation with ``hold_standing``."""
        return replace(table, lon_accel_max=np.where(speed == 0.0, 0.0, table.lon_accel_max))


PARAMS_FILE = "rss_params.json"  # the resolved RSS parameters next to the CSVs they judged
# AuditResult's files
OCCLUSION_FILE = "occlusion.csv"  # rule 4: the episodes whose cars could not see each other at some step
AUDIT_FILES = ("episodes.csv", "violations.csv", "collisions.csv", "pair_states.csv", STATE_FILE, PARAMS_FILE,
               OCCLUSION_FILE)


@dataclass
class AuditResult:
    episodes: pd.DataFrame
    violations: pd.DataFrame
    collisions: pd.DataFrame
    params: dict[str, dict[str, float]]
    pair_states: pd.DataFrame | None = None  # per step of the traced episodes (``Auditor(trace_class=...)``)
    episode_states: EpisodeStates | None = None  # per step of every episode (``Auditor(record_states=True)``)
    occlusion: pd.DataFrame | None = None  # rule 4's occlusion.csv (``Auditor(occlusion=...)`` enabled)
    occluded_pair_steps: int = 0  # rule 4: dangerous pair-steps whose cars could not see each other

    def file_names(self) -> tuple[str, ...]:
        """The files :meth:`to_csv` writes."""
        return tuple(name for name in AUDIT_FILES if (name != "pair_states.csv" or self.pair_states is not None)
                     and (name != STATE_FILE or self.episode_states is not None)
                     and (name != OCCLUSION_FILE or self.occlusion is not None))

    def to_csv(self, directory: str | Path, also: Mapping[str, Callable[[Path], None]] | None = None) -> None:
        """Write episodes.csv, violations.csv, collisions.csv (and pair_states.csv when traced, episode_states.npz
        when recorded), the parameters they were judged with, rss_params.json, and the files ``also`` names
        (file name → a function writing it to a path), as a set (:func:`~sumo_rss.files.write_file_set`: all of
        them or, when one cannot be written, none)."""
        directory = Path(directory)
        made = not directory.exists()
        make_folder(directory)
        frames = {"episodes.csv": self.episodes, "violations.csv": self.violations, "collisions.csv": self.collisions,
                  "pair_states.csv": self.pair_states, OCCLUSION_FILE: self.occlusion}
        writers = {directory / name: csv_writer(frames[name]) for name in self.file_names() if name in frames}
        if self.episode_states is not None:
            writers[directory / STATE_FILE] = self.episode_states.write
        params = json_text(self.params)
        writers[directory / PARAMS_FILE] = lambda path: path.write_text(params, encoding="utf-8")
        writers.update({directory / name: write for name, write in (also or {}).items()})
        try:
            write_file_set(writers)
        except BaseException:
            if made:  # nothing left behind: neither the files nor the folder made for them
                directory.rmdir()
            raise


def collision_blame(records: list[dict]) -> tuple[str, str]:
    """(blamed, episode_key) of a collision that closed the episode ``records`` of one pair: the cars responsible
    in any of them (';'-joined, 'none' if no car) and their episode keys (';'-joined, '' for none)."""
    blamed = []
    for record in records:
        for car, side in ((record["vehicle_a"], "a"), (record["vehicle_b"], "b")):
            if record["responsible"] in (side, "both") and car not in blamed:
                blamed.append(car)
    return ";".join(sorted(blamed)) or "none", ";".join(record["episode_key"] for record in records)


class Auditor:
    """RSS auditor of one run. Feed it every snapshot in time order, then call :meth:`finish`."""

    def __init__(self, network: RoadNetwork, params: ParamResolver | None = None, run_id: str = "",
                 trace_class: str | None = None, signal_rule: bool = True, raw_episodes: bool = False,
                 junction_brake_min: bool = False, record_states: bool = False, spool: Path | None = None,
                 evasive: EvasiveParams | None = None, occlusion: OcclusionParams | None = None,
                 heights: Mapping[str, float] | None = None, occluders: OccluderEdges | None = None):
        """``trace_class``: record gaps and safe distances at every step of each episode involving a car of
        this class (e.g. 'ego') in ``AuditResult.pair_states``. ``signal_rule``: report red-light entries and
        avoidable yellow-light entries as violations (docs/rss.md). ``raw_episodes``: an episode that re-opens
        within the pair's ρ of its end is a new one (default: it continues the previous one).
        ``junction_brake_min``: a car owing braking at a junction must brake at b_min after ρ until stopped
        however far before the conflict area it stops, as ad_rss reads the response (default: a car that never
        enters the area while the episode lasts complied). ``record_states``: record every episode's steps, with
        the owed responses' bounds, in ``AuditResult.episode_states`` (for the viewer); ``spool``: a folder they
        go to as they come (:mod:`sumo_rss.spool`) instead of memory, which must stay until the result is
        written. ``evasive``: rule 5's settings (docs/rss.md; off unless ``enabled``). ``occlusion``: rule 4's
        settings (off unless ``enabled``), with the vTypes' ``heights`` [m] (vType → height; see
        :meth:`set_heights`) and the static ``occluders`` (:func:`~sumo_rss.rss.occlusion.read_occluders`)."""
        self.network = network
        self.junctions = JunctionModel.from_file(network.path, network)
        self._area_ids = np.array(sorted(c.id for c in self.junctions.conflicts), dtype=str)  # area number: index
        self._persons = PersonAudit(network, self.junctions)  # the crossings' areas: numbers after these
        self._signal_rule = SignalRule(network, self.junctions, run_id) if signal_rule else None
        self.trace_class = trace_class
        self.record_states = record_states
        self._states = EpisodeStateTrace(trace_class, record_states, spool=spool) \
            if trace_class or record_states else None
        self.params = params or ParamResolver()
        self.run_id = run_id
        self.pair_steps = 0
        self._rule5 = Rule5Tracker(network, evasive)
        self._occlusion = OcclusionTracker(network, occlusion, heights, occluders)
        self._tracker = ResponsibilityTracker(run_id, join=not raw_episodes, stay_out_complies=not junction_brake_min,
                                              on_close=self._close_episode)
        self._uids = Numbering()  # every road user seen: its number in the pair keys
        self._routes = RouteTable(network)
        self._prev_uids = np.zeros(0, dtype=np.int64)  # the road users' numbers at the step before
        self._collisions: list[dict] = []

    def observe(self, snapshot: WorldSnapshot, collisions: Iterable[CollisionInput] = ()) -> PairSituations:
        """Audit one step; returns the evaluated vehicle pairs (for inspection; rows of ``snapshot``: the pairs with
        persons are left out)."""
        # Candidates as if no car stood (hold_standing): standing neighbours stay evaluated, so what was safe the step
        # before one moves off is known.
        moving = self.params.arrays(snapshot, held=False)
        params = self.params.hold(moving, snapshot.speed)
        frame = vehicle_frame(snapshot, self.network, params, self._routes.remaining(snapshot), moving)
        road = evaluate(snapshot, frame, self.network)
        persons = snapshot.persons
        users = self._persons.users(snapshot, params, self.params.hold(self.params.of(
            np.full(len(persons), PERSON), persons.vtype), persons.speed) if persons is not None else
            RssParamArrays.stack([]))
        ids = users.ids.tolist()  # Python strings: faster to hash than numpy's, one by one
        uid = self._uids.of(ids)
        road_keys = (uid[road.a] << 32) | uid[road.b]
        horizon = 2.0 * float(frame.reach.max(initial=0.0)) + 20.0
        # At junctions a standing car is held (a_acc = 0) whatever hold_standing says (docs/rss.md, moving_off.py).
        crossing = intersection_situations(
            snapshot, replace(frame, params=self.params.held_standing(moving, snapshot.speed)), self.network,
            self.junctions, horizon=horizon) if self.junctions.conflicts else None
        number = np.searchsorted(self._area_ids, crossing.area.astype(str)) if crossing is not None else None
        walking = self._persons.situations(snapshot, frame, users, horizon)
        if walking is not None:  # persons on crossings: junction situations of their own areas
            walking_number = len(self._area_ids) + self._persons.area_numbers(walking.area)
            crossing = walking if crossing is None else PairSituations.concat([crossing, walking])
            number = walking_number if number is None else np.concatenate([number, walking_number])
        areas = area_number = None
        if crossing is not None and len(crossing):
            crossing_keys = ((uid[crossing.a] << 32) | uid[crossing.b]) | INTERSECTION_KEY
            # Several conflict areas per pair: the pair is dangerous if any is; keep the most critical one
            # (dangerous first, then the yielding car closest to needing to stop), and remember every area's rules.
            margin = crossing.lon_gap - crossing.lon_d_min
            order = np.lexsort((margin, ~crossing.dangerous, crossing_keys))
            first = order[np.r_[True, crossing_keys[order][1:] != crossing_keys[order][:-1]]]
            areas = _area_rules(crossing_keys, number, crossing, margin)
            situations = PairSituations.concat([road, crossing.take(first)])
            keys = np.concatenate([road_keys, crossing_keys[first]])
            area_number = np.concatenate([np.full(len(road), -1), number[first]])
        else:
            situations, keys = road, road_keys
        seen_before = np.zeros(len(self._uids), dtype=bool)
        seen_before[self._prev_uids] = True
        new_vehicle = ~seen_before[uid]
        vehicle_pairs, vehicle_keys = situations, keys
        if walking is not None:  # rows of snapshot only: rules 4 and 5 are asked of vehicles, and callers read them
            cars = (situations.a < users.vehicles) & (situations.b < users.vehicles)
            vehicle_pairs, vehicle_keys = situations.take(cars), keys[cars]
        seen_from = self._occlusion.sight(snapshot, vehicle_pairs, vehicle_keys)
        self._tracker.step(StepInput(
            time=snapshot.time, keys=keys, situations=situations, ids=users.ids, uids=uid,
            vclass=users.vclass, accel=users.accel, speed=users.speed,
            accel_tolerance=EPS_ACCEL + snapshot.accel_resolution, params=users.params,
            new_vehicle=new_vehicle, areas=areas,
            area_number=area_number, seen_from=seen_from))
        self._occlusion.step(snapshot, frame, vehicle_pairs, vehicle_keys, self._tracker)
        self._rule5.step(snapshot, uid[:users.vehicles], frame, vehicle_pairs, vehicle_keys, self._tracker, params,
                         EPS_ACCEL + snapshot.accel_resolution)
        if self._states is not None:
            self._states.step(snapshot.time, self._tracker, keys, situations)
        if self._signal_rule is not None:
            self._signal_rule.step(snapshot, frame)
        self.record_collisions(collisions)
        self._prev_uids = uid
        self.pair_steps += len(situations)
        return vehicle_pairs

    def set_heights(self, heights: Mapping[str, float]) -> None:
        """The vTypes' heights [m] (vType → height) for rule 4, where they are known only once SUMO runs."""
        self._occlusion.heights = dict(heights)

    def _close_episode(self, record: dict, joinable: bool, window: float, time: float) -> list[dict]:
        """Rule 4's and rule 5's verdicts of a closed episode (the responsibility tracker's ``on_close``): rule 4
        first, as its unreasonable-speed violations make a car responsible, which rule 5 reads."""
        return self._occlusion.close(record) + self._rule5.close(record, joinable, window, time)

    def owed_by(self, vehicle_id: str) -> OwedResponses:
        """The proper responses ``vehicle_id`` owes right now (open episodes after the last observed step)."""
        return self._tracker.owed_by(vehicle_id)

    def record_collisions(self, collisions: Iterable[CollisionInput]) -> None:
        """Join collisions of the current step to their pairs' open episodes (blame = the episode's)."""
        for c in collisions:
            self._record_collision(c)

    def _record_collision(self, c: CollisionInput) -> None:
        a, b = sorted((c.collider, c.victim))
        records = []
        if a in self._uids.number and b in self._uids.number:
            key = (np.int64(self._uids.number[a]) << 32) | np.int64(self._uids.number[b])
            # The collision ends every open episode of the pair (on the road and at a junction).
            records = self._tracker.collide([int(key), int(key | INTERSECTION_KEY)], c.time, c.collider, c.victim)
        blamed, episode_key = collision_blame(records)
        avoidable = sorted({r["rule5_responsible"] for r in records if r["rule5_responsible"]})
        self._collisions.append({"run_id": self.run_id, "time_s": c.time, "collider": c.collider,
                                 "victim": c.victim, "sumo_type": c.kind, "blamed": blamed,
                                 "episode_key": episode_key, "could_have_avoided": ";".join(avoidable)})

    def finish(self) -> AuditResult:
        self._tracker.finish()
        episodes = self._tracker.episodes().sort_values(["t_b_s", "vehicle_a", "vehicle_b"], kind="stable",
                                                        ignore_index=True)
        signal = self._signal_rule.records if self._signal_rule is not None else []
        violations = _concat_rows(self._tracker.violations(), pd.DataFrame(signal, columns=VIOLATION_COLUMNS))
        violations = violations.sort_values(["t_start_s", "episode_key", "vehicle_id", "constraint"], kind="stable",
                                            ignore_index=True)
        collisions = pd.DataFrame(self._collisions, columns=COLLISION_COLUMNS)
        keys = self._tracker.serial_keys
        pair_states = self._states.pair_states(self.run_id, keys) if self.trace_class is not None else None
        states = self._states.episode_states(keys) if self.record_states else None
        occlusion = self._occlusion.frame() if self._occlusion.enabled else None
        return AuditResult(episodes, violations, collisions, self.params.resolved(), pair_states, states, occlusion,
                           self._occlusion.pair_steps)


def _concat_rows(*frames: pd.DataFrame) -> pd.DataFrame:
    """The rows of ``frames`` (same columns) in order; empty frames are left out, so they cannot change a dtype."""
    rows = [frame for frame in frames if len(frame)]
    return pd.concat(rows, ignore_index=True) if rows else frames[0]


def _area_rules(keys: np.ndarray, number: np.ndarray, crossing: PairSituations, margin: np.ndarray) -> AreaRules:
    """Every (pair, conflict area)'s rules and priority (the most critical row where a pair meets in one area
    through several pairs of links), sorted for look-ups."""
    area_keys = np.empty(len(keys), dtype=AREA_KEY)
    area_keys["pair"], area_keys["area"] = keys, number
    order = np.lexsort((margin, ~crossing.dangerous, number, keys))
    pair, area = keys[order], number[order]  # compared field by field (numpy's structured != is ~10x slower)
    first = order[np.r_[True, (pair[1:] != pair[:-1]) | (area[1:] != area[:-1])]]
    return AreaRules(area_keys[first], crossing.safe_rules[first], crossing.priority[first],
                     crossing.kind[first] == KIND_SIGNAL)
