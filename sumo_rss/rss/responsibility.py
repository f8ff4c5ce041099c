"""Per-pair state across steps: danger threshold, owed response, compliance of both cars, violations, blame
(rss.md §5).

Open episodes live in one struct of arrays sorted by pair key and are rolled over once per step; closed
episodes and finished violations become records and leave the state, so memory stays bounded by the number of
pairs that are dangerous *now*. What each step is given: :mod:`.step_input`; the episodes that open at the danger
threshold: :mod:`.threshold`; the compliance judged at every step: :mod:`.compliance`; what a car owes, for a
guard: :mod:`.owed_responses`.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from .compliance import TIME_EPS, JudgedStep, judge_step
from .open_episodes import CONSTRAINTS, OpenEpisodes
from .episode_log import EpisodeLog, EpisodeParts, join_records
from .moving_off import StandingCars
from .owed_responses import OwedResponses, owed_in
from .sorted_keys import find_sorted
from .records import EVASIVE_CONSTRAINT, OCCLUSION_CONSTRAINT, RULE5_UNCHECKED
from .situations import FIRST_INTERSECTION_CODE, SITUATION_CODES
from .step_input import StepInput
from .threshold import StepBefore, new_episodes


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
        self._before = StepBefore()  # what was safe at the step before: it decides who owes what at t_b
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
        self._before.remember(step, keys, order)
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
        return owed_in(self._open, vehicle_id)

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
        """Open the episodes of the pairs ``keys`` (situation ``rows``) that became dangerous now: a new serial
        each, or the one of the pair's episode that ended within ρ (it goes on)."""
        n = len(keys)
        serials = np.arange(self._next_serial, self._next_serial + n, dtype=np.int64)
        for r, k in enumerate(keys.tolist()):
            held = self._log.resume(k, step.time)
            if held is not None:  # the pair's episode that ended within ρ goes on (its serial too)
                self._continued[k] = held
                serials[r] = held[0]["serial"]
            else:
                self._episode_count[k] = self._episode_count.get(k, 0) + 1
        fresh = new_episodes(step, keys, rows, self._before, self._standing, self._dt(step), serials)
        self._next_serial += n
        merged = OpenEpisodes.concat([self._open, fresh]) if len(self._open) else fresh
        self._open = merged.take(np.argsort(merged.keys, kind="stable"))

    def _dt(self, step: StepInput) -> float:
        """[s] since the step before (0 at the first)."""
        return step.time - self._last_time if self._last_time is not None else 0.0

    def _check_compliance(self, step: StepInput, rows: np.ndarray, candidate: np.ndarray,
                          in_danger: np.ndarray) -> None:
        """Judge both cars of every open episode at ``step.time`` (:func:`.compliance.judge_step`) and hold the
        violations that ended as rows of their episodes."""
        self.judged, ended = judge_step(self._open, step, rows, candidate, in_danger, self._dt(step), self._log.join)
        if np.any(ended):
            self._emit_violations(ended)

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
