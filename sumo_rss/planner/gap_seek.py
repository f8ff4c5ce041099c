"""Gap seeking for a held discretionary lane change (docs/planner.md, "The discretionary overtake seeks its gap"):
whether, at constant speeds, a gap in the target lane lines up beside the ego RSS-safe for the change before the
lane-change context expires, and the highest ego speed at which one does. The RSS distances are the auditor's
(:func:`~sumo_rss.rss.formulas.lon_safe_distance_same_dir`), with the virtual barrier's look-ahead (the gap must stay
safe ``commit_time`` s at constant speeds, :func:`.behavior.lane_change.lane_change_command`). Units: m, s, m/s."""
from __future__ import annotations

import numpy as np

from ..rss import formulas
from ..rss.params import PARAM_NAMES, RssParamArrays
from .behavior.dcp_tree import Lat
from .behavior.evaluation import TARGET_CHAIN
from .behavior.forward_sim import Vehicles

# [m/s] The seeking ego's speeds are tried from its own speed down by this step, at most navigation.SEEK_SLOWER below.
SEEK_SPEED_STEP = 1.0


def line_up_speed(vehicles: Vehicles, params: RssParamArrays, direction: Lat, within: float, slower: float,
                  commit_time: float, seen_behind: float) -> float | None:
    """[m/s] The highest ego speed u (column 0 of ``vehicles``; tried from its speed down to ``slower`` below it in
    SEEK_SPEED_STEP steps) at which, all at constant speeds, a gap between two consecutive cars of the target lane
    towards ``direction`` (or ahead of its frontmost known car) lines up beside the ego RSS-safe for the change
    within ``within`` [s]. None: no gap lines up in time at any of them, or one is safe now at
    the ego's speed (the change is then held by something else this test does not see). ``params``: every
    vehicle column's RSS parameters; ``commit_time`` [s]: the barrier's look-ahead. ``vehicles`` holds every car seen
    within ``seen_behind`` [m] behind the ego's centre; beyond it a car may come at the speed of the fastest seen in
    the target lane (the worst case consistent with what is seen): one is assumed just there (with the rearmost seen
    car's RSS parameters), so a gap behind the rearmost seen car is only as long as the rest of the seeing range.

    A gap (front car F, rear car R) is safe at t where the ego's bumper gap to F is at least d_min(u, v_F) and R's
    to the ego at least d_min(v_R, u), each less what closes in ``commit_time``; both gaps change linearly in t,
    so the safe times are one interval, [t_early, t_late]."""
    if within <= 0.0:
        return None
    target = np.flatnonzero(vehicles.chain[1:] == TARGET_CHAIN[direction]) + 1
    if not target.size:
        return None
    cars = target[np.argsort(vehicles.s[target], kind="stable")]
    beyond = _with_car_beyond(vehicles, cars, seen_behind)
    vehicles, params = beyond, RssParamArrays(*(np.append(getattr(params, name), getattr(params, name)[cars[0]])
                                                for name in PARAM_NAMES))
    # Gaps k = 0..m: rear car cars[k-1] (k = 0: the one assumed beyond the seeing range), front car cars[k] (none for
    # k = m).
    rear = np.concatenate([[len(vehicles) - 1], cars])
    front = np.concatenate([cars, [-1]])
    u = vehicles.speed[0] - np.arange(0.0, slower + 1e-9, SEEK_SPEED_STEP)
    u = u[u >= 0.0][None, :]  # [1, U]
    half_ego = 0.5 * vehicles.length[0]
    ego = _rows(params, np.zeros(rear.size, dtype=int))
    t_early = np.zeros((rear.size, u.shape[1]))
    t_late = np.full_like(t_early, np.inf)
    for col, is_front in ((front, True), (rear, False)):
        has = col >= 0
        j = np.where(has, col, 0)
        v_o = vehicles.speed[j][:, None]
        gap0 = (vehicles.s[j] - vehicles.s[0]) * (1.0 if is_front else -1.0) - 0.5 * vehicles.length[j] - half_ego
        other = _rows(params, j)
        if is_front:
            need = formulas.lon_safe_distance_same_dir(u, v_o, ego, other) + np.maximum(u - v_o, 0.0) * commit_time
            rate = v_o - u  # the front gap opens at v_F − u
        else:
            need = formulas.lon_safe_distance_same_dir(v_o, u, other, ego) + np.maximum(v_o - u, 0.0) * commit_time
            rate = u - v_o
        short = need + formulas.SAFE_DISTANCE_PRECISION - gap0[:, None]  # [m] still missing now (<= 0: safe now)
        with np.errstate(divide="ignore", invalid="ignore"):
            when = short / rate
        opening = rate > 0.0
        early = np.where(opening, when, np.where(short < 0.0, 0.0, np.inf))
        late = np.where(rate < 0.0, when, np.where(opening | (short < 0.0), np.inf, -np.inf))
        t_early = np.where(has[:, None], np.maximum(t_early, early), t_early)
        t_late = np.where(has[:, None], np.minimum(t_late, late), t_late)
    t_early = np.maximum(t_early, 0.0)
    lines_up = (t_early <= t_late) & (t_early <= within)
    if np.any(lines_up[:, 0] & (t_early[:, 0] == 0.0)):
        return None
    ok = np.flatnonzero(np.any(lines_up, axis=0))
    return float(u[0, ok[0]]) if ok.size else None


def _with_car_beyond(vehicles: Vehicles, cars: np.ndarray, seen_behind: float) -> Vehicles:
    """``vehicles`` and one more column: a car ``seen_behind`` [m] behind the ego's centre at the speed of the
    fastest of the target lane's ``cars`` (sorted by s), as long as the rearmost of them (and behind it)."""
    last = cars[0]
    extra = {"s": min(vehicles.s[0] - seen_behind, vehicles.s[last] - vehicles.length[last]),
             "speed": float(np.max(vehicles.speed[cars])), "length": vehicles.length[last],
             "width": vehicles.width[last], "chain": vehicles.chain[last]}
    return Vehicles(**{name: np.append(value, extra.get(name, 0.0)) for name, value in vars(vehicles).items()})


def _rows(params: RssParamArrays, index: np.ndarray) -> RssParamArrays:
    """Rows ``index`` of ``params`` as a column ([k, 1] fields) that broadcasts against [k, U] speeds."""
    return RssParamArrays(*(getattr(params, name)[index][:, None] for name in PARAM_NAMES))
