"""The ego's lane-change layers in EUDM's forward simulation (epsilon.md §3.5, §3.6): the cars around the gap it
aims at, the gap-informed speed controller (with the port's fix: the caller still applies the current-lane IDM),
the RSS evasive speed-up and the RSS virtual barrier; and the lateral RSS test shared with the policy cost.
The first two are the forward-simulation kernel's (numba, one rollout at a time); :func:`laterally_safe` is jitable
(numpy over arrays for the policy cost, compiled in the kernel). Units: m, s, m/s, m/s².
"""
from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ...angles import cos_sin
from ...jit import jitable, rss_row, select
from ...rss import formulas
from .controllers import clamp


class GapSettings(NamedTuple):
    """The gap controller's settings (:class:`~.forward_sim.SimSettings`' fields of the same names)."""

    gap_speed_gain: float
    preferred_blend: float
    track_speed_gain: float
    track_pos_gain: float
    track_accel: float  # [m/s²] the tracking acceleration's upper clip: the ego's own acceleration limit
    evasive_accel: float
    evasive_extra_speed: float
    commit_time: float
    evasive: bool


@jitable
def gap_cars(s: np.ndarray, d: np.ndarray, target_centre: np.ndarray, radius: float) -> tuple[int, int]:
    """The nearest agents ahead of and behind the ego (column 0) on its target lane, as columns (0: none), of one
    rollout: ``s``, ``d`` [n] the vehicles' frame positions, ``target_centre`` [n] the target lane's centre at each
    [m]; a car is on it within ``radius`` [m] of the centre."""
    front, rear, ahead, behind = 0, 0, np.inf, np.inf
    for j in range(1, s.shape[0]):
        if np.abs(d[j] - target_centre[j]) < radius:
            ds = s[j] - s[0]
            if ds >= 0.0:
                if ds < ahead:
                    front, ahead = j, ds
            elif -ds < behind:
                rear, behind = j, -ds
    return front, rear


@jitable
def lane_change_command(f: int, r: int, has_f: bool, has_r: bool, s: np.ndarray, d: np.ndarray,
                        heading: np.ndarray, v: np.ndarray, slope: np.ndarray, length: np.ndarray,
                        width: np.ndarray, s0: float, headway: float, v0: float, st: GapSettings, rss_ego: Any,
                        rss_table: np.ndarray, dt: float) -> tuple[float, bool, float]:
    """One rollout's ego speed command in a lane-change layer (§3.5), whether the RSS barrier holds it back, and the
    desired speed of its evasive speed-up into the gap (§3.6: the gap-rear car is RSS-unsafe; inf where not).
    ``f``, ``r``: the columns of the front and rear gap cars (:func:`gap_cars`), ``has_f``, ``has_r`` whether
    there are such cars; ``s``, ``d``, ``heading``, ``v`` [n] the vehicles' states, ``slope`` [n] the target lane's
    direction at each [rad]; ``s0`` [m], ``headway`` [s], ``v0`` [m/s]: the ego's IDM s0, T and desired speed;
    ``rss_table`` [n, fields]: every vehicle's RSS parameters (:func:`~sumo_rss.jit.rss_row`).

    The barrier is RSS's cut-in rule: the ego may not make a gap car laterally unsafe while that pair is
    longitudinally unsafe, now or ``commit_time`` s later at constant speeds (the crossing takes time). Once the
    ego is laterally unsafe to a gap car that was safe when it got there, the pair's duty is longitudinal (the rear
    car keeps its distance), so the barrier no longer holds the ego half-way. (The caller also releases an ego
    already in the way of the target lane's cars: the footprint band the agents see it by.)"""
    s_e, v_e = s[0], v[0]
    half = 0.5 * length[0]
    s_ref_f = s[f] - 0.5 * length[f]  # gap front's rear bumper
    s_ref_r = s[r] + 0.5 * length[r]  # gap rear's front bumper
    v_f, v_r = v[f], v[r]
    s_thr_f = s_ref_f - s0 - headway * v_e - half
    s_thr_r = s_ref_r + s0 + headway * v_r + half
    v_ref_f = np.maximum(0.0, v_f + clamp(st.gap_speed_gain * (s_thr_f - s_e), -3.0, 5.0))
    v_ref_r = np.maximum(0.0, v_r + clamp(st.gap_speed_gain * (s_thr_r - s_e), -3.0, 5.0))
    v_pref = v_e + st.preferred_blend * (v0 - v_e)
    mid = 0.5 * (s_ref_f + s_ref_r)
    both_s = clamp(s_e, np.minimum(mid, s_thr_r), np.maximum(mid, s_thr_f))
    both_v = np.minimum(np.maximum(v_ref_r, v_pref), v_ref_f)
    squeezed = s_ref_f < s_ref_r
    s_des = select(has_f & has_r, select(squeezed, s_e, both_s),
                   select(has_f, np.minimum(s_e, s_thr_f), select(has_r, np.maximum(s_e, s_thr_r), s_e)))
    v_des = select(has_f & has_r, select(squeezed, v_e, both_v),
                   select(has_f, np.minimum(v_pref, v_ref_f), select(has_r, np.maximum(v_ref_r, v_pref), v_e)))
    a_track = clamp(st.track_speed_gain * (v_des + st.track_pos_gain * (s_des - s_e) - v_e), -1.0, st.track_accel)
    cmd = np.maximum(v_e + a_track * dt, 0.0)
    # RSS in the two pairs (bumper gaps): the rear gap car behind the ego, the ego behind the front gap car. At
    # constant speeds the safe distances stay the same for commit_time; only the gaps change.
    rear_r, rear_e, front_f = rss_row(rss_table, r), rss_row(rss_table, 0), rss_row(rss_table, f)
    reach_r = formulas.lon_reach(v_r, rear_r, rear_r.lon_brake_min)
    reach_e = formulas.lon_reach(v_e, rear_e, rear_e.lon_brake_min)
    d_min_r = formulas.combine_same_dir(reach_r, formulas.stopping_distance(v_e, rear_e.lon_brake_max),
                                        rear_r.min_lon_gap)
    d_min_f = formulas.combine_same_dir(reach_e, formulas.stopping_distance(v_f, front_f.lon_brake_max),
                                        rear_e.min_lon_gap)
    gap_r, gap_f = s_e - half - s_ref_r, s_ref_f - s_e - half
    too_slow = st.evasive and has_r and not formulas.is_safe_distance(gap_r, d_min_r)
    if too_slow:
        cmd = np.maximum(cmd, v_e + st.evasive_accel * dt)
    # Beside the rear car (a gap below its λ) no speed is safe yet: speed up as for a gap of λ, which opens as it goes.
    v_low = formulas.min_safe_speed_ahead_of_reach(np.maximum(gap_r, rear_r.min_lon_gap), reach_r,
                                                   rear_r.min_lon_gap, rss_ego.lon_brake_max)
    evasive_v0 = np.maximum(v0, v_low + st.evasive_extra_speed) if too_slow else np.inf
    rear_unsafe = has_r and not formulas.is_safe_distance(
        np.minimum(gap_r, gap_r + (v_e - v_r) * st.commit_time), d_min_r)
    front_unsafe = has_f and not formulas.is_safe_distance(
        np.minimum(gap_f, gap_f + (v_f - v_e) * st.commit_time), d_min_f)
    # Lateral speeds relative to the target lane (+ = left) of the ego and the two gap cars.
    u_e = v_e * cos_sin(heading[0] - slope[0])[1]
    u_f = v_f * cos_sin(heading[f] - slope[f])[1]
    u_r = v_r * cos_sin(heading[r] - slope[r])[1]
    barrier = (rear_unsafe and laterally_safe(d[0], d[r], u_e, u_r, width[0], width[r], rss_ego, rear_r)) or \
        (front_unsafe and laterally_safe(d[0], d[f], u_e, u_f, width[0], width[f], rss_ego, front_f))
    return cmd, barrier, evasive_v0


@jitable
def laterally_safe(d_e: Any, d_o: Any, u_e: Any, u_o: Any, w_e: Any, w_o: Any, rss_ego: Any,
                   rss_other: Any) -> np.ndarray:
    """Whether the ego (centre offset ``d_e`` [m], lateral speed ``u_e`` [m/s], + = left, extent across the lane
    ``w_e`` [m]) and another car (``d_o``, ``u_o``, ``w_o``) are laterally RSS-safe (rss.md §2; arrays broadcast)."""
    ego_left = d_e >= d_o
    lat_gap = np.abs(d_e - d_o) - 0.5 * (w_e + w_o)
    # Reaches at the speeds towards the other car; the ego's for both sides, on its own (smaller) shape.
    reach_e = formulas.lateral_reach(select(ego_left, -u_e, u_e), rss_ego)
    reach_o = formulas.lateral_reach(select(ego_left, u_o, -u_o), rss_other)
    lat_min = formulas.combine_lateral(reach_e, reach_o, rss_ego.lat_fluctuation_margin,
                                       rss_other.lat_fluctuation_margin)
    return formulas.is_safe_distance(lat_gap, lat_min)


# [m] kept beyond the lateral RSS distance and the agents' band by an ego that waits beside its gap, ready to go
READY_MARGIN = 0.2


@jitable
def ready_offset(f: int, r: int, d: np.ndarray, heading: np.ndarray, v: np.ndarray, width: np.ndarray,
                 target_centre: float, ego_band: float, rss_ego: Any, rss_table: np.ndarray) -> float:
    """[m] Where across its lane an ego that the barrier holds back waits where its lane ends (its centre's offset in
    the frame, with ``SimSettings.ready_wait``; ``heading`` [n]: each car's against the target lane [rad]): as far
    towards its target lane (centre at ``target_centre``) as it stays out of the target lane's band in which
    the agents see it in their way (``ego_band``, :func:`.leaders.occupied_band`) and laterally RSS-safe, at its
    present lateral speed, to the gap cars ``f`` and ``r`` (columns, 0: none), each by READY_MARGIN; never further
    from the target lane than it is. RSS's cut-in rule forbids making an unsafe pair laterally unsafe, not a lateral
    move that keeps it safe; standing at its lane's centre, a waiting ego needed ~1.6 s from standstill to become
    laterally unsafe to the target lane's cars (the steer rate, 0.39 rad/s, and the 3 m/s³ jerk), longer than the
    gaps a standing ego gets (docs/planner.md, "A standing ego's start")."""
    side = 1.0 if target_centre > d[0] else -1.0
    limit = target_centre - side * (ego_band + READY_MARGIN)
    u_e = side * v[0] * np.sin(heading[0])  # towards the target lane
    for j in (f, r):
        if j > 0:
            u_j = -side * v[j] * np.sin(heading[j])  # towards the ego
            p_j = rss_row(rss_table, j)
            need = 0.5 * (width[0] + width[j]) + READY_MARGIN + formulas.combine_lateral(
                formulas.lateral_reach(u_e, rss_ego), formulas.lateral_reach(u_j, p_j),
                rss_ego.lat_fluctuation_margin, p_j.lat_fluctuation_margin)
            limit = min(limit, d[j] - need) if side > 0.0 else max(limit, d[j] + need)
    return d[0] + side * max(side * (limit - d[0]), 0.0)
