"""The gap a held mandatory lane change aims at, and the speed that takes the ego there (docs/planner.md,
"merge_onramp: aiming at a gap"). A driver who must merge picks a gap in the target lane and adjusts its speed to
it: it speeds up to get ahead of a car or slows down to slip in behind it, rather than driving on at its own speed
until a gap happens to be beside it.

Every candidate speed u (0 to the road's reference speed) is a speed profile: from the ego's speed to u at its
acceleration or AIM_BRAKE, then constant. The target lane's cars (up to AIM_REAR_REACH behind the ego) keep their
speeds. Along each profile the ego is *in* a gap at time t where the gap is RSS-legal for it, with the auditor's
formulas (:func:`~sumo_rss.rss.formulas.lon_safe_distance_same_dir`): the gap's rear car at least d_min(v_rear,
v_ego) behind it and the ego at least d_min(v_ego, v_front) behind the gap's front car, at t and ``commit_time``
later (the virtual barrier's test, :func:`.behavior.lane_change.lane_change_command`), with its front bumper still
able to stop at its comfortable braking short of the lane end's waiting margin (the forward simulation's IDM
holds it to that). The aim is the profile whose first legal time is earliest (ties: the speed
nearest the ego's). Vectorised over [speeds, times, gaps]. Units: m, s, m/s, m/s².
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rss import formulas
from ..rss.params import RssParamArrays
from .behavior.forward_sim import Vehicles

AIM_SPEED_STEP = 1.0  # [m/s] between candidate speeds
AIM_TIME_STEP = 0.2  # [s] the forward simulation's step
AIM_HORIZON = 20.0  # [s] how far ahead a gap is looked for (a 270 m acceleration lane takes ~12-25 s)
# [m/s²] the profiles slow down at this: the forward simulation's IIDM approaches a lower desired speed at
# -b·(1 - (v0/v)^(a·δ/b)), 0.7-1.3 m/s² measured (merge_onramp seed 10), not at b = 1.67 (then the ego lagged the
# aimed profile and missed the gap)
AIM_BRAKE = 1.0
# [m] the target lane's cars are looked at this far behind the ego (the key vehicles reach only as far as a car
# could be RSS-unsafe now, ~125 m at 25 m/s: behind them a gap would look open)
AIM_REAR_REACH = 250.0


@dataclass(frozen=True)
class GapAim:
    """The aimed gap: the ego's speed ``speed`` [m/s] that makes it RSS-legal first, ``time`` [s] from now; the
    gap's rear and front cars as vehicle columns (0: none, an open end)."""

    speed: float
    time: float
    rear: int
    front: int


def aim_at_gap(vehicles: Vehicles, target: int, params: RssParamArrays, room: float, v_max: float,
               commit_time: float, accel: float, brake: float) -> GapAim | None:
    """The earliest RSS-legal gap on chain ``target`` that a speed profile of the ego (column 0 of ``vehicles``,
    ``params`` per column, the ego's as while moving) reaches within AIM_HORIZON, with its front bumper no more than
    ``room`` [m] ahead of where it is now (and able to stop within it at ``brake`` [m/s²]); speeds 0..``v_max``,
    reached at ``accel`` [m/s²] / AIM_BRAKE. None: no gap is reachable; ``time`` 0: one is legal now."""
    cars = np.flatnonzero(vehicles.chain[1:] == target) + 1
    cars = cars[np.argsort(vehicles.s[cars])]
    rear = np.concatenate([[0], cars])  # gap k lies between rear[k] and front[k]; 0: an open end
    front = np.concatenate([cars, [0]])
    v0, half = float(vehicles.speed[0]), 0.5 * float(vehicles.length[0])
    u = np.arange(0.0, max(v_max, 0.0) + 1e-9, AIM_SPEED_STEP)[:, None]  # [U, 1]
    t = np.arange(0.0, AIM_HORIZON + 1e-9, AIM_TIME_STEP)[None, :]  # [1, T]
    rate = np.where(u >= v0, accel, AIM_BRAKE)
    t_ramp = np.abs(u - v0) / rate
    ramping = t < t_ramp
    v = np.where(ramping, v0 + np.sign(u - v0) * rate * t, u)  # [U, T]
    ds = np.where(ramping, 0.5 * (v0 + v) * t, 0.5 * (v0 + u) * t_ramp + u * (t - t_ramp))
    legal = _legal(vehicles, params, rear, front, half, ds, v, t)  # [U, T, K]
    steps = int(round(commit_time / AIM_TIME_STEP))
    legal = legal[:, :legal.shape[1] - steps] & legal[:, steps:]  # legal now and commit_time later
    n = legal.shape[1]
    fits = ds[:, :n] + v[:, :n] ** 2 / (2.0 * brake) <= room  # it can still stop short of the end (now it is where
    fits[:, 0] = True  # it is)
    legal &= fits[:, :, None]
    hit = legal.any(axis=2)  # [U, T]
    if not hit.any():
        return None
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), np.iinfo(np.int64).max)
    best = np.flatnonzero(first == first.min())
    i = int(best[np.argmin(np.abs(u[best, 0] - v0))])
    k = int(np.argmax(legal[i, first[i]]))
    return GapAim(float(u[i, 0]), float(first[i]) * AIM_TIME_STEP, int(rear[k]), int(front[k]))


def _legal(vehicles: Vehicles, params: RssParamArrays, rear: np.ndarray, front: np.ndarray, half: float,
           ds: np.ndarray, v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """[U, T, K] Whether the ego, ``ds`` [U, T] ahead of where it is at speed ``v`` [U, T], is RSS-safe to gap k's
    rear car (``rear[k]``, 0: none) and front car (``front[k]``) at the times ``t`` [1, T], every car at its speed."""
    ego = params.take(np.zeros(1, dtype=int))
    s_ego = float(vehicles.s[0]) + ds[:, :, None]  # [U, T, 1]
    v_ego = v[:, :, None]
    tt = t[:, :, None]
    ok = np.ones(s_ego.shape[:2] + (rear.size,), dtype=bool)
    for cols, is_rear in ((rear, True), (front, False)):
        present = cols > 0
        c = cols[present]
        if not c.size:
            continue
        p = params.take(c)
        s_car = vehicles.s[c] + vehicles.speed[c] * tt  # [1, T, k]
        if is_rear:
            gap = s_ego - half - (s_car + 0.5 * vehicles.length[c])
            need = formulas.lon_safe_distance_same_dir(vehicles.speed[c], v_ego, p, ego)
        else:
            gap = s_car - 0.5 * vehicles.length[c] - s_ego - half
            need = formulas.lon_safe_distance_same_dir(v_ego, vehicles.speed[c], ego, p)
        ok[:, :, present] &= formulas.is_safe_distance(gap, need)
    return ok
