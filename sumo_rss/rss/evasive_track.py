"""Rule 5 over a run (rss.md §8): at every step, for each open road episode in which exactly one car (c₂) has broken
its proper response, whether the other car (c₁) had a legal evasive manoeuvre (:mod:`.evasive`); over the following
ρ of c₁, whether its actual motion matched one of them; at the episode's end, the verdict.

State is one struct of arrays per kind — the episodes asked so far (by serial) and the open matching windows (one per
step with a legal manoeuvre, ρ long) — updated with array operations over all of them at once.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .evasive import (N_CANDIDATES, OPPOSITE_CODE, Candidates, PairRows, candidate_motion, candidates, collides,
                      dangerous_at_end, grid, on_drivable_lanes, owed_to_others)
from .params import EvasiveParams, RssParamArrays
from .records import EVASIVE_CONSTRAINT
from .responsibility import ResponsibilityTracker
from .sorted_keys import find_sorted
from .situations import FIRST_INTERSECTION_CODE, SITUATION_CODES, PairSituations, VehicleFrame

TIME_EPS = 1e-9  # [s]
ROAD_SITUATIONS = frozenset(s.value for s in SITUATION_CODES[:FIRST_INTERSECTION_CODE])


@dataclass
class _Soa:
    """A struct of arrays whose fields share their first axis."""

    def take(self, index: np.ndarray):
        return type(self)(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def extend(self, other) -> None:
        for f in fields(self):
            setattr(self, f.name, np.concatenate([getattr(self, f.name), getattr(other, f.name)]))

    def __len__(self) -> int:
        return len(getattr(self, fields(self)[0].name))


@dataclass
class _Asked(_Soa):
    """The episodes asked so far, sorted by serial."""

    serial: np.ndarray
    c1_side: np.ndarray  # 0: c₁ is car a, 1: car b
    c1_role: np.ndarray  # object: c₁'s role in the episode (violations.csv)
    prior: np.ndarray  # [n, 2] bool: responsible in the episode's earlier parts (joined episodes)
    followed: np.ndarray  # c₁ followed a legal manoeuvre over ρ at least once
    first_legal: np.ndarray  # [s] the first / last step with a legal manoeuvre whose ρ was (partly) observed
    last_legal: np.ndarray
    fail_t0: np.ndarray  # [s] the latest such step whose manoeuvres c₁ did not follow, with the legal one nearest
    fail_bound: np.ndarray  # to what it did: its longitudinal acceleration [m/s²], c₁'s mean one over the window,
    fail_actual: np.ndarray  # and the largest acceleration mismatch beyond the tolerance [m/s²]
    fail_excess: np.ndarray
    expiry: np.ndarray  # [s] closed: forgotten after this (inf while open)

    @classmethod
    def empty(cls, n: int = 0) -> _Asked:
        nan = np.full(n, np.nan)
        return cls(np.zeros(n, np.int64), np.zeros(n, np.int8), np.zeros(n, object), np.zeros((n, 2), bool),
                   np.zeros(n, bool), nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy(), nan.copy(),
                   np.full(n, np.inf))


@dataclass
class _Windows(_Soa):
    """Open matching windows: the legal candidates of c₁ (by uid) at t₀, how far its motion since is from each."""

    serial: np.ndarray
    uid: np.ndarray
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
    folded: np.ndarray  # its episode closed: already folded into it

    @classmethod
    def empty(cls) -> _Windows:
        z, zc = np.zeros(0), np.zeros((0, N_CANDIDATES))
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), z, z, z, z, z, z, z, zc, zc,
                   np.zeros((0, N_CANDIDATES), bool), zc, np.zeros(0, np.int64), z, np.zeros(0, bool))


def shortfall(actual: np.ndarray, planned: np.ndarray) -> np.ndarray:
    """[m/s²] how far an acceleration falls short of a candidate's planned one in its direction: braking at least as
    hard as a braking candidate (accelerating at least as hard as an accelerating one) follows it, a zero candidate
    is followed within ±0 (the caller's tolerance); ≤ 0 where followed."""
    return np.where(planned < 0.0, actual - planned, np.where(planned > 0.0, planned - actual, np.abs(actual)))


def _expand(values: np.ndarray, queries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(query index, index into ``values``) of every element of ``values`` equal to each query (any order)."""
    order = np.argsort(values, kind="stable")
    lo = np.searchsorted(values[order], queries, side="left")
    hi = np.searchsorted(values[order], queries, side="right")
    count = hi - lo
    q = np.repeat(np.arange(len(queries)), count)
    start = np.repeat(lo - np.cumsum(count) + count, count)
    return q, order[np.arange(count.sum()) + start]


class Rule5Tracker:
    """Rule 5 of one run; :meth:`step` after the responsibility tracker's step, :meth:`close` (its close hook)
    for every closed episode record."""

    def __init__(self, network: RoadNetwork, params: EvasiveParams | None = None):
        self.network = network
        self.params = params or EvasiveParams()
        self._asked = _Asked.empty()
        self._windows = _Windows.empty()
        self._prev_uid = np.zeros(0, np.int64)  # sorted
        self._prev_lat = np.zeros(0)
        self._prev_time: float | None = None

    # ---------------------------------------------------------------------------------------------------------
    def step(self, snapshot: WorldSnapshot, uids: np.ndarray, frame: VehicleFrame, situations: PairSituations,
             keys: np.ndarray, tracker: ResponsibilityTracker, params: RssParamArrays, tolerance: float) -> None:
        """Judge step ``snapshot.time``: match the open windows with the cars' accelerations, then ask the open
        episodes (``tracker``'s, after its step) with the pairs' ``situations`` (``keys`` per row)."""
        if not self.params.enabled:
            return
        t = snapshot.time
        lat_accel = np.zeros(len(snapshot))
        if self._prev_time is not None:
            seen, pos = find_sorted(self._prev_uid, uids)
            lat_accel = np.where(seen, (snapshot.lat_speed - self._prev_lat[pos]) / (t - self._prev_time), 0.0)
            self._match(t, t - self._prev_time, snapshot, uids, lat_accel, tolerance)
        self._finish(self._windows.t_end <= t + TIME_EPS)
        open_serials = np.sort(tracker.open.serial)
        self._asked = self._asked.take(np.flatnonzero((self._asked.expiry >= t - TIME_EPS) |
                                                      find_sorted(open_serials, self._asked.serial)[0]))
        self._ask(t, snapshot, uids, frame, situations, keys, tracker, params, tolerance)
        order = np.argsort(uids)
        self._prev_uid, self._prev_lat, self._prev_time = uids[order], snapshot.lat_speed[order], t

    def close(self, record: dict, joinable: bool, window: float, time: float) -> list[dict]:
        """Fill ``record``'s rule-5 fields (a closed, possibly joined, episode) and return its evasive-effort
        violation row (none, or one)."""
        if not self.params.enabled:
            return []
        serial = np.int64(record["serial"])
        w = self._windows
        ended = np.flatnonzero((w.serial == serial) & ~w.folded)  # dropped at the next step (one copy per step)
        self._fold(w.take(ended))
        w.folded[ended] = True
        found, pos = find_sorted(self._asked.serial, np.array([serial]))
        k = int(pos[0]) if found[0] else None
        sides = {"a": 0, "b": 1}
        margin = float(np.fmin(record["min_lon_margin_m"], record["min_lat_margin_m"]))
        asked = record["responsible"] in sides and record["situation"] in ROAD_SITUATIONS and \
            (bool(record["collision"]) or margin < -self.params.margin_m)
        c1_side = 1 - sides.get(record["responsible"], 0)
        s = self._asked
        legal = k is not None and int(s.c1_side[k]) == c1_side and np.isfinite(s.last_legal[k])
        failed = asked and legal and not s.followed[k]
        c1 = record["vehicle_a"] if c1_side == 0 else record["vehicle_b"]
        record.update(evasive_checked=asked, evasive_last_s=float(s.last_legal[k]) if asked and legal else np.nan,
                      rule5_responsible=c1 if failed else "")
        rows = []
        if failed:
            rows.append({"run_id": record["run_id"], "episode_key": record["episode_key"], "vehicle_id": c1,
                         "vehicle_class": record["class_a"] if c1_side == 0 else record["class_b"],
                         "role": s.c1_role[k], "constraint": EVASIVE_CONSTRAINT, "bound": float(s.fail_bound[k]),
                         "worst_actual": float(s.fail_actual[k]), "excess": float(s.fail_excess[k]),
                         "t_start_s": float(s.first_legal[k]), "t_end_s": float(s.last_legal[k])})
        if k is not None:
            s.prior[k] = [record["responsible"] in ("a", "both"), record["responsible"] in ("b", "both")]
            s.expiry[k] = time + window if joinable else -np.inf
        return rows

    # ---------------------------------------------------------------------------------------------------------
    def _match(self, t: float, dt: float, snapshot: WorldSnapshot, uids: np.ndarray, lat_accel: np.ndarray,
               tolerance: float) -> None:
        w = self._windows
        if not len(w):
            return
        present, row = find_sorted(np.sort(uids), w.uid)
        row = np.argsort(uids)[row]
        live = np.flatnonzero(present & (w.t0 < t - TIME_EPS) & ~w.folded)
        if live.size:
            tau = (t - w.t0[live])[:, None, None] + np.array([-dt, 0.0])
            _, v, _, u = candidate_motion(w.v0[live], w.u0[live], w.lon[live], w.lat[live], w.cap[live],
                                          w.half_lane[live], w.back[live], tau)
            planned_lon, planned_lat = (v[..., 1] - v[..., 0]) / dt, (u[..., 1] - u[..., 0]) / dt
            r = row[live]
            miss = np.maximum(shortfall(snapshot.accel[r][:, None], planned_lon),
                              shortfall(lat_accel[r][:, None], planned_lat)) - tolerance
            w.excess[live] = np.maximum(w.excess[live], miss)
            w.steps[live] += 1
            w.lon_sum[live] += snapshot.accel[r]
        self._finish(~present)  # c₁ left the data: its windows end where its data ends

    def _finish(self, mask: np.ndarray) -> None:
        """Fold the windows ``mask`` into their episodes and drop them (with those folded at a close)."""
        if not np.any(mask) and not self._windows.folded.any():
            return
        w = self._windows.take(np.flatnonzero(mask & ~self._windows.folded))
        self._windows = self._windows.take(np.flatnonzero(~mask & ~self._windows.folded))
        self._fold(w)

    def _fold(self, w: _Windows) -> None:
        """Fold the windows ``w`` into their episodes."""
        judged = w.steps > 0  # a manoeuvre found at the last observed step cannot be judged
        w = w.take(np.flatnonzero(judged))
        found, k = find_sorted(self._asked.serial, w.serial)
        w, k = w.take(np.flatnonzero(found)), k[found]
        if not len(w):
            return
        s = self._asked
        matched = w.legal & (w.excess <= 0.0)
        np.logical_or.at(s.followed, k, matched.any(axis=1))
        np.fmin.at(s.first_legal, k, w.t0)
        np.fmax.at(s.last_legal, k, w.t0)
        failed = np.flatnonzero(~matched.any(axis=1))
        if failed.size:
            order = failed[np.lexsort((w.t0[failed], k[failed]))]
            last = order[np.r_[k[order][1:] != k[order][:-1], True]]  # the latest failed window per episode
            newer = w.t0[last] > np.nan_to_num(s.fail_t0[k[last]], nan=-np.inf)
            last = last[newer]
            best = np.argmin(np.where(w.legal[last], w.excess[last], np.inf), axis=1)
            s.fail_t0[k[last]] = w.t0[last]
            s.fail_bound[k[last]] = w.lon[last, best]
            s.fail_actual[k[last]] = w.lon_sum[last] / w.steps[last]
            s.fail_excess[k[last]] = w.excess[last, best]

    def _ask(self, t: float, snapshot: WorldSnapshot, uids: np.ndarray, frame: VehicleFrame, sit: PairSituations,
             keys: np.ndarray, tracker, params: RssParamArrays, tolerance: float) -> None:
        e = tracker.open
        if not len(e) or not len(sit):
            return
        known, at = find_sorted(self._asked.serial, e.serial)
        prior = np.zeros(e.responsible.shape, dtype=bool)
        prior[known] = self._asked.prior[at[known]]
        resp = e.responsible | prior
        order = np.argsort(keys, kind="stable")
        present, pos = find_sorted(keys[order], e.keys)
        ask = np.flatnonzero((resp.sum(axis=1) == 1) & (e.kind < FIRST_INTERSECTION_CODE) & present)
        if not ask.size:
            return
        target = order[pos[ask]]  # situation rows
        c1_side = resp[ask, 0].astype(np.int8)  # c₂ is a → c₁ is b
        c1 = np.where(c1_side == 0, sit.a[target], sit.b[target])
        # The cheap tests first, each on the asked cars that still have a legal candidate: the pair at t₀ + T (the
        # candidates' end states only), then on the time grid the drivable band, the contact with c₂ and with the
        # other road users around c₁, and the responses c₁ owes them.
        net, horizon = self.network, self.params.horizon_s
        ends = self._candidates(snapshot, frame, params, c1, np.array([0.0, horizon]))
        rows = self._rows(sit, frame, snapshot, params, target, c1, np.arange(ask.size))
        some = np.flatnonzero(~dangerous_at_end(ends, rows).all(axis=1))
        if not some.size:
            return
        ask, c1_side, c1, target = ask[some], c1_side[some], c1[some], target[some]
        cand = self._candidates(snapshot, frame, params, c1, grid(horizon))
        rows = replace(rows.take(some), q=np.arange(some.size))
        lane = frame.lane[c1]
        legal = ~dangerous_at_end(cand, rows)
        legal &= on_drivable_lanes(cand, frame.d[c1], frame.half_lat[c1], self._room(lane, net.lane_left),
                                   self._room(lane, net.lane_right))
        live = np.flatnonzero(legal.any(axis=1))
        legal[live] &= ~collides(cand, rows.take(live))
        live = np.flatnonzero(legal.any(axis=1))
        # (d) every other road user around c₁ (within reach over the horizon) on its naive prediction.
        road = np.flatnonzero(sit.kind < FIRST_INTERSECTION_CODE)
        q, j = _expand(np.concatenate([sit.a[road], sit.b[road]]), c1[live])
        q, row = live[q], np.concatenate([road, road])[j]
        keep = row != target[q]
        if keep.any():
            others = self._rows(sit, frame, snapshot, params, row[keep], c1[q[keep]], q[keep])
            others = others.take(np.flatnonzero(~others.beyond_reach(cand)))
            bad = np.zeros(legal.shape, dtype=bool)
            np.logical_or.at(bad, others.q, collides(cand, others))
            legal &= ~bad
        legal[live] &= self._owed(cand, tracker, e, ask[live], uids[c1[live]], tolerance, live)
        self._remember(t, e, ask, c1_side, uids[c1], cand, legal, params.response_time[c1])

    def _candidates(self, snapshot: WorldSnapshot, frame: VehicleFrame, params: RssParamArrays, c1: np.ndarray,
                    times: np.ndarray) -> Candidates:
        """The candidates of the cars ``c1`` (snapshot rows) at ``times`` [s]."""
        lane = frame.lane[c1]
        return candidates(snapshot.speed[c1], snapshot.lat_speed[c1], params.take(c1), self.network.lane_speed[lane],
                          0.5 * self.network.lane_width[lane], times)

    def _rows(self, sit: PairSituations, frame: VehicleFrame, snapshot: WorldSnapshot, params: RssParamArrays,
              rows: np.ndarray, c1: np.ndarray, q: np.ndarray) -> PairRows:
        """The pair rows ``rows`` of ``sit`` seen from car ``c1`` (snapshot rows, one per row; asked index ``q``)."""
        a, b = sit.a[rows], sit.b[rows]
        c1_is_a = a == c1
        other = np.where(c1_is_a, b, a)
        b_minus_a = np.where(sit.a_is_rear[rows], 1.0, -1.0) * (sit.lon_gap[rows] + frame.half_lon[a] +
                                                                frame.half_lon[b])
        b_minus_a_lat = np.where(sit.a_is_left[rows], -1.0, 1.0) * (sit.lat_gap[rows] + frame.half_lat[a] +
                                                                    frame.half_lat[b])
        flip = np.where(c1_is_a, 1.0, -1.0)
        opposite = sit.kind[rows] == OPPOSITE_CODE
        dir_a = np.where(opposite & ~sit.a_is_rear[rows], -1.0, 1.0)
        dir_b = np.where(opposite, -dir_a, 1.0)
        wrong = (sit.wrong_way_a[rows], sit.wrong_way_b[rows]) if sit.wrong_way_a is not None else \
            (np.zeros(len(rows), bool),) * 2
        p1, po = params.take(c1), params.take(other)
        w1, wo = np.where(c1_is_a, wrong[0], wrong[1]), np.where(c1_is_a, wrong[1], wrong[0])
        return PairRows(
            q=q, dx=flip * b_minus_a, dy=flip * b_minus_a_lat, dir_c1=np.where(c1_is_a, dir_a, dir_b),
            dir_o=np.where(c1_is_a, dir_b, dir_a), half_lon=frame.half_lon[a] + frame.half_lon[b],
            half_lat=frame.half_lat[a] + frame.half_lat[b], v_o=snapshot.speed[other], a_o=snapshot.accel[other],
            u_o=snapshot.lat_speed[other], opposite=opposite, p_c1=p1, p_o=po,
            brake_c1=np.where(w1, p1.lon_brake_min, p1.lon_brake_min_correct),
            brake_o=np.where(wo, po.lon_brake_min, po.lon_brake_min_correct))

    def _room(self, lane: np.ndarray, beside: np.ndarray) -> np.ndarray:
        """[m] drivable width from a lane's centre line to the far side of the lane ``beside`` it (or its own
        border where there is none)."""
        net = self.network
        other = beside[lane]
        return 0.5 * net.lane_width[lane] + np.where(other >= 0, net.lane_width[np.maximum(other, 0)], 0.0)

    @staticmethod
    def _owed(cand: Candidates, tracker, e, ask: np.ndarray, c1_uid: np.ndarray, tolerance: float,
              rows: np.ndarray) -> np.ndarray:
        """Legality (a) of the asked episodes ``ask`` (candidate rows ``rows``): the bounds of this step in c₁'s
        other open episodes."""
        n = len(e)
        q, j = _expand(np.concatenate([e.uids[:, 0], e.uids[:, 1]]), c1_uid)
        episode, side = j % n, j // n
        keep = episode != ask[q]
        q, episode, side = q[keep], episode[keep], side[keep]
        judged = tracker.judged
        accel_max, accel_min = np.full(q.size, np.nan), np.full(q.size, np.nan)
        if judged is not None and len(judged.serial) and q.size:
            by_serial = np.argsort(judged.serial)
            found, at = find_sorted(judged.serial[by_serial], e.serial[episode])
            at = by_serial[at]
            accel_max = np.where(found, judged.accel_max[at, side], np.nan)
            accel_min = np.where(found, judged.accel_min[at, side], np.nan)
        other_left = np.where(side == 0, ~e.a_left[episode], e.a_left[episode])
        towards = np.where(e.owed_lat[episode], np.where(other_left, 1.0, -1.0), 0.0)
        return owed_to_others(cand, rows, q, accel_max, accel_min, towards, tolerance)

    def _remember(self, t: float, e, ask: np.ndarray, c1_side: np.ndarray, c1_uid: np.ndarray, cand: Candidates,
                  legal: np.ndarray, rho: np.ndarray) -> None:
        """Open a window for every asked episode with a legal candidate (and its state, the first time)."""
        some = np.flatnonzero(legal.any(axis=1))
        if not some.size:
            return
        serial = e.serial[ask]
        known = find_sorted(self._asked.serial, serial[some])[0]
        if not known.all():
            new = some[~known]
            fresh = _Asked.empty(new.size)
            fresh.serial, fresh.c1_side = serial[new], c1_side[new]
            fresh.c1_role = e.roles[ask[new], c1_side[new]]
            self._asked.extend(fresh)
            self._asked = self._asked.take(np.argsort(self._asked.serial, kind="stable"))
        n = some.size
        self._windows.extend(_Windows(
            serial=serial[some], uid=c1_uid[some], t0=np.full(n, t), t_end=t + rho[some], v0=cand.v[some, 0, 0],
            u0=cand.u[some, 0, 0], cap=cand.speed_cap[some], half_lane=cand.half_lane[some],
            back=cand.lat_back[some], lon=cand.lon_accel[some], lat=cand.lat_accel[some], legal=legal[some],
            excess=np.full((n, N_CANDIDATES), -np.inf), steps=np.zeros(n, np.int64), lon_sum=np.zeros(n),
            folded=np.zeros(n, bool)))
