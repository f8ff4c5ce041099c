"""Per-pair state across steps: danger threshold, owed response, compliance of both cars, violations, blame
(rss.md §5).

Open episodes live in one struct of arrays sorted by pair key and are rolled over once per step; closed
episodes and finished violations become records and leave the state, so memory stays bounded by the number of
pairs that are dangerous *now*.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .params import RssParamArrays
from .duties import duties_at_threshold
from .open_episodes import CONSTRAINTS, N_CONSTRAINTS, Constraint, OpenEpisodes
from .episode_log import EpisodeLog, EpisodeParts, join_records
from .moving_off import StandingCars
from .sorted_keys import find_sorted
from .records import EVASIVE_CONSTRAINT, OCCLUSION_CONSTRAINT, RULE5_UNCHECKED
from ..road_users import PERSON_CLASS
from .intersection import KIND_SIGNAL
from .situations import FIRST_INTERSECTION_CODE, SAME_DIRECTION_CODES, SITUATION_CODES, PairSituations

EPS_ACCEL = 0.05  # [m/s²] tolerance on every acceleration bound
STOPPED_SPEED = 0.05  # [m/s] below this a car counts as stopped
TIME_EPS = 1e-9  # [s]


@dataclass
class StepInput:
    """What one step of the tracker needs, per pair (rows of the snapshot in ``a``/``b``)."""

    time: float  # [s]
    keys: np.ndarray  # int64 pair keys, unique
    situations: PairSituations
    ids: np.ndarray  # vehicle ids of the snapshot
    uids: np.ndarray  # int64 per snapshot row: a number for each vehicle id, the same at every step
    vclass: np.ndarray
    accel: np.ndarray  # [m/s²] per snapshot row
    speed: np.ndarray  # [m/s] per snapshot row
    params: RssParamArrays  # per snapshot row
    new_vehicle: np.ndarray  # bool per snapshot row: not seen at the previous step
    # Intersections: every conflict area's rules of every crossing pair (not only the row kept per pair), and the
    # number of the area of each row of ``situations`` (-1: a road situation).
    areas: AreaRules | None = None
    area_number: np.ndarray | None = None
    accel_tolerance: float = EPS_ACCEL  # [m/s²] on the acceleration bounds (wider for accelerations measured coarsely)
    # Rule 4 (:mod:`.occlusion_track`): sorted pair keys and the start [s] of their cars' current run of seeing each
    # other (+inf while hidden); a response is owed from max(t_b, that start) + ρ. None: every car sees every car.
    seen_from: tuple[np.ndarray, np.ndarray] | None = None


RESPONSIBLE_VALUES = ("a", "b", "both", "none")  # episodes.csv's 'responsible': the cars with a violation

AREA_KEY = np.dtype([("pair", np.int64), ("area", np.int64)])


@dataclass(frozen=True, eq=False)
class AreaRules:
    """The RULE_* bits and priority of one step in every conflict area of every crossing pair, sorted by ``keys``
    (AREA_KEY: pair key, area number). A pair is kept as one situation, in its most critical area; when it
    becomes dangerous in an area, what held in that area at the step before t_b decides who owes what (rss.md
    §5), not what held in the area that was most critical then."""

    keys: np.ndarray
    rules: np.ndarray  # int8
    priority: np.ndarray  # int8
    by_signal: np.ndarray  # bool: the signals decided the priority


@dataclass(frozen=True, eq=False)
class OwedResponses:
    """What one vehicle owes in its open episodes (one row per episode), for a proper-response guard."""

    t_b: np.ndarray  # [s] danger threshold time
    must_brake: np.ndarray  # bool: longitudinal braking owed after ρ
    brake_correct: np.ndarray  # bool: the braking owed is b_corr (opposite direction, correct lane)
    front_limited: np.ndarray  # bool: must not brake harder than b_max
    owed_lat: np.ndarray  # bool: lateral response owed (not while the cars are in line: neither side is towards)
    other_is_left: np.ndarray  # bool: the other car is on this car's left (as they are now)
    u0: np.ndarray  # [m/s] this car's lateral speed towards the other at t_b
    other_id: np.ndarray  # the other car's id
    same_direction: np.ndarray  # bool: one car follows the other (same direction or merge)
    lat_settled: np.ndarray  # bool: this car's speed towards the other has been ≤ 0 from ρ on (it must stay there)
    # bool: the lateral response is owed in the episode, in line now or not (judged at any step where the cars
    # are apart: ``in_line``); None: as ``owed_lat``
    lat_duty: np.ndarray | None = None
    # bool: the braking is owed from t_b, without a response time (moved off from standing, moving_off.py); None:
    # never
    no_response_time: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.lat_duty is None:
            object.__setattr__(self, "lat_duty", self.owed_lat)
        if self.no_response_time is None:
            object.__setattr__(self, "no_response_time", np.zeros(len(self.t_b), dtype=bool))

    def __len__(self) -> int:
        return int(self.t_b.shape[0])

    def without_lon_duty(self) -> frozenset[str]:
        """The cars going this car's way that it owes no longitudinal braking in an open episode: the episode did
        not start longitudinally for it (e.g. the other car cut in), so closing the gap is not its duty."""
        return frozenset(self.other_id[self.same_direction & ~self.must_brake].tolist())


@dataclass(frozen=True, eq=False)
class JudgedStep:
    """The owed responses' bounds of one step, per open episode (by ``serial``) and car (column 0: a, 1: b); NaN
    where a bound does not apply (not owed, the step at t_b, a car stopped after ρ, the pair not evaluated)."""

    serial: np.ndarray  # int64, one per open episode
    accel: np.ndarray  # [m/s²] the car's acceleration
    accel_max: np.ndarray  # [m/s²] a ≤ this: a_acc during ρ, −b_min (−b_corr) after it
    accel_min: np.ndarray  # [m/s²] a ≥ this: −b_max (the front car)
    lat_speed: np.ndarray  # [m/s] the car's lateral speed towards the other
    lat_speed_max: np.ndarray  # [m/s] the lateral response's envelope


def in_line(lat_offset: Any, mu_a: Any, mu_b: Any) -> np.ndarray:
    """Whether two cars whose centres are ``lat_offset`` [m] apart across the road are in line: within μ/2 (the
    larger μ [m] of the two), where neither side is towards the other and the lateral response is not judged
    (rss.md, "The lateral duty keeps away from the side the other car is on now"). NaN: False."""
    return np.asarray(lat_offset) <= 0.5 * np.maximum(mu_a, mu_b)


def lateral_speed_bound(u0: Any, tau: Any, rho: Any, a_lat: Any, b_lat: Any) -> np.ndarray:
    """The lateral response's bound on a car's speed towards the other [m/s], ``tau`` s after the trigger at
    which it was ``u0`` (rss.md §5): it may grow at a_lat during ρ, must then fall at b_lat to ≤ 0 and stay there
    (never asked below 0)."""
    return np.maximum(u0 + a_lat * np.minimum(tau, rho) - b_lat * np.maximum(tau - rho, 0.0), 0.0)


class ResponsibilityTracker:
    """Rolls the per-pair state forward one step at a time and collects closed episodes and violations.

    ``join``: an episode that re-opens within the pair's ρ of its end continues it (:mod:`.episode_log`); False:
    raw episodes. ``stay_out_complies``: a car that owes braking at a junction and never enters the conflict area
    while the episode lasts complied (the intersection response exists so that it does not enter); False: ad_rss's
    reading, braking at b_min after ρ until stopped however far from the area it stops. ``on_close(record,
    joinable, window [s], time [s])``: called with every closed (or joined, or collided) episode record before it is
    logged; may fill its rule-5 fields and returns violation rows to add (rule 5, :mod:`.evasive_track`; rule 4,
    :mod:`.occlusion_track`, whose rows make their car responsible)."""

    def __init__(self, run_id: str = "", join: bool = True, stay_out_complies: bool = True,
                 on_close: Callable[[dict, bool, float, float], list[dict]] | None = None):
        self.run_id = run_id
        self._on_close = on_close or (lambda record, joinable, window, time: [])
        self.stay_out_complies = stay_out_complies
        self._log = EpisodeLog(join)
        # pair key → (car, row) of its open episode's violations, judged at its end
        self._episode_violations: dict[int, list[tuple[int, dict]]] = {}
        self._continued: dict[int, tuple[dict, EpisodeParts]] = {}  # pair key → the episode its open one continues
        self._open = OpenEpisodes()
        self._prev_keys = np.zeros(0, dtype=np.int64)
        self._prev_rules = np.zeros(0, dtype=np.int8)
        self._prev_priority = np.zeros(0, dtype=np.int8)
        self._prev_by_signal = np.zeros(0, dtype=bool)
        self._prev_areas: AreaRules | None = None
        self._episode_count: dict[int, int] = {}
        self._collided = np.zeros(0, dtype=np.int64)  # pairs whose episode a collision closed, until safe again
        self._last_time: float | None = None
        self._standing = StandingCars()
        self._next_serial = 0
        self.serial_keys: dict[int, str] = {}  # serial → episode key of every closed episode
        self.judged: JudgedStep | None = None  # the bounds of the last step (None: no episode was judged)

    # -----------------------------------------------------------------------------------------------------
    def step(self, step: StepInput) -> None:
        """Advance to ``step.time``."""
        if self._last_time is not None and step.time <= self._last_time + TIME_EPS:
            raise ValueError(f"time must increase: {step.time} s after {self._last_time} s")
        self._log.expire(step.time)
        self.judged = None
        sit = step.situations
        order = np.argsort(step.keys, kind="stable")
        keys = step.keys[order]
        sit_rows = order
        dangerous = sit.dangerous[order]

        # 1. Episodes with a car that has left the data (arrived, teleported, removed) end where their data ends;
        # episodes whose pair is safe now (or no longer a candidate, i.e. far apart) end at this step. A collision
        # reported at this step still joins them (collide): SUMO's default collision action removes the collider
        # or moves it far away in the very step of the collision.
        gone = ~np.isin(self._open.uids, step.uids).all(axis=1)
        self._close(gone, step.time, end_of_data=True)
        found, pos = find_sorted(keys, self._open.keys)
        still_dangerous = found & dangerous[pos] if len(keys) else found
        # 2. Compliance of both cars in every open episode (the first judged step is the one after t_b). An episode
        # that ends now is judged at this step too: the acceleration reported now was driven from the step before,
        # when the pair was still dangerous; also one whose pair is no longer a candidate (far apart now).
        if len(self._open):
            self._check_compliance(step, sit_rows[pos] if len(keys) else pos, found, still_dangerous)
        self._close(~still_dangerous, step.time)
        # A collided pair stays in contact or danger for a while: no new episode until it is safe once.
        found, pos = find_sorted(keys, self._collided)
        self._collided = self._collided[found & dangerous[pos]] if len(keys) else self._collided[:0]
        # 3. Newly dangerous pairs open an episode at the danger threshold t_b = now (or continue the one that ended
        # within ρ before).
        new = dangerous & ~find_sorted(self._open.keys, keys)[0] & ~find_sorted(self._collided, keys)[0]
        if np.any(new):
            self._open_new(step, keys[new], sit_rows[new])
        self._prev_keys = keys
        self._prev_areas = step.areas
        self._prev_rules = sit.safe_rules[order]
        self._prev_priority = sit.priority[order] if sit.priority is not None else np.zeros(len(keys), dtype=np.int8)
        self._prev_by_signal = sit.kind[order] == KIND_SIGNAL
        self._standing.update(step.uids, step.speed)
        self._last_time = step.time

    @property
    def open(self) -> OpenEpisodes:
        """The open episodes (after the last step), sorted by pair key."""
        return self._open

    def open_episodes(self, vclass: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pair keys, serials, involves) of the open episodes, sorted by pair key; ``involves``: the episode has a
        car of class ``vclass`` (every episode where None)."""
        e = self._open
        involves = np.ones(len(e), dtype=bool) if vclass is None else (e.a_class == vclass) | (e.b_class == vclass)
        return e.keys, e.serial, involves

    def owed_by(self, vehicle_id: str) -> OwedResponses:
        """The responses ``vehicle_id`` owes in its open episodes."""
        e = self._open
        as_a, as_b = e.a_id == vehicle_id, e.b_id == vehicle_id
        idx = np.flatnonzero(as_a | as_b)
        car = np.where(as_a[idx], 0, 1)
        return OwedResponses(
            t_b=e.t_b[idx], must_brake=e.must_brake[idx, car], brake_correct=e.brake_correct[idx, car],
            front_limited=e.front_limited[idx, car], owed_lat=e.owed_lat[idx] & ~e.in_line[idx],
            other_is_left=np.where(car == 0, ~e.a_left[idx], e.a_left[idx]), u0=e.u0[idx, car],
            other_id=np.where(car == 0, e.b_id[idx], e.a_id[idx]),
            same_direction=np.isin(e.kind[idx], SAME_DIRECTION_CODES), lat_settled=e.lat_settled[idx, car],
            lat_duty=e.owed_lat[idx], no_response_time=e.moved_off[idx, car])

    def collide(self, pair_keys: list[int], time: float, collider: str, victim: str) -> list[dict]:
        """Close the open episodes of ``pair_keys`` (one pair's road and junction keys) with a collision; returns
        their records (none: the pair was in no episode). An episode that ended within its join window (with raw
        episodes: at this step, step 1 of :meth:`step`) is the collision's too: the pair was in danger up to just
        before the contact. Either way no new episode of the pair opens until it is safe once: cars left in contact
        are not judged for what follows it."""
        records = []
        for pair_key in pair_keys:
            hit = self._open.keys == pair_key
            if hit.any():
                records.append(self._close(hit, time, collision=(collider, victim))[0])
                continue
            held = self._log.collide(pair_key, time)
            if held is not None:
                record, parts = held
                record.update(t_end_s=time, duration_s=time - record["t_b_s"], collision=True, collider=collider,
                              victim=victim, ended_by="collision")
                self._judge_rules_4_5(record, parts, False, 0.0, time)
                self._log.close(pair_key, record, parts, time, 0.0, joinable=False)
                records.append(record)
        self._collided = np.union1d(self._collided, np.asarray(pair_keys, dtype=np.int64)).astype(np.int64)
        return records

    def finish(self) -> None:
        """Close every open episode at the last observed time (end of data)."""
        if len(self._open):
            self._close(np.ones(len(self._open), dtype=bool), self._last_time or 0.0, end_of_data=True)
        self._log.expire(np.inf)

    def episodes(self) -> pd.DataFrame:
        """The closed episodes so far (EPISODE_COLUMNS)."""
        return self._log.frame()

    def violations(self) -> pd.DataFrame:
        """The finished violations of the closed episodes so far, in the order they finished (VIOLATION_COLUMNS)."""
        return self._log.violation_frame()

    # -----------------------------------------------------------------------------------------------------
    def _episode_key(self, i: int) -> str:
        """'a|b|k' for road episodes, 'a|b|xk' for intersection episodes of the pair."""
        e = self._open
        tag = "x" if e.kind[i] >= FIRST_INTERSECTION_CODE else ""
        return f"{e.a_id[i]}|{e.b_id[i]}|{tag}{self._episode_count[int(e.keys[i])]}"

    def _open_new(self, step: StepInput, keys: np.ndarray, rows: np.ndarray) -> None:
        sit = step.situations
        a, b = sit.a[rows], sit.b[rows]
        # What was safe just before t_b decides the owed response (rss.md §5).
        seen, pos = find_sorted(self._prev_keys, keys)
        prev_rules = self._prev_rules[pos] if len(self._prev_keys) else np.zeros(len(keys), dtype=np.int8)
        prev_priority = self._prev_priority[pos] if len(self._prev_keys) else np.zeros(len(keys), dtype=np.int8)
        prev_by_signal = self._prev_by_signal[pos] if len(self._prev_keys) else np.zeros(len(keys), dtype=bool)
        if self._prev_areas is not None and len(self._prev_areas.keys) and step.area_number is not None:
            # A crossing pair: what held in the area it is dangerous in now.
            area_keys = np.empty(len(keys), dtype=AREA_KEY)
            area_keys["pair"], area_keys["area"] = keys, step.area_number[rows]
            found, at = find_sorted(self._prev_areas.keys, area_keys)
            found &= step.area_number[rows] >= 0
            seen = seen | found
            prev_rules = np.where(found, self._prev_areas.rules[at], prev_rules)
            prev_priority = np.where(found, self._prev_areas.priority[at], prev_priority)
            prev_by_signal = np.where(found, self._prev_areas.by_signal[at], prev_by_signal)
        appeared = ~seen & (step.new_vehicle[a] | step.new_vehicle[b])
        duties = duties_at_threshold(sit, rows, prev_rules, prev_priority, seen, appeared, prev_by_signal)
        # Lateral speed towards the other car at t_b: the left car's is −v_lat, the right car's +v_lat.
        u0 = np.column_stack([np.where(sit.a_is_left[rows], -sit.v_lat_a[rows], sit.v_lat_a[rows]),
                              np.where(sit.a_is_left[rows], sit.v_lat_b[rows], -sit.v_lat_b[rows])])
        n = len(keys)
        # A car that owes braking at a junction and moved off from standing short of the area owes it at once.
        enter = np.column_stack([sit.enter_a[rows], sit.enter_b[rows]]) if sit.enter_a is not None \
            else np.full((n, 2), np.nan)
        moved_off = duties.must_brake & (sit.kind[rows] >= FIRST_INTERSECTION_CODE)[:, None] & \
            self._standing.moved_off(np.column_stack([step.uids[a], step.uids[b]]),
                                     np.column_stack([step.vclass[a], step.vclass[b]]), enter,
                                     np.column_stack([sit.v_lon_a[rows], sit.v_lon_b[rows]]),
                                     step.time - self._last_time if self._last_time is not None else 0.0)
        serials = np.arange(self._next_serial, self._next_serial + n, dtype=np.int64)
        for r, k in enumerate(keys.tolist()):
            held = self._log.resume(k, step.time)
            if held is not None:  # the pair's episode that ended within ρ goes on (its serial too)
                self._continued[k] = held
                serials[r] = held[0]["serial"]
            else:
                self._episode_count[k] = self._episode_count.get(k, 0) + 1
        fresh = OpenEpisodes(
            keys=keys.astype(np.int64), serial=serials, a_id=step.ids[a].astype(object),
            b_id=step.ids[b].astype(object),
            uids=np.column_stack([step.uids[a], step.uids[b]]),
            a_class=step.vclass[a].astype(object), b_class=step.vclass[b].astype(object),
            kind=sit.kind[rows], t_b=np.full(n, step.time), t_last=np.full(n, step.time),
            window=np.maximum(step.params.response_time[a], step.params.response_time[b]),
            must_brake=duties.must_brake, moved_off=moved_off, front_limited=duties.front_limited,
            brake_correct=duties.brake_correct,
            owed_lat=duties.owed_lat, trigger=duties.trigger, roles=duties.roles, owed=duties.owed,
            area=sit.area[rows].astype(object) if sit.area is not None else np.full(n, "", dtype=object),
            a_left=sit.a_is_left[rows], in_line=np.zeros(n, dtype=bool), u0=u0,
            lat_settled=np.zeros((n, 2), dtype=bool),
            min_lon_margin=sit.lon_gap[rows] - sit.lon_d_min[rows],
            min_lat_margin=sit.lat_gap[rows] - sit.lat_d_min[rows],
            responsible=np.zeros((n, 2), dtype=bool), **_area_progress(
                sit, rows, np.column_stack([sit.v_lon_a[rows], sit.v_lon_b[rows]]),
                np.column_stack([step.accel[a], step.accel[b]]), _instant_brake(step, np.column_stack([a, b]))),
            active=np.zeros((n, 2, N_CONSTRAINTS), dtype=bool),
            v_start=np.zeros((n, 2, N_CONSTRAINTS)), v_last=np.zeros((n, 2, N_CONSTRAINTS)),
            v_worst=np.zeros((n, 2, N_CONSTRAINTS)), v_bound=np.zeros((n, 2, N_CONSTRAINTS)),
            v_excess=np.full((n, 2, N_CONSTRAINTS), -np.inf))
        self._next_serial += n
        merged = OpenEpisodes.concat([self._open, fresh]) if len(self._open) else fresh
        self._open = merged.take(np.argsort(merged.keys, kind="stable"))

    def _check_compliance(self, step: StepInput, rows: np.ndarray, candidate: np.ndarray,
                          in_danger: np.ndarray) -> None:
        """Evaluate every owed constraint for both cars of each open episode at ``step.time`` (both cars are in the
        snapshot): with the pair's situation where it is a ``candidate`` now (situation ``rows``; elsewhere ``rows``
        is ignored); elsewhere (far apart now, e.g. one has left the junction) only the longitudinal constraints,
        on the cars' own accelerations and speeds: the pair's lateral speeds are not known there. ``in_danger``: the
        pair is still dangerous (its margins count)."""
        e, sit, t = self._open, step.situations, step.time
        if len(sit):
            e.min_lon_margin = np.where(in_danger, np.minimum(e.min_lon_margin,
                                                              sit.lon_gap[rows] - sit.lon_d_min[rows]), e.min_lon_margin)
            e.min_lat_margin = np.where(in_danger, np.minimum(e.min_lat_margin,
                                                              sit.lat_gap[rows] - sit.lat_d_min[rows]), e.min_lat_margin)
        e.t_last = np.where(candidate, t, e.t_last)
        start = e.t_b  # the response starts when the cars can see each other (rule 4)
        if step.seen_from is not None and len(step.seen_from[0]):
            seen, at = find_sorted(step.seen_from[0], e.keys)
            start = np.where(seen, np.maximum(e.t_b, step.seen_from[1][at]), e.t_b)
        judged = t > start + TIME_EPS
        by_uid = np.argsort(step.uids)
        own = by_uid[np.searchsorted(step.uids[by_uid], e.uids)]  # [n, 2] snapshot rows of the cars
        pair = candidate[:, None]
        if len(sit):
            cars = np.where(pair, np.column_stack([sit.a[rows], sit.b[rows]]), own)  # [n, 2] snapshot rows
            v_lon = np.where(pair, np.column_stack([sit.v_lon_a[rows], sit.v_lon_b[rows]]), step.speed[own])
            v_lat = np.where(pair, np.column_stack([sit.v_lat_a[rows], sit.v_lat_b[rows]]), 0.0)
        else:
            cars, v_lon, v_lat = own, step.speed[own], np.zeros(own.shape)
        p = step.params
        accel = step.accel[cars]
        if len(sit):
            progress = _area_progress(sit, rows, v_lon, accel, _instant_brake(step, cars))
            e.entered |= pair & progress["entered"]
            e.stood_short |= pair & progress["stood_short"]
            e.stopping = np.where(pair, progress["stopping"], e.stopping)
        rho = p.response_time[cars]
        tau = (t - np.minimum(start, t))[:, None]  # 0 while hidden (nothing is judged then)
        rho_lon = np.where(e.moved_off, 0.0, rho)  # no response time to its own moving off (moving_off.py)
        in_response = tau <= rho_lon + TIME_EPS
        # The step that ends ρ inside it (ρ not a multiple of the step): its mean acceleration may be a_acc for
        # the part before t_b + ρ and must be −b after it, so its bound is the time-weighted mix of the two.
        dt = t - self._last_time if self._last_time is not None else 0.0
        before = np.clip((rho_lon - (tau - dt)) / dt, 0.0, 1.0) if dt > 0.0 else np.zeros_like(rho)
        braker = e.must_brake
        front = e.front_limited
        brake_needed = np.where(e.brake_correct, p.lon_brake_min_correct[cars], p.lon_brake_min[cars])
        moving = v_lon >= STOPPED_SPEED

        actual = np.zeros(cars.shape + (N_CONSTRAINTS,))
        bound = np.zeros_like(actual)
        sign = np.array([1.0, 1.0, -1.0, 1.0])  # +1: actual ≤ bound; −1: actual ≥ bound
        applies = np.zeros(actual.shape, dtype=bool)
        applies[..., 0] = braker & in_response
        actual[..., 0], bound[..., 0] = accel, p.lon_accel_max[cars]
        applies[..., 1] = braker & ~in_response & moving
        actual[..., 1], bound[..., 1] = accel, before * p.lon_accel_max[cars] - (1.0 - before) * brake_needed
        applies[..., 2] = front
        actual[..., 2], bound[..., 2] = accel, -p.lon_brake_max[cars]
        self._update_lateral_order(sit, rows, candidate, p.lat_fluctuation_margin[cars])
        left = np.column_stack([e.a_left, ~e.a_left])
        u = np.where(left, -v_lat, v_lat)
        beside = pair & ~e.in_line[:, None]
        applies[..., 3] = e.owed_lat[:, None] & beside
        actual[..., 3] = u
        # Once a car's speed towards the other is ≤ 0 from ρ on, it must stay there.
        bound[..., 3] = np.where(e.lat_settled, 0.0,
                                 lateral_speed_bound(e.u0, tau, rho, p.lat_accel_max[cars], p.lat_brake_min[cars]))
        e.lat_settled = e.lat_settled | (judged[:, None] & beside & (tau >= rho - TIME_EPS) & (u <= 0.0))
        tolerance = np.full(actual.shape, step.accel_tolerance)
        # The velocity envelope's tolerance: the acceleration tolerance integrated while the envelope changes,
        # up to when it reaches 0; from then on "stay ≤ 0" does not loosen with time.
        settles = rho + np.maximum(e.u0 + p.lat_accel_max[cars] * rho, 0.0) / p.lat_brake_min[cars]
        tolerance[..., 3] = EPS_ACCEL * np.minimum(tau, settles)
        excess = sign * (actual - bound)
        violating = applies & judged[:, None, None] & (excess > tolerance)
        # With joining, a violation that resumes within the car's ρ continues its interval (one row, not one per
        # step where a coarsely measured acceleration dips back within its bound).
        self._roll_violations(violating, actual, bound, excess, t, rho if self._log.join else np.zeros_like(rho))
        shown = np.where(applies & judged[:, None, None], bound, np.nan)
        self.judged = JudgedStep(e.serial, accel, np.fmin(shown[..., 0], shown[..., 1]), shown[..., 2],
                                 np.where(pair, u, np.nan), shown[..., 3])

    def _update_lateral_order(self, sit: PairSituations, rows: np.ndarray, candidate: np.ndarray,
                              mu: np.ndarray) -> None:
        """Which car is left of the other, as they are now (the side a lateral response keeps away from), and
        whether they are in line: centres within μ/2 across the road (the larger μ [m] of the two, ``mu`` [n, 2]),
        where neither side is towards the other (a car that cut in and now drives straight ahead in the other's
        lane). Kept from the last step seen where the pair is no road situation now."""
        e = self._open
        if not len(sit) or sit.lat_offset is None:
            return
        offset = np.where(candidate, sit.lat_offset[rows], np.nan)
        lined_up = in_line(offset, mu[:, 0], mu[:, 1])  # NaN (junctions, not a candidate): False
        seen = candidate & np.isfinite(offset)
        e.in_line = np.where(seen, lined_up, e.in_line)
        e.a_left = np.where(seen & ~lined_up, sit.a_is_left[rows], e.a_left)

    def _roll_violations(self, violating: np.ndarray, actual: np.ndarray, bound: np.ndarray, excess: np.ndarray,
                         t: float, grace: np.ndarray) -> None:
        """Start, extend and end the violation intervals [episode, car, constraint]; an interval ends once ``grace``
        [s] per car has passed since its last violating step."""
        e = self._open
        starting = violating & ~e.active
        e.v_start = np.where(starting, t, e.v_start)
        worse = violating & (excess > e.v_excess)
        e.v_worst = np.where(worse, actual, e.v_worst)
        e.v_bound = np.where(worse, bound, e.v_bound)
        e.v_excess = np.where(worse, excess, e.v_excess)
        e.v_last = np.where(violating, t, e.v_last)
        ended = e.active & ~violating & (t - e.v_last > grace[..., None] + TIME_EPS)
        if np.any(ended):
            self._emit_violations(ended)
        e.active = violating | (e.active & ~ended)
        e.responsible |= np.any(violating, axis=2)

    def _emit_violations(self, mask: np.ndarray) -> None:
        """The finished violations ``mask`` [episode, car, constraint] as rows of their episodes (written when the
        episode ends: a car that stays out of the conflict area has complied after all)."""
        e = self._open
        for i, car, c in zip(*np.nonzero(mask)):
            vid = e.a_id[i] if car == 0 else e.b_id[i]
            vclass = e.a_class[i] if car == 0 else e.b_class[i]
            self._episode_violations.setdefault(int(e.keys[i]), []).append((int(car), {
                "run_id": self.run_id, "episode_key": self._episode_key(i), "vehicle_id": vid,
                "vehicle_class": vclass, "role": e.roles[i, car], "constraint": CONSTRAINTS[c].value,
                "bound": float(e.v_bound[i, car, c]), "worst_actual": float(e.v_worst[i, car, c]),
                "excess": float(e.v_excess[i, car, c]), "t_start_s": float(e.v_start[i, car, c]),
                "t_end_s": float(e.v_last[i, car, c])}))
        e.v_excess = np.where(mask, -np.inf, e.v_excess)

    def _close(self, mask: np.ndarray, time: float, *, collision: tuple[str, str] | None = None,
               end_of_data: bool = False) -> list[dict]:
        if not np.any(mask):
            return []
        e = self._open
        self._emit_violations(e.active & mask[:, None, None])
        # A car owing braking at a junction that stops before the conflict area complied: it never entered the area
        # while the (joined) episode lasted, and stood still short of it or, when the episode ended, was braking hard
        # enough to stop before it (EpisodeParts).
        junction = (e.kind >= FIRST_INTERSECTION_CODE)[:, None] & self.stay_out_complies
        excusable = e.must_brake & junction
        stays_out = (e.stood_short | e.stopping) & junction
        records = []
        for i in np.flatnonzero(mask):
            key = int(e.keys[i])
            t_end = float(e.t_last[i]) if end_of_data else time
            first, parts = self._continued.pop(key, (None, EpisodeParts()))
            parts.add(self._episode_violations.pop(key, []), e.responsible[i], excusable[i], e.entered[i],
                      stays_out[i])
            resp = parts.responsible
            episode_key = self._episode_key(i)
            self.serial_keys[int(e.serial[i])] = episode_key
            record = {
                "run_id": self.run_id, "episode_key": episode_key, "serial": int(e.serial[i]),
                "vehicle_a": e.a_id[i], "vehicle_b": e.b_id[i], "class_a": e.a_class[i], "class_b": e.b_class[i],
                "episode_index": self._episode_count[int(e.keys[i])],
                "situation": SITUATION_CODES[e.kind[i]].value, "t_b_s": float(e.t_b[i]), "t_end_s": t_end,
                "duration_s": t_end - float(e.t_b[i]), "trigger": e.trigger[i],
                "conflict_area": e.area[i], "owed_a": e.owed[i, 0], "owed_b": e.owed[i, 1],
                "responsible": "both" if resp.all() else "a" if resp[0] else "b" if resp[1] else "none",
                "min_lon_margin_m": float(e.min_lon_margin[i]), "min_lat_margin_m": float(e.min_lat_margin[i]),
                "collision": collision is not None, "collider": collision[0] if collision else "",
                "victim": collision[1] if collision else "", "ended_by": "collision" if collision else
                "end-of-data" if end_of_data else "safe", **RULE5_UNCHECKED}
            if first is not None:
                record = join_records(first, record)
            joinable = collision is None and not end_of_data
            self._judge_rules_4_5(record, parts, joinable, float(e.window[i]), time)
            records.append(record)
            self._log.close(key, record, parts, time, float(e.window[i]), joinable=joinable)
        self._open = e.take(np.flatnonzero(~mask))
        return records


    def _judge_rules_4_5(self, record: dict, parts: EpisodeParts, joinable: bool, window: float, time: float) -> None:
        """Rules 4 and 5's verdicts of a closed (joined, collided) episode (``on_close``): its record's fields, its
        evasive-effort row in place of an earlier part's, and rule 4's unreasonable-speed rows."""
        rows = self._on_close(record, joinable, window, time)
        parts.rows[:] = [held for held in parts.rows if held[2]["constraint"] != EVASIVE_CONSTRAINT] + \
            [(0 if row["vehicle_id"] == record["vehicle_a"] else 1, False, row) for row in rows]
        for row in rows:  # rule 4's unreasonable speed makes a car responsible, also for a later part
            if row["constraint"] == OCCLUSION_CONSTRAINT:
                parts.fixed[0 if row["vehicle_id"] == record["vehicle_a"] else 1] = True


def _instant_brake(step: StepInput, cars: np.ndarray) -> np.ndarray:
    """[m/s²] b_max of the persons among the road users ``cars`` (rows of ``step``), NaN for vehicles."""
    return np.where(step.vclass[cars] == PERSON_CLASS, step.params.lon_brake_max[cars], np.nan)


def _area_progress(sit: PairSituations, rows: np.ndarray, speed: np.ndarray, accel: np.ndarray,
                   instant_brake: np.ndarray) -> dict[str, np.ndarray]:
    """[n, 2] per car of the crossing situations ``rows`` (``speed`` [m/s] and ``accel`` [m/s²] per car): its front
    bumper is in the conflict area or past its start ('entered'), it stands short of it ('stood_short'), it is
    short of it and stands or brakes hard enough to stop before it ('stopping'); all False on roads. A person
    (``instant_brake``: its b_max [m/s²], NaN for a vehicle) is also 'stopping' while braking at b_max would stop
    it before the area: SUMO's persons have no deceleration, they stop within a step where they are to wait."""
    if sit.enter_a is None:
        none = np.zeros((len(rows), 2), dtype=bool)
        return {"entered": none, "stood_short": none, "stopping": none}
    enter = np.column_stack([sit.enter_a[rows], sit.enter_b[rows]])  # NaN on roads: every comparison False
    short = enter > 0.0
    standing = short & (speed < STOPPED_SPEED)
    can_stop = speed * speed < 2.0 * instant_brake * enter  # NaN (a vehicle): False
    return {"entered": enter < 0.0, "stood_short": standing,
            "stopping": standing | (short & (((accel < 0.0) & (speed * speed < -2.0 * accel * enter)) | can_stop))}
