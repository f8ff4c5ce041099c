"""The ego's lane-change layers in EUDM's forward simulation (epsilon.md §3.5, §3.6): the cars around the gap it
aims at, the gap-informed speed controller (with the port's fix: the caller still applies the current-lane IDM),
the RSS evasive speed-up and the RSS virtual barrier; and the lateral RSS test shared with the policy cost.
Units: m, s, m/s, m/s².
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ...angles import cos_sin
from ...rss import formulas
from ..road_frame import FrameCells, RoadFrame
from .controllers import BicycleState, IdmParams, clamp

if TYPE_CHECKING:
    from .forward_sim import SimSettings


@dataclass(frozen=True, eq=False)
class GapCars:
    """Per rollout, the nearest agents ahead of and behind the ego on its target lane, found once per layer:
    ``index`` [G, 2] (front, rear; 0 where ``present`` is False); ``trio`` [G, 3]: the flat indices into [G, n]
    arrays of the ego, the front and the rear car (``x.take(trio)``); ``half_length`` and ``width`` [G, 2] of the
    two cars [m]; ``params`` their RSS parameters [G, 2]; ``rear_params`` / ``front_params`` [2, G] those of the
    rear and the front car of the two longitudinal pairs (the rear gap car behind the ego, the ego behind the
    front gap car)."""

    index: np.ndarray
    present: np.ndarray
    trio: np.ndarray
    half_length: np.ndarray
    width: np.ndarray
    params: Any
    rear_params: Any
    front_params: Any

    @classmethod
    def find(cls, centres: np.ndarray, s: np.ndarray, d: np.ndarray, target: np.ndarray, radius: float,
             length: np.ndarray, width: np.ndarray, rss_vehicles: Any) -> GapCars:
        """``centres``: [3, G, n] lane centres at every vehicle's position; ``target`` [G] the ego's target chain;
        ``length``, ``width`` [n] [m] and ``rss_vehicles`` the RSS parameters of every vehicle (the ego first)."""
        rows = np.arange(s.shape[0])
        on_target = np.abs(d - centres[target, rows]) < radius
        on_target[:, 0] = False
        ds = s - s[:, :1]
        distance = np.stack([np.where(on_target & (ds >= 0.0), ds, np.inf),
                             np.where(on_target & (ds < 0.0), -ds, np.inf)], axis=2)  # [G, n, 2]
        index = np.argmin(distance, axis=1)
        present = np.isfinite(np.take_along_axis(distance, index[:, None, :], axis=1)[:, 0])
        index = np.where(present, index, 0)
        vehicles = np.concatenate([np.zeros((rows.size, 1), dtype=index.dtype), index], axis=1)  # ego, front, rear
        return cls(index, present, rows[:, None] * s.shape[1] + vehicles, 0.5 * length[index], width[index],
                   rss_vehicles.take(index), rss_vehicles.take(vehicles.take(_REAR_CARS, axis=1).T),
                   rss_vehicles.take(vehicles.take(_FRONT_CARS, axis=1).T))


# Columns of a trio (ego, front, rear) that are the rear / the front car of the two longitudinal pairs.
_REAR_CARS, _FRONT_CARS = np.array((2, 0)), np.array((0, 1))


def lane_change_command(frame: RoadFrame, target: np.ndarray, state: BicycleState, cells: FrameCells,
                        length: np.ndarray, width: np.ndarray, gap: GapCars, idm: IdmParams, v0: np.ndarray,
                        st: SimSettings, rss_ego: Any, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ego's speed command in a lane-change layer (§3.5), whether the RSS barrier holds it back, and the
    desired speed of its evasive speed-up into the gap (§3.6: the gap-rear car is RSS-unsafe; inf where not);
    ``target``: the ego's target chain per rollout; ``gap``: the cars around the gap it aims at.

    The barrier is RSS's cut-in rule: the ego may not make a gap car laterally unsafe while that pair is
    longitudinally unsafe, now or ``commit_time`` s later at constant speeds (the crossing takes time). Once the
    ego is laterally unsafe to a gap car that was safe when it got there, the pair's duty is longitudinal (the rear
    car keeps its distance), so the barrier no longer holds the ego half-way. (The caller also releases an ego
    already in the way of the target lane's cars: the footprint band the agents see it by.)"""
    s, v = state.x, state.speed
    has_f, has_r = gap.present[:, 0], gap.present[:, 1]
    s3, v3 = s.take(gap.trio), v.take(gap.trio)  # [G, 3]: ego, front, rear
    s_e, v_e = s3[:, 0], v3[:, 0]
    s0, T = idm.s0[:, 0], idm.headway[:, 0]
    half = 0.5 * length[0]
    s_ref_f = s3[:, 1] - gap.half_length[:, 0]  # gap front's rear bumper
    s_ref_r = s3[:, 2] + gap.half_length[:, 1]  # gap rear's front bumper
    v_f, v_r = v3[:, 1], v3[:, 2]
    s_thr_f = s_ref_f - s0 - T * v_e - half
    s_thr_r = s_ref_r + s0 + T * v_r + half
    v_ref_f = np.maximum(0.0, v_f + clamp(st.gap_speed_gain * (s_thr_f - s_e), -3.0, 5.0))
    v_ref_r = np.maximum(0.0, v_r + clamp(st.gap_speed_gain * (s_thr_r - s_e), -3.0, 5.0))
    v_pref = v_e + st.preferred_blend * (v0[:, 0] - v_e)
    mid = 0.5 * (s_ref_f + s_ref_r)
    both_s = clamp(s_e, np.minimum(mid, s_thr_r), np.maximum(mid, s_thr_f))
    both_v = np.minimum(np.maximum(v_ref_r, v_pref), v_ref_f)
    squeezed = s_ref_f < s_ref_r
    s_des = np.where(has_f & has_r, np.where(squeezed, s_e, both_s),
                     np.where(has_f, np.minimum(s_e, s_thr_f), np.where(has_r, np.maximum(s_e, s_thr_r), s_e)))
    v_des = np.where(has_f & has_r, np.where(squeezed, v_e, both_v),
                     np.where(has_f, np.minimum(v_pref, v_ref_f), np.where(has_r, np.maximum(v_ref_r, v_pref), v_e)))
    a_track = clamp(st.track_speed_gain * (v_des + st.track_pos_gain * (s_des - s_e) - v_e), -1.0, 1.0)
    cmd = np.maximum(v_e + a_track * dt, 0.0)
    # RSS in the two pairs [2, G] (bumper gaps): the rear gap car behind the ego, the ego behind the front gap car.
    # At constant speeds the safe distances stay the same for commit_time; only the gaps change.
    v_rear, v_front = v3.take(_REAR_CARS, axis=1).T, v3.take(_FRONT_CARS, axis=1).T
    rear, front = gap.rear_params, gap.front_params
    reach = formulas.lon_reach(v_rear, rear, rear.lon_brake_min)
    d_min = formulas.combine_same_dir(reach, formulas.stopping_distance(v_front, front.lon_brake_max),
                                      rear.min_lon_gap)
    gaps = np.array([s_e - half - s_ref_r, s_ref_f - s_e - half])
    too_slow = has_r & ~formulas.is_safe_distance(gaps[0], d_min[0])
    cmd = np.where(too_slow, np.maximum(cmd, v_e + st.evasive_accel * dt), cmd)
    # Beside the rear car (a gap below its λ) no speed is safe yet: speed up as for a gap of λ, which opens as it goes.
    v_low = formulas.min_safe_speed_ahead_of_reach(np.maximum(gaps[0], rear.min_lon_gap[0]), reach[0],
                                                   rear.min_lon_gap[0], rss_ego.lon_brake_max)
    evasive_v0 = np.where(too_slow, np.maximum(v0[:, 0], v_low + st.evasive_extra_speed), np.inf)
    safe_later = formulas.is_safe_distance(np.minimum(gaps, gaps + (v_front - v_rear) * st.commit_time), d_min)
    rear_unsafe, front_unsafe = has_r & ~safe_later[0], has_f & ~safe_later[1]
    # Lateral speeds relative to the target lane (+ = left) of the ego and the two gap cars.
    slope = frame.slope(target[:, None], FrameCells(cells.index.take(gap.trio), cells.fraction.take(gap.trio)))
    v_lat = v3 * cos_sin(state.heading.take(gap.trio) - slope)[1]
    d3 = state.y.take(gap.trio)
    lat_safe = laterally_safe(d3[:, :1], d3[:, 1:], v_lat[:, :1], v_lat[:, 1:], width[0], gap.width, rss_ego,
                              gap.params)  # [G, 2]: to the front and the rear car
    barrier = (rear_unsafe & lat_safe[:, 1]) | (front_unsafe & lat_safe[:, 0])
    return cmd, barrier, evasive_v0


def laterally_safe(d_e: Any, d_o: Any, u_e: Any, u_o: Any, w_e: Any, w_o: Any, rss_ego: Any,
                   rss_other: Any) -> np.ndarray:
    """Whether the ego (centre offset ``d_e`` [m], lateral speed ``u_e`` [m/s], + = left, extent across the lane
    ``w_e`` [m]) and another car (``d_o``, ``u_o``, ``w_o``) are laterally RSS-safe (rss.md §2; arrays broadcast)."""
    ego_left = d_e >= d_o
    lat_gap = np.abs(d_e - d_o) - 0.5 * (w_e + w_o)
    # Reaches at the speeds towards the other car; the ego's for both sides, on its own (smaller) shape.
    reach_e = formulas.lateral_reach(np.where(ego_left, -u_e, u_e), rss_ego)
    reach_o = formulas.lateral_reach(np.where(ego_left, u_o, -u_o), rss_other)
    lat_min = formulas.combine_lateral(reach_e, reach_o, rss_ego.lat_fluctuation_margin,
                                       rss_other.lat_fluctuation_margin)
    return formulas.is_safe_distance(lat_gap, lat_min)
