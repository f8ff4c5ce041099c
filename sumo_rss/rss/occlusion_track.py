"""Rule 4 over a run (rss.md §9, paper Def. 23-24): who could see whom, exposure times, and the hidden cars'
reasonable speed.

Only the pairs that are dangerous at a step (in an episode, or opening one) have their line of sight tested
(:func:`.occlusion.line_of_sight`). Per pair the state is the start of its current uninterrupted run of visibility
(+inf while hidden): the responsibility tracker starts a car's proper response at max(t_b, that time) plus its ρ
(``StepInput.seen_from``). An episode whose pair was hidden at t_b is judged for reasonable speed from t_b to the
exposure time (or to its end, if the cars never saw each other): a hidden car whose mean speed along its lane
exceeded ``speed_factor`` × the lane's limit (the lower-priority car of a junction pair within ``yield_zone_m`` of
the conflict area: ``yield_speed_ms``), or whose mean lateral speed exceeded ``lat_speed_ms``, has a violation
``occluded-unreasonable-speed`` and is responsible. Only episodes that were ever hidden are kept in the state, as
one struct of arrays, updated with array operations.
"""
from __future__ import annotations

from bisect import bisect_left
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from ..road.network import RoadNetwork
from ..sim.snapshot import WorldSnapshot
from .occlusion import OccluderEdges, OcclusionParams, line_of_sight, vtype_heights
from .records import OCCLUSION_COLUMNS, OCCLUSION_CONSTRAINT
from .responsibility import ResponsibilityTracker
from .sorted_keys import find_sorted
from .situations import PairSituations, VehicleFrame

TIME_EPS = 1e-9  # [s]
SPEED_EPS = 1e-6  # [m/s] a mean speed above its limit by more than this is unreasonable


@dataclass
class _Hidden:
    """The open episodes whose pair has been hidden at some step, sorted by serial (``[n, 2]``: car a, car b)."""

    serial: np.ndarray
    at_t_b: np.ndarray  # hidden at the danger threshold
    first_run: np.ndarray  # still in the hidden run that began at t_b (its speeds are summed)
    hidden: np.ndarray  # hidden at the last step
    exposure: np.ndarray  # [s] the start of the latest run of visibility after a hidden step (NaN: none yet)
    steps: np.ndarray  # hidden steps summed
    t_hidden: np.ndarray  # [s] the last of them
    speed: np.ndarray  # [n, 2] sums of the speed along the lane [m/s]
    limit: np.ndarray  # [n, 2] ... of the reasonable speed [m/s]
    lat: np.ndarray  # [n, 2] ... of |lateral speed| [m/s]
    roles: np.ndarray  # [n, 2] object: the cars' roles in the episode (violations.csv)
    closed: np.ndarray  # closed since the last step (dropped at the next one)

    @classmethod
    def empty(cls, n: int = 0) -> _Hidden:
        return cls(np.zeros(n, np.int64), np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool),
                   np.full(n, np.nan), np.zeros(n, np.int64), np.full(n, np.nan), np.zeros((n, 2)),
                   np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2), object), np.zeros(n, bool))

    def take(self, index: np.ndarray) -> _Hidden:
        return _Hidden(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def __len__(self) -> int:
        return int(self.serial.shape[0])


class OcclusionTracker:
    """Rule 4 of one run: :meth:`sight` before the responsibility tracker's step, :meth:`step` after it,
    :meth:`close` for every closed episode record (before rule 5's)."""

    def __init__(self, network: RoadNetwork, params: OcclusionParams | None = None,
                 heights: Mapping[str, float] | None = None, occluders: OccluderEdges | None = None):
        self.network = network
        self.params = params or OcclusionParams()
        self.heights = dict(heights or {})  # vType → height [m]
        self.occluders = occluders
        self.pair_steps = 0  # dangerous pair-steps whose cars could not see each other
        self._keys = np.zeros(0, np.int64)  # pairs with a known visibility, sorted
        self._seen_from = np.zeros(0)  # [s] start of their current run of visibility (+inf: hidden now)
        self._hidden = _Hidden.empty()
        self._verdicts: dict[int, list[dict]] = {}  # serial → unreasonable-speed rows not yet given to an episode
        self._judged: set[int] = set()  # serials of the episodes judged for reasonable speed
        self._rows: dict[str, dict] = {}  # episode key → its occlusion.csv row

    @property
    def enabled(self) -> bool:
        return self.params.enabled

    def sight(self, snapshot: WorldSnapshot, situations: PairSituations, keys: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray] | None:
        """Test the line of sight of this step's dangerous pairs; returns (sorted pair keys, start of their current
        run of visibility [s], +inf while hidden) for ``StepInput.seen_from`` (None when rule 4 is off)."""
        if not self.enabled:
            return None
        rows = np.flatnonzero(situations.dangerous)
        visible = line_of_sight(snapshot, situations.a[rows], situations.b[rows],
                                vtype_heights(snapshot, self.heights), self.params.min_height_m, self.occluders)
        self.pair_steps += int((~visible).sum())
        now = keys[rows]
        found, pos = find_sorted(self._keys, now)
        before = np.where(found, self._seen_from[pos], np.inf) if len(self._keys) else np.full(len(now), np.inf)
        seen_from = np.where(visible, np.where(np.isfinite(before), before, snapshot.time), np.inf)
        # Pairs not tested now keep their state for this step's compliance (their episodes end now).
        kept = np.ones(len(self._keys), dtype=bool)
        kept[pos[found]] = False
        merged_keys = np.concatenate([self._keys[kept], now])
        merged = np.concatenate([self._seen_from[kept], seen_from])
        order = np.argsort(merged_keys, kind="stable")
        self._keys, self._seen_from = merged_keys[order], merged[order]
        return self._keys, self._seen_from

    def step(self, snapshot: WorldSnapshot, frame: VehicleFrame, situations: PairSituations, keys: np.ndarray,
             tracker: ResponsibilityTracker) -> None:
        """After the tracker's step at ``snapshot.time``: the hidden episodes' speeds, exposures and verdicts."""
        if not self.enabled:
            return
        t = snapshot.time
        e = tracker.open
        known, pos = find_sorted(self._keys, e.keys)
        hidden_now = known & ~np.isfinite(self._seen_from[pos] if len(self._keys) else np.zeros(len(e)))
        # Only the open episodes' pairs are kept (sorted, as the episodes are).
        self._keys, self._seen_from = self._keys[pos[known]], self._seen_from[pos[known]]
        h = self._hidden
        if h.closed.any():
            h = self._hidden = h.take(np.flatnonzero(~h.closed))
        new = hidden_now & ~find_sorted(h.serial, e.serial)[0]
        if np.any(new):
            fresh = _Hidden.empty(int(new.sum()))
            fresh.serial = e.serial[new]
            fresh.at_t_b = np.abs(e.t_b[new] - t) < TIME_EPS
            # One verdict per (joined) episode: a part that re-opens hidden after a judged one is not judged again.
            fresh.first_run = fresh.at_t_b & ~np.array([s in self._judged for s in fresh.serial.tolist()], bool)
            fresh.roles = e.roles[new]
            merged = _Hidden(**{f.name: np.concatenate([getattr(h, f.name), getattr(fresh, f.name)])
                                for f in fields(h)})
            h = self._hidden = merged.take(np.argsort(merged.serial, kind="stable"))
        if not len(h):
            return
        by_serial = np.argsort(e.serial, kind="stable")  # the open episodes are sorted by pair key
        is_open, at = find_sorted(e.serial[by_serial], h.serial)
        at = by_serial[at] if len(e) else at
        hid = is_open & hidden_now[at]
        exposed = is_open & ~hid & h.hidden & known[at]
        h.exposure = np.where(exposed, t, h.exposure)
        if np.any(exposed):
            self._restart_lateral(e, at[exposed], situations, keys)
        summing = hid & h.first_run
        if np.any(summing):
            self._sum_speeds(snapshot, frame, situations, keys, e.keys[at[summing]], np.flatnonzero(summing))
        h.steps = h.steps + summing
        h.t_hidden = np.where(summing, t, h.t_hidden)
        ending = exposed & h.first_run
        for i in np.flatnonzero(ending):  # rare: episodes whose cars have just seen each other for the first time
            k = int(at[i])
            self._verdicts[int(h.serial[i])] = self._verdict_rows(
                h, int(i), (e.a_id[k], e.b_id[k]), (e.a_class[k], e.b_class[k]), float(e.t_b[k]))
        h.first_run = h.first_run & ~ending
        self._judged.update(h.serial[ending].tolist())
        h.hidden = np.where(is_open, hid, h.hidden)

    def close(self, record: dict) -> list[dict]:
        """A closed (possibly joined) episode: its unreasonable-speed rows (their cars made responsible in
        ``record``) and, if it was ever hidden, its occlusion.csv row."""
        if not self.enabled:
            return []
        serial = int(record["serial"])
        h = self._hidden
        i = bisect_left(h.serial, serial)  # one look-up: cheaper than numpy's call overhead
        rows = self._verdicts.pop(serial, [])
        if i < h.serial.size and h.serial[i] == serial and not h.closed[i]:
            if h.first_run[i]:  # hidden from t_b to its end: judged over all of it
                rows = self._verdict_rows(h, i, (record["vehicle_a"], record["vehicle_b"]),
                                          (record["class_a"], record["class_b"]), float(record["t_b_s"]))
                self._judged.add(serial)
            exposure = float(h.exposure[i])
            previous = self._rows.get(record["episode_key"])
            self._rows[record["episode_key"]] = {
                **{name: record[name] for name in OCCLUSION_COLUMNS[:7]},
                "exposure_a_s": exposure if np.isfinite(exposure) or previous is None else previous["exposure_a_s"],
                "exposure_b_s": exposure if np.isfinite(exposure) or previous is None else previous["exposure_b_s"],
                "occluded_at_t_b": bool(h.at_t_b[i]) if previous is None else previous["occluded_at_t_b"]}
            h.closed[i] = True
        for row in rows:
            row.update(run_id=record["run_id"], episode_key=record["episode_key"])
        blamed = {row["vehicle_id"] for row in rows}
        if blamed:
            was = record["responsible"]
            a = was in ("a", "both") or record["vehicle_a"] in blamed
            b = was in ("b", "both") or record["vehicle_b"] in blamed
            record["responsible"] = "both" if a and b else "a" if a else "b"
        return rows

    def frame(self) -> pd.DataFrame:
        """occlusion.csv: one row per episode that was ever hidden (OCCLUSION_COLUMNS), by t_b and pair."""
        frame = pd.DataFrame(list(self._rows.values()), columns=OCCLUSION_COLUMNS)
        return frame.sort_values(["t_b_s", "vehicle_a", "vehicle_b"], kind="stable", ignore_index=True)

    # -----------------------------------------------------------------------------------------------------
    @staticmethod
    def _restart_lateral(e, rows: np.ndarray, situations: PairSituations, keys: np.ndarray) -> None:
        """The lateral response of the open episodes ``rows`` (of ``e``, the tracker's; their pairs dangerous now)
        starts at this step, their exposure: its envelope from the lateral speeds towards the other car now."""
        order = np.argsort(keys, kind="stable")
        sit = order[np.searchsorted(keys[order], e.keys[rows])]
        left = situations.a_is_left[sit]
        e.u0[rows] = np.column_stack([np.where(left, -situations.v_lat_a[sit], situations.v_lat_a[sit]),
                                      np.where(left, situations.v_lat_b[sit], -situations.v_lat_b[sit])])
        e.lat_settled[rows] = False

    def _sum_speeds(self, snapshot: WorldSnapshot, frame: VehicleFrame, situations: PairSituations,
                    keys: np.ndarray, pair_keys: np.ndarray, hidden_rows: np.ndarray) -> None:
        """Add this step's speeds and reasonable limits of both cars to the hidden episodes ``hidden_rows``
        (their pairs ``pair_keys``, dangerous now: rows of ``situations``)."""
        p, h = self.params, self._hidden
        order = np.argsort(keys, kind="stable")
        row = order[np.searchsorted(keys[order], pair_keys)]
        cars = np.column_stack([situations.a[row], situations.b[row]])
        lane = frame.lane[cars]
        limit = p.speed_factor * np.where(lane >= 0, self.network.lane_speed[np.maximum(lane, 0)], np.inf)
        if situations.priority is not None and situations.enter_a is not None:
            priority = situations.priority[row]
            lower = np.column_stack([priority == 2, priority == 1])  # 1: a has priority, 2: b
            enter = np.column_stack([situations.enter_a[row], situations.enter_b[row]])
            near = lower & (enter <= p.yield_zone_m)  # NaN (a road situation): False
            limit = np.where(near, np.minimum(limit, p.yield_speed_ms), limit)
        h.speed[hidden_rows] += snapshot.speed[cars]
        h.limit[hidden_rows] += limit
        h.lat[hidden_rows] += np.abs(snapshot.lat_speed[cars])

    def _verdict_rows(self, h: _Hidden, i: int, ids: tuple, classes: tuple, t_b: float) -> list[dict]:
        """Rows (their run and episode keys filled at the episode's close) for the cars of hidden episode ``i``
        whose mean speed from t_b to the last hidden step exceeded the reasonable one (along the lane, else across
        it)."""
        rows: list[dict] = []
        if not h.steps[i]:
            return rows
        n = float(h.steps[i])
        for car in (0, 1):
            for actual, bound in ((h.speed[i, car] / n, h.limit[i, car] / n), (h.lat[i, car] / n,
                                                                                 self.params.lat_speed_ms)):
                if actual > bound + SPEED_EPS:
                    rows.append({"run_id": "", "episode_key": "", "vehicle_id": ids[car],
                                 "vehicle_class": classes[car], "role": h.roles[i, car],
                                 "constraint": OCCLUSION_CONSTRAINT,
                                 "bound": float(bound), "worst_actual": float(actual),
                                 "excess": float(actual - bound), "t_start_s": t_b, "t_end_s": float(h.t_hidden[i])})
                    break
        return rows
