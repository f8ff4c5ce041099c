"""Rule 5 — evasive effort (rss.md §8; paper §3.6, Def. 11-13): the naive prediction of a road user, the fixed set
of candidate evasive manoeuvres of a car and their legality, vectorised over the asked cars, the road users around
them and the candidates (no loop over pairs).

Geometry is the pair's road frame of :mod:`.situations` (X along the reference lane, Y to its left): each pair row
gives the two cars' centres (from the bumper-to-bumper gaps and the half extents of the footprints) and which way
each drives along it. Every motion is a function of time [s] since t₀, in the car's own lane frame (x forward,
y to its left), and is sampled on a grid of GRID_STEP over [t₀, t₀ + T].

Units: m, s, m/s, m/s² (brakes positive magnitudes).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .formulas import combine_lateral, combine_opposite, combine_same_dir, is_safe_distance, lateral_reach, lon_reach
from .formulas import stopping_distance
from .params import PARAM_NAMES, RssParamArrays

GRID_STEP = 0.1  # [s] the time grid on which the manoeuvres are compared (a pass between two samples counts too)
LON_CHOICES = ("-b_max", "-b_min", "0", "a_acc")  # the candidates' longitudinal accelerations
LAT_CHOICES = (-1.0, 0.0, 1.0)  # their lateral accelerations, in units of a_lat (+ = left)
N_CANDIDATES = len(LON_CHOICES) * len(LAT_CHOICES)  # candidate k: LON_CHOICES[k // 3] x LAT_CHOICES[k % 3]
OPPOSITE_CODE = 1  # SITUATION_CODES index of opposite-direction pairs
BAND_EPS = 1e-6  # [m]


def ramp(v0: Any, a: Any, v_end: Any, t: Any) -> tuple[np.ndarray, np.ndarray]:
    """(distance [m], speed [m/s]) after ``t`` [s] of a motion along one axis that starts at ``v0`` with constant
    acceleration ``a`` until its speed reaches ``v_end`` and then holds it (a = 0: v0 throughout)."""
    v0, a = np.asarray(v0, dtype=float), np.asarray(a, dtype=float)
    moving = a != 0.0
    tau = np.where(moving, np.maximum((v_end - v0) / np.where(moving, a, 1.0), 0.0), np.inf)
    te = np.minimum(t, tau)
    v = v0 + a * te
    return v0 * te + 0.5 * a * te * te + v * (t - te), v


def naive(p0: Any, v0: Any, a0: Any, t: Any) -> tuple[np.ndarray, np.ndarray]:
    """Naive prediction (Def. 11) along one axis: (position [m], speed [m/s]) ``t`` [s] on of a road user at
    ``p0``, ``v0``, ``a0``: constant a₀ until its speed reaches 0 (τ = −v₀/a₀ where they have opposite signs),
    then standing on that axis."""
    v0, a0 = np.asarray(v0, dtype=float), np.asarray(a0, dtype=float)
    x, v = ramp(v0, a0, 0.0, t)  # until standing
    # No stop ahead: constant acceleration throughout (a car standing with a negative acceleration stays: SUMO's
    # cars do not reverse).
    free = (v0 * a0 > 0.0) | (a0 == 0.0) | ((v0 == 0.0) & (a0 > 0.0))
    x = np.where(free, v0 * t + 0.5 * a0 * t * t, x)
    v = np.where(free, v0 + a0 * t, v)
    return p0 + x, v


def _first_reach(u0: np.ndarray, a: np.ndarray, h: np.ndarray) -> np.ndarray:
    """[s] the first time > 0 at which y(t) = u0·t + a·t²/2 reaches ±h (inf: never)."""
    best = np.full(np.broadcast(u0, a, h).shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for side in (-1.0, 1.0):
            disc = u0 * u0 + 2.0 * a * side * h
            root = np.sqrt(np.maximum(disc, 0.0))
            for sign in (-1.0, 1.0):
                t = np.where(a != 0.0, (-u0 + sign * root) / np.where(a != 0.0, a, 1.0),
                             side * h / np.where(u0 != 0.0, u0, np.nan))
                ok = (t > 0.0) & ((disc >= 0.0) | (a == 0.0)) & np.isfinite(t)
                best = np.where(ok, np.minimum(best, t), best)
    return best


def lateral_manoeuvre(u0: Any, a: Any, half_lane: Any, a_back: Any, t: Any) -> tuple[np.ndarray, np.ndarray]:
    """(offset [m], lateral speed [m/s]) ``t`` [s] on of a lateral candidate starting at lateral speed ``u0``:
    acceleration ``a`` until the car has moved ``half_lane`` to either side, then its lateral speed brought back
    to 0 at ``a_back`` (> 0) and held there."""
    u0, a, half_lane = (np.asarray(x, dtype=float) for x in (u0, a, half_lane))
    t1 = _first_reach(u0, a, half_lane)
    early = np.minimum(t, t1)
    y = u0 * early + 0.5 * a * early * early
    u = u0 + a * early
    u1 = u0 + a * np.where(np.isfinite(t1), t1, 0.0)
    y1 = u0 * np.where(np.isfinite(t1), t1, 0.0) + 0.5 * a * np.where(np.isfinite(t1), t1, 0.0) ** 2
    late = np.maximum(t - t1, 0.0)  # 0 before t1 (t1 = inf: never)
    s = np.minimum(late, np.abs(u1) / a_back)
    back = -np.sign(u1) * a_back
    y = np.where(late > 0.0, y1 + u1 * s + 0.5 * back * s * s, y)
    u = np.where(late > 0.0, u1 + back * s, u)
    return y, u


@dataclass(frozen=True, eq=False)
class Candidates:
    """Every candidate of the asked cars (rows q) on the time grid, in each car's own lane frame: x, v [q, 4, K+1]
    along, per LON_CHOICES, and y, u [q, 3, K+1] across (+ = left), per LAT_CHOICES (candidate k combines lon k // 3
    and lat k % 3); the commanded accelerations lon_accel, lat_accel [q, 12] and the longitudinal one the car would
    apply at t₀ (0 where it stands, or is at its speed cap)."""

    times: np.ndarray  # [K+1] s since t₀
    x: np.ndarray
    v: np.ndarray
    y: np.ndarray
    u: np.ndarray
    lon_accel: np.ndarray
    lat_accel: np.ndarray
    initial_lon_accel: np.ndarray
    speed_cap: np.ndarray  # [q] m/s
    half_lane: np.ndarray  # [q] m
    lat_back: np.ndarray  # [q] m/s², the rate the lateral speed is brought back to 0 at


def lon_commands(p: RssParamArrays) -> np.ndarray:
    """[q, 4] the longitudinal accelerations of LON_CHOICES for cars with parameters ``p`` [m/s²]."""
    return np.column_stack([-p.lon_brake_max, -p.lon_brake_min, np.zeros_like(p.lon_brake_max), p.lon_accel_max])


def candidate_accels(p: RssParamArrays) -> tuple[np.ndarray, np.ndarray]:
    """([q, 12] longitudinal, [q, 12] lateral) commanded accelerations of the candidates [m/s²]."""
    lon = np.repeat(lon_commands(p), len(LAT_CHOICES), axis=1)
    lat = np.tile(np.array(LAT_CHOICES), len(LON_CHOICES))[None, :] * p.lat_accel_max[:, None]
    return lon, lat


def candidate_motion(v0: np.ndarray, u0: np.ndarray, lon_accel: np.ndarray, lat_accel: np.ndarray,
                     speed_cap: np.ndarray, half_lane: np.ndarray, lat_back: np.ndarray, t: Any
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, v, y, u) of candidates (commands [q, 12]) of cars at speed ``v0`` / lateral speed ``u0`` [q] after ``t``
    [s] (broadcast on a trailing axis): braking ends standing, accelerating ends at ``speed_cap``."""
    v_end = np.where(lon_accel < 0.0, 0.0, speed_cap[:, None])
    x, v = ramp(v0[:, None, None], lon_accel[..., None], v_end[..., None], t)
    y, u = lateral_manoeuvre(u0[:, None, None], lat_accel[..., None], half_lane[:, None, None],
                             lat_back[:, None, None], t)
    return x, v, y, u


def grid(horizon: float) -> np.ndarray:
    """[s] the sample times 0, GRID_STEP, ..., ``horizon`` (the last one exactly)."""
    return np.linspace(0.0, horizon, int(np.ceil(horizon / GRID_STEP - 1e-9)) + 1)


def candidates(v0: np.ndarray, u0: np.ndarray, p: RssParamArrays, speed_limit: np.ndarray, half_lane: np.ndarray,
               times: np.ndarray) -> Candidates:
    """The fixed candidate set (rss.md §8) of cars at speed ``v0`` and lateral speed ``u0`` [q]: longitudinal
    {−b_max, −b_min, 0, a_acc} (accelerating up to the larger of ``speed_limit`` and v0) x lateral {−a_lat, 0,
    +a_lat}, the lateral speed brought back to 0 at a_lat once the car has moved ``half_lane``, sampled at
    ``times`` [s] (:func:`grid`; the first 0, the last the horizon)."""
    lon, lat = candidate_accels(p)
    cap = np.maximum(speed_limit, v0)
    back = np.maximum(p.lat_accel_max, 1e-9)
    along = lon_commands(p)
    x, v = ramp(v0[:, None, None], along[..., None], np.where(along < 0.0, 0.0, cap[:, None])[..., None], times)
    y, u = lateral_manoeuvre(u0[:, None, None], lat[:, :len(LAT_CHOICES), None], half_lane[:, None, None],
                             back[:, None, None], times)
    starts = np.where(lon < 0.0, v0[:, None] > 0.0, v0[:, None] < cap[:, None])
    return Candidates(times, x, v, y, u, lon, lat, np.where(starts, lon, 0.0), cap, half_lane, back)


@dataclass(frozen=True, eq=False)
class PairRows:
    """Road pair rows around asked cars: for row r, the asked car q[r] (c₁) and another road user o, with their
    centres' offsets at t₀ in the pair's frame (dx = X_o − X_c₁, dy = Y_o − Y_c₁ [m]), which way each drives
    along X (±1; Y turns with it), the sums of their half extents [m] and the other's state for its naive
    prediction (own frame)."""

    q: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    dir_c1: np.ndarray
    dir_o: np.ndarray
    half_lon: np.ndarray
    half_lat: np.ndarray
    v_o: np.ndarray
    a_o: np.ndarray
    u_o: np.ndarray
    opposite: np.ndarray  # bool: opposite-direction pair
    p_c1: RssParamArrays
    p_o: RssParamArrays
    brake_c1: np.ndarray  # [m/s²] opposite pairs: the braking each car's d_min assumes (b_corr in its correct lane)
    brake_o: np.ndarray

    def take(self, index: np.ndarray) -> PairRows:
        return PairRows(**{name: getattr(self, name).take(index) if name in ("p_c1", "p_o") else
                           getattr(self, name)[index] for name in self.__dataclass_fields__})

    def beyond_reach(self, c: Candidates) -> np.ndarray:
        """[r] rows whose cars cannot touch within the horizon whatever c₁'s candidate: farther apart on either axis
        than the most both can close in T (the other on its naive prediction, c₁ braking at b_max or accelerating at
        a_acc, and swerving at a_lat from its lateral speed)."""
        t = c.times[-1]
        v_c1, u_c1 = c.v[self.q, 0, 0], c.u[self.q, 0, 0]
        a_c1 = np.maximum(self.p_c1.lon_brake_max, self.p_c1.lon_accel_max)
        lon = np.abs(self.dir_o * self.v_o - self.dir_c1 * v_c1) * t + 0.5 * (np.abs(self.a_o) + a_c1) * t * t
        lat = (np.abs(self.u_o) + np.abs(u_c1)) * t + 0.5 * self.p_c1.lat_accel_max * t * t
        widen = 0.5 * (self.p_c1.lat_fluctuation_margin + self.p_o.lat_fluctuation_margin)
        return (np.abs(self.dx) - self.half_lon > lon) | (np.abs(self.dy) - self.half_lat - widen > lat)


def per_candidate(along: np.ndarray, across: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[r, 12, ...] both parts of the candidates from their longitudinal [r, 4, ...] and lateral [r, 3, ...] ones."""
    return np.repeat(along, len(LAT_CHOICES), axis=1), np.tile(across, (1, len(LON_CHOICES)) + (1,) * (across.ndim - 2))


def _column(p: RssParamArrays) -> RssParamArrays:
    return RssParamArrays(*(getattr(p, name)[:, None] for name in PARAM_NAMES))


def relative_motion(c: Candidates, rows: PairRows, k: slice = slice(None)
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(DX [r, 4, K+1] per longitudinal choice, DY [r, 3, K+1] per lateral one, other's lon speed, its lat speed
    [r, 1, K+1]) at the grid times ``k``: the other's centre minus c₁'s in the pair frame with c₁ on each candidate
    and the other on its naive prediction (lateral acceleration 0)."""
    t = c.times[k]
    x_o, v_o = naive(0.0, rows.v_o[:, None], rows.a_o[:, None], t)
    y_o = rows.u_o[:, None] * t
    d = rows.dir_o[:, None]
    dx = rows.dx[:, None, None] + (d * x_o)[:, None, :] - rows.dir_c1[:, None, None] * c.x[rows.q][..., k]
    dy = rows.dy[:, None, None] + (d * y_o)[:, None, :] - rows.dir_c1[:, None, None] * c.y[rows.q][..., k]
    return dx, dy, v_o[:, None, :], np.broadcast_to(rows.u_o[:, None, None], v_o[:, None, :].shape)


def collides(c: Candidates, rows: PairRows) -> np.ndarray:
    """[r, 12] whether c₁ on each candidate and the other road user on its naive prediction collide within the
    horizon: their boxes (footprints widened by μ/2 each) overlap at a grid time, or pass through each other
    between two (the centre offset changes sign on one axis while they overlap on the other at both)."""
    dx, dy, _, _ = relative_motion(c, rows)
    widen = 0.5 * (rows.p_c1.lat_fluctuation_margin + rows.p_o.lat_fluctuation_margin)
    lon = (np.abs(dx) < rows.half_lon[:, None, None])[:, :, None, :]  # [r, 4, 1, K+1]
    lat = (np.abs(dy) < (rows.half_lat + widen)[:, None, None])[:, None, :, :]  # [r, 1, 3, K+1]
    overlap = np.any(lon & lat, axis=3)
    turns_lon = (np.sign(dx[..., 1:]) != np.sign(dx[..., :-1]))[:, :, None, :]
    turns_lat = (np.sign(dy[..., 1:]) != np.sign(dy[..., :-1]))[:, None, :, :]
    passes = (turns_lon & lat[..., 1:] & lat[..., :-1]) | (turns_lat & lon[..., 1:] & lon[..., :-1])
    return (overlap | np.any(passes, axis=3)).reshape(len(rows.q), N_CANDIDATES)


def dangerous_at_end(c: Candidates, rows: PairRows) -> np.ndarray:
    """[r, 12] whether the pair is dangerous (neither longitudinally nor laterally safe, rss.md §2) at t₀ + T with
    c₁ on each candidate and the other on its naive prediction; the worst-case terms as the auditor's."""
    dx, dy, v_o, u_o = (z[..., -1] for z in relative_motion(c, rows, slice(-1, None)))
    dx, dy = per_candidate(dx, dy)
    v_c1, u_c1 = per_candidate(np.maximum(c.v[rows.q, :, -1], 0.0), rows.dir_c1[:, None] * c.u[rows.q, :, -1])
    v_o = np.maximum(v_o, 0.0)
    u_o = rows.dir_o[:, None] * u_o
    p1, po = _column(rows.p_c1), _column(rows.p_o)
    lon_gap = np.abs(dx) - rows.half_lon[:, None]
    lat_gap = np.abs(dy) - rows.half_lat[:, None]
    other_front = dx > 0.0
    same = combine_same_dir(np.where(other_front, lon_reach(v_c1, p1, p1.lon_brake_min),
                                     lon_reach(v_o, po, po.lon_brake_min)),
                            np.where(other_front, stopping_distance(v_o, po.lon_brake_max),
                                     stopping_distance(v_c1, p1.lon_brake_max)),
                            np.where(other_front, p1.min_lon_gap, po.min_lon_gap))
    opposite = combine_opposite(lon_reach(v_c1, p1, rows.brake_c1[:, None]), lon_reach(v_o, po, rows.brake_o[:, None]),
                                p1.min_lon_gap, po.min_lon_gap)
    passed = rows.opposite[:, None] & (dx * rows.dir_c1[:, None] < 0.0)  # the two drove past each other
    lon_safe = passed | is_safe_distance(lon_gap, np.where(rows.opposite[:, None], opposite, same))
    other_left = dy > 0.0
    u_left, u_right = np.where(other_left, u_o, u_c1), np.where(other_left, u_c1, u_o)
    lat_d_min = combine_lateral(
        np.where(other_left, lateral_reach(-u_left, po), lateral_reach(-u_left, p1)),
        np.where(other_left, lateral_reach(u_right, p1), lateral_reach(u_right, po)),
        np.where(other_left, po.lat_fluctuation_margin, p1.lat_fluctuation_margin),
        np.where(other_left, p1.lat_fluctuation_margin, po.lat_fluctuation_margin))
    return ~lon_safe & ~is_safe_distance(lat_gap, lat_d_min)


def on_drivable_lanes(c: Candidates, offset: np.ndarray, half_lat: np.ndarray, room_left: np.ndarray,
                      room_right: np.ndarray) -> np.ndarray:
    """[q, 12] whether each candidate keeps the car's footprint (centre ``offset`` from its lane's centre line,
    ``half_lat`` across [m]) within the drivable band [−room_right, room_left] of its lane and the lanes beside it
    over the horizon; a car already beyond it may not move further out."""
    y = offset[:, None, None] + c.y
    left = np.maximum(room_left, offset + half_lat)[:, None, None] + BAND_EPS
    right = np.minimum(-room_right, offset - half_lat)[:, None, None] - BAND_EPS
    inside = np.all((y + half_lat[:, None, None] <= left) & (y - half_lat[:, None, None] >= right), axis=2)
    return per_candidate(np.ones((len(offset), len(LON_CHOICES)), dtype=bool), inside)[1]


def owed_to_others(c: Candidates, cars: np.ndarray, q: np.ndarray, accel_max: np.ndarray, accel_min: np.ndarray,
                   lat_owed_towards: np.ndarray, tolerance: float) -> np.ndarray:
    """[len(cars), 12] legality (a) of the candidates of ``cars`` (rows of ``c``): at t₀ each candidate satisfies the
    proper responses the car owes in its other open episodes (rows r of car cars[q[r]]): a ≤ ``accel_max`` and
    a ≥ ``accel_min`` (NaN: no bound) within ``tolerance`` [m/s²], and no lateral acceleration towards a road user
    it owes a lateral response (``lat_owed_towards`` [r]: +1 that one is on its left, −1 on its right, 0 none)."""
    legal = np.ones((len(cars), c.lon_accel.shape[1]), dtype=bool)
    if q.size:
        a = c.initial_lon_accel[cars[q]]
        ok = ~(a > accel_max[:, None] + tolerance) & ~(a < accel_min[:, None] - tolerance)
        ok &= ~(np.sign(c.lat_accel[cars[q]]) * lat_owed_towards[:, None] > 0.0)
        np.logical_and.at(legal, q, ok)
    return legal
