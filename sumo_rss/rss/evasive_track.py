"""Rule 5 over a run (rss.md §8, docs/rss.md "Rule 5"), asked of the road episodes with one responsible car (c₂) that
end in a collision: whether the other car (c₁) had a legal evasive manoeuvre at the steps from c₂'s first violation
on (:mod:`.evasive`), whether its actual motion over the following ρ matched one of them, and the verdict.

An episode is not known to end in a collision while it lasts, so the evaluation is retrospective: every step keeps
only what the legality needs for the episodes that would be asked (:class:`~.evasive_steps.AskedStep`) and every
car's accelerations, for the last ``lookback_s`` seconds; when a collision closes an asked episode, its steps within
that window are evaluated and matched, as they would have been step by step. Memory grows with traffic x window.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields

import numpy as np

from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .evasive import N_CANDIDATES, Candidates, candidate_motion
from .evasive_steps import AskedStep, StepMotion, asked_step, legal_at
from .params import EvasiveParams, RssParamArrays
from .records import EVASIVE_CONSTRAINT
from .responsibility import ResponsibilityTracker
from .situations import FIRST_INTERSECTION_CODE, SITUATION_CODES, PairSituations, VehicleFrame
from .sorted_keys import find_sorted

TIME_EPS = 1e-9  # [s]
ROAD_SITUATIONS = frozenset(s.value for s in SITUATION_CODES[:FIRST_INTERSECTION_CODE])


@dataclass
class _Windows:
    """Matching windows of one episode: c₁'s legal candidates at t₀ and how far its motion since is from each."""

    t0: np.ndarray
    t_end: np.ndarray  # t₀ + ρ of c₁
    v0: np.ndarray
    u0: np.ndarray
    cap: np.ndarray
    half_lane: np.ndarray
    back: np.ndarray
    lon: np.ndarray  # [w, 12] commanded accelerations [m/s²]
    lat: np.ndarray
    legal: np.ndarray  # [w, 12]
    excess: np.ndarray  # [w, 12] largest |actual − planned| acceleration minus the tolerance so far [m/s²]
    steps: np.ndarray  # observed steps
    lon_sum: np.ndarray  # sum of c₁'s longitudinal accelerations over them [m/s²]

    @classmethod
    def empty(cls) -> _Windows:
        z, zc = np.zeros(0), np.zeros((0, N_CANDIDATES))
        return cls(z, z, z, z, z, z, z, zc, zc, np.zeros((0, N_CANDIDATES), bool), zc, np.zeros(0, np.int64), z)

    @classmethod
    def at(cls, t0: float, rho: float, cand: Candidates, legal: np.ndarray) -> _Windows:
        """The window of candidates ``cand`` (one car) found at ``t0`` [s], ``legal`` [1, 12]."""
        one = np.ones(1)
        return cls(one * t0, one * (t0 + rho), cand.v[:, 0, 0], cand.u[:, 0, 0], cand.speed_cap, cand.half_lane,
                   cand.lat_back, cand.lon_accel, cand.lat_accel, legal, np.full((1, N_CANDIDATES), -np.inf),
                   np.zeros(1, np.int64), np.zeros(1))

    def take(self, index: np.ndarray) -> _Windows:
        return _Windows(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def extend(self, other: _Windows) -> _Windows:
        return _Windows(**{f.name: np.concatenate([getattr(self, f.name), getattr(other, f.name)])
                           for f in fields(self)})

    def __len__(self) -> int:
        return len(self.t0)


@dataclass
class _Verdict:
    """What the windows of one episode add up to (Def. 13)."""

    role: str = ""  # c₁'s role (violations.csv), at its first step with a legal manoeuvre
    followed: bool = False  # c₁ followed a legal manoeuvre over ρ at least once
    first_legal: float = np.nan  # [s] the first / last step with a legal manoeuvre whose ρ was (partly) observed
    last_legal: float = np.nan
    fail_t0: float = -np.inf  # [s] the latest such step whose manoeuvres c₁ did not follow, with the legal one
    fail_bound: float = np.nan  # nearest to what it did: its longitudinal acceleration [m/s²], c₁'s mean one over
    fail_actual: float = np.nan  # the window and the largest acceleration mismatch beyond the tolerance [m/s²]
    fail_excess: float = np.nan

    def fold(self, w: _Windows) -> None:
        """Fold the finished windows ``w``; a manoeuvre found at the last observed step cannot be judged."""
        w = w.take(np.flatnonzero(w.steps > 0))
        if not len(w):
            return
        matched = w.legal & (w.excess <= 0.0)
        self.followed |= bool(matched.any())
        self.first_legal = float(np.fmin(self.first_legal, w.t0.min()))
        self.last_legal = float(np.fmax(self.last_legal, w.t0.max()))
        failed = np.flatnonzero(~matched.any(axis=1))
        if failed.size:
            last = failed[np.argmax(w.t0[failed])]
            if w.t0[last] > self.fail_t0:
                best = int(np.argmin(np.where(w.legal[last], w.excess[last], np.inf)))
                self.fail_t0, self.fail_bound = float(w.t0[last]), float(w.lon[last, best])
                self.fail_actual = float(w.lon_sum[last] / w.steps[last])
                self.fail_excess = float(w.excess[last, best])


def shortfall(actual: np.ndarray, planned: np.ndarray) -> np.ndarray:
    """[m/s²] how far an acceleration falls short of a candidate's planned one in its direction: braking at least as
    hard as a braking candidate (accelerating at least as hard as an accelerating one) follows it, a zero candidate
    is followed within ±0 (the caller's tolerance); ≤ 0 where followed."""
    return np.where(planned < 0.0, actual - planned, np.where(planned > 0.0, planned - actual, np.abs(actual)))


class Rule5Tracker:
    """Rule 5 of one run; :meth:`step` after the responsibility tracker's step, :meth:`close` (its close hook)
    for every closed episode record."""

    def __init__(self, network: RoadNetwork, params: EvasiveParams | None = None):
        self.network = network
        self.params = params or EvasiveParams()
        self._motion: deque[StepMotion] = deque()  # the look-back window's steps, oldest first
        self._asked: deque[AskedStep | None] = deque()  # in step with _motion
        # Joinable closed episodes with a responsible car (sorted by serial): which car was responsible in them,
        # until when they may go on; those closed since the last step wait in _closed (serial, a, b, expiry).
        self._prior_serial = np.zeros(0, np.int64)
        self._prior = np.zeros((0, 2), bool)
        self._prior_expiry = np.zeros(0)
        self._closed: list[tuple[int, bool, bool, float]] = []
        self._parts: deque[tuple[float, int]] = deque()  # (time, serial) of their closes within the window
        self._prev_uid = np.zeros(0, np.int64)  # sorted
        self._prev_lat = np.zeros(0)
        self._prev_time: float | None = None

    # ---------------------------------------------------------------------------------------------------------
    def step(self, snapshot: WorldSnapshot, uids: np.ndarray, frame: VehicleFrame, situations: PairSituations,
             keys: np.ndarray, tracker: ResponsibilityTracker, params: RssParamArrays, tolerance: float) -> None:
        """Keep step ``snapshot.time``: the cars' accelerations and the record of the episodes that would be asked
        (``tracker``'s open ones, after its step) with the pairs' ``situations`` (``keys`` per row)."""
        if not self.params.enabled:
            return
        t = snapshot.time
        order = np.argsort(uids)
        lat_accel = np.zeros(len(snapshot))
        if self._prev_time is not None and len(self._prev_uid):  # (a step before may have had no vehicle)
            seen, pos = find_sorted(self._prev_uid, uids)
            lat_accel = np.where(seen, (snapshot.lat_speed - self._prev_lat[pos]) / (t - self._prev_time), 0.0)
        oldest = t - self.params.lookback_s - TIME_EPS
        while self._motion and self._motion[0].time < oldest:
            self._motion.popleft()
            self._asked.popleft()
        while self._parts and self._parts[0][0] < oldest:
            self._parts.popleft()
        self._update_priors(t, tracker.open.serial)
        self._motion.append(StepMotion(t, uids[order], snapshot.accel[order].copy(), lat_accel[order], tolerance))
        self._asked.append(asked_step(snapshot, uids, frame, situations, keys, tracker, params,
                                      (self._prior_serial, self._prior)))
        self._prev_uid, self._prev_lat, self._prev_time = uids[order], snapshot.lat_speed[order].copy(), t

    def close(self, record: dict, joinable: bool, window: float, time: float) -> list[dict]:
        """Fill ``record``'s rule-5 fields (a closed, possibly joined, episode) and return its evasive-effort
        violation row (none, or one)."""
        if not self.params.enabled:
            return []
        serial = int(record["serial"])
        sides = {"a": 0, "b": 1}
        asked = record["responsible"] in sides and record["situation"] in ROAD_SITUATIONS and bool(record["collision"])
        c1_side = 1 - sides.get(record["responsible"], 0)
        verdict = self._replay(serial, c1_side) if asked else _Verdict()
        legal = np.isfinite(verdict.last_legal)
        failed = asked and legal and not verdict.followed
        c1 = record["vehicle_a"] if c1_side == 0 else record["vehicle_b"]
        record.update(evasive_checked=asked, evasive_last_s=verdict.last_legal if asked else np.nan,
                      rule5_responsible=c1 if failed else "")
        if joinable and record["responsible"] != "none":
            self._closed.append((serial, record["responsible"] in ("a", "both"), record["responsible"] in ("b", "both"),
                                 time + window))
            self._parts.append((time, serial))
        if not failed:
            return []
        return [{"run_id": record["run_id"], "episode_key": record["episode_key"], "vehicle_id": c1,
                 "vehicle_class": record["class_a"] if c1_side == 0 else record["class_b"], "role": verdict.role,
                 "constraint": EVASIVE_CONSTRAINT, "bound": verdict.fail_bound, "worst_actual": verdict.fail_actual,
                 "excess": verdict.fail_excess, "t_start_s": verdict.first_legal, "t_end_s": verdict.last_legal}]

    # ---------------------------------------------------------------------------------------------------------
    def _update_priors(self, t: float, open_serials: np.ndarray) -> None:
        """Merge the episodes closed since the last step into the priors (a later close of a serial replaces an
        earlier one) and forget those that can no longer go on."""
        if self._closed:
            serials, a, b, expiries = zip(*self._closed)
            self._closed = []
            serial = np.concatenate([self._prior_serial, np.array(serials, np.int64)])
            prior = np.concatenate([self._prior, np.column_stack([a, b]).astype(bool)])
            expiry = np.concatenate([self._prior_expiry, np.array(expiries, float)])
            order = np.argsort(serial, kind="stable")
            last = order[np.r_[serial[order][1:] != serial[order][:-1], True]]
            self._prior_serial, self._prior, self._prior_expiry = serial[last], prior[last], expiry[last]
        keep = self._prior_expiry >= t - TIME_EPS
        if not keep.all():
            keep[~keep] = np.isin(self._prior_serial[~keep], open_serials)
            self._prior_serial, self._prior, self._prior_expiry = (x[keep] for x in (self._prior_serial, self._prior,
                                                                                     self._prior_expiry))

    def _replay(self, serial: int, c1_side: int) -> _Verdict:
        """The verdict of the collided episode ``serial`` over the kept steps, in the order the auditor met them:
        at each step, the windows of an earlier part that closed then are folded, the open windows are matched
        with c₁'s accelerations, those past ρ folded, and a new window opens where a legal manoeuvre exists; the
        collision, after the step, folds the rest."""
        verdict, windows = _Verdict(), _Windows.empty()
        steps = [(motion, asked, np.flatnonzero(asked.serial == serial) if asked is not None else np.zeros(0, int))
                 for motion, asked in zip(self._motion, self._asked)]
        c1 = [asked.c1_uid[k[0]] for _, asked, k in steps if k.size and asked.c1_side[k[0]] == c1_side]
        if not c1:  # not asked within the look-back window
            return verdict
        parts = [time for time, s in self._parts if s == serial]
        prev = None
        for motion, asked, k in steps:
            t = motion.time
            if any(abs(t - time) < TIME_EPS for time in parts):  # closed in the tracker's step, before rule 5's
                verdict.fold(windows)
                windows = _Windows.empty()
            if len(windows):
                windows = _match(windows, verdict, motion, c1[0], t - prev)
            done = windows.t_end <= t + TIME_EPS
            verdict.fold(windows.take(np.flatnonzero(done)))
            windows = windows.take(np.flatnonzero(~done))
            if k.size and asked.c1_side[k[0]] == c1_side:
                found = legal_at(asked, int(k[0]), self.network, self.params.horizon_s, motion.tolerance)
                if found is not None:
                    cand, legal, rho = found
                    windows = windows.extend(_Windows.at(t, rho, cand, legal))
                    verdict.role = verdict.role or str(asked.role[k[0]])
            prev = t
        verdict.fold(windows)
        return verdict


def _match(w: _Windows, verdict: _Verdict, motion: StepMotion, c1_uid: int, dt: float) -> _Windows:
    """Match the windows ``w`` of car ``c1_uid`` with its accelerations at step ``motion`` (``dt`` [s] after the one
    before); the car gone from the data: its windows end (folded into ``verdict``) where its data ends."""
    present, row = find_sorted(motion.uid, np.array([c1_uid]))
    if not present[0]:
        verdict.fold(w)
        return _Windows.empty()
    t = motion.time
    live = np.flatnonzero(w.t0 < t - TIME_EPS)
    if live.size:
        tau = (t - w.t0[live])[:, None, None] + np.array([-dt, 0.0])
        _, v, _, u = candidate_motion(w.v0[live], w.u0[live], w.lon[live], w.lat[live], w.cap[live],
                                      w.half_lane[live], w.back[live], tau)
        planned_lon, planned_lat = (v[..., 1] - v[..., 0]) / dt, (u[..., 1] - u[..., 0]) / dt
        r = row[0]
        miss = np.maximum(shortfall(motion.accel[r], planned_lon), shortfall(motion.lat_accel[r], planned_lat)) \
            - motion.tolerance
        w.excess[live] = np.maximum(w.excess[live], miss)
        w.steps[live] += 1
        w.lon_sum[live] += motion.accel[r]
    return w
