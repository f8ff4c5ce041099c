"""RSS parameters per vehicle class and the named presets (rss.md §1).

All quantities are SI: seconds, metres, m/s, m/s². Braking values are **positive magnitudes** with
``lon_brake_min_correct <= lon_brake_min <= lon_brake_max``.

Parameters are resolved per vehicle: the preset's value for the vehicle's role (``ego`` or ``background``),
then the role's overrides, then the overrides of its SUMO vType id (most specific wins).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from ..road_users import BICYCLE_CLASS, PERSON_CLASS

MODEL_VERSION = "rss-1"
"""Version of the audit semantics; written into every summary so old results stay interpretable."""

PRESETS = ("ad_rss", "mobileye_human", "epsilon", "krauss")
ROLES = ("ego", "background")
# Road users that are not cars (rss.md §10) have their own parameter rows: BICYCLE (SUMO vClass bicycle) and PERSON.
BICYCLE, PERSON = BICYCLE_CLASS, PERSON_CLASS

SUMO_DEFAULT_TAU = 1.0  # [s] SUMO's default vType tau
SUMO_DEFAULT_DECEL = 4.5  # [m/s²] SUMO's default passenger decel


@dataclass(frozen=True)
class RssParams:
    """One vehicle's RSS dynamics (rss.md §1; symbols in brackets)."""

    response_time: float = 1.0  # ρ [s]
    lon_accel_max: float = 3.5  # a_acc [m/s²] worst-case acceleration during ρ
    lon_brake_min: float = 4.0  # b_min [m/s²] braking the rear car owes after ρ
    lon_brake_min_correct: float = 3.0  # b_corr [m/s²] braking owed in the correct lane (opposite dir.)
    lon_brake_max: float = 8.0  # b_max [m/s²] hardest braking anyone may assume of a front car
    lat_accel_max: float = 0.2  # a_lat [m/s²] worst-case lateral acceleration during ρ
    lat_brake_min: float = 0.8  # b_lat [m/s²] lateral braking owed after ρ
    lat_fluctuation_margin: float = 0.1  # μ [m] lateral fluctuation margin
    min_lon_gap: float = 0.0  # λ [m] extra longitudinal gap kept at standstill
    max_speed_on_accel: float = 100.0  # v_cap [m/s] speed up to which a_acc applies during ρ

    def problems(self) -> list[str]:
        """Every range and ordering rule this parameter set breaks (empty when valid)."""
        out = []
        if not 0.0 < self.response_time <= 10.0:
            out.append(f"response_time must be in (0, 10] s, is {self.response_time:g}")
        for name in ("lon_accel_max", "lat_accel_max", "min_lon_gap"):
            if getattr(self, name) < 0.0:
                out.append(f"{name} must be >= 0, is {getattr(self, name):g}")
        for name in ("lon_brake_min", "lon_brake_min_correct", "lon_brake_max", "lat_brake_min"):
            if getattr(self, name) <= 0.0:
                out.append(f"{name} must be > 0 (a positive magnitude), is {getattr(self, name):g}")
        if not self.lon_brake_min_correct <= self.lon_brake_min <= self.lon_brake_max:
            out.append("expected lon_brake_min_correct <= lon_brake_min <= lon_brake_max, got "
                       f"{self.lon_brake_min_correct:g} <= {self.lon_brake_min:g} <= {self.lon_brake_max:g}")
        if not 0.0 <= self.lat_fluctuation_margin <= 1.0:
            out.append(f"lat_fluctuation_margin must be in [0, 1] m, is {self.lat_fluctuation_margin:g}")
        if not 0.0 < self.max_speed_on_accel <= 100.0:
            out.append(f"max_speed_on_accel must be in (0, 100] m/s, is {self.max_speed_on_accel:g}")
        return out

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


PARAM_NAMES = tuple(f.name for f in fields(RssParams))


# rss.md §10, assumptions (docs/rss.md, persons and bicycles). A bicycle: ρ 1 s, a_acc 1.5, b_min 2, b_max 4 m/s²,
# a_lat 0.5, b_lat 0.5 m/s², μ 0.2 m; b_corr keeps ad_rss's ratio b_corr / b_min = 3 / 4.
BICYCLE_PARAMS = RssParams(response_time=1.0, lon_accel_max=1.5, lon_brake_min=2.0, lon_brake_min_correct=1.5,
                           lon_brake_max=4.0, lat_accel_max=0.5, lat_brake_min=0.5, lat_fluctuation_margin=0.2)
# A person (the paper's example): ρ 0.5 s, a_acc 2, b_min = b_max (= b_corr) 2 m/s²; sideways as along its way.
PERSON_PARAMS = RssParams(response_time=0.5, lon_accel_max=2.0, lon_brake_min=2.0, lon_brake_min_correct=2.0,
                          lon_brake_max=2.0, lat_accel_max=2.0, lat_brake_min=2.0, lat_fluctuation_margin=0.2)


def preset_params(preset: str, role: str, *, tau: float = SUMO_DEFAULT_TAU,
                  decel: float = SUMO_DEFAULT_DECEL) -> RssParams:
    """The preset's parameters for a road user of ``role`` ('ego', 'background', BICYCLE or PERSON).

    Bicycles and persons have their own rows (BICYCLE_PARAMS, PERSON_PARAMS) under every preset but ``krauss``,
    under which a bicycle, which SUMO drives with Krauss as it drives cars, gets the Krauss row of its own vType.

    ``tau`` [s] and ``decel`` [m/s²] are the vehicle's SUMO vType values; only ``krauss`` uses them.

    - ``ad_rss``: ad-rss-lib / CARLA defaults.
    - ``mobileye_human``: the paper's suggestion (seed 001): ρ = 1 s for the ego, 2 s for human drivers, λ = 1 m.
    - ``epsilon``: the EPSILON planner's own RSS configuration (epsilon.md).
    - ``krauss``: what SUMO's Krauss car-following model guarantees. Its safe speed
      v_safe = v_l + (g − v_l·τ) / (v̄/b + τ) lets the follower stop behind a leader braking at ``decel`` if
      it reacts after τ and then brakes at ``decel`` too, without accelerating meanwhile. Hence
      ρ = τ, a_acc = 0, b_corr = b_min = b_max = decel. Lateral values are ad_rss's.
    """
    if preset not in PRESETS:
        raise ValueError(f"unknown RSS preset {preset!r}; expected one of {', '.join(PRESETS)}")
    if role == PERSON:
        return PERSON_PARAMS
    if role == BICYCLE and preset != "krauss":
        return BICYCLE_PARAMS
    if preset == "ad_rss":
        return RssParams()
    if preset == "mobileye_human":
        return RssParams(response_time=1.0 if role == "ego" else 2.0, min_lon_gap=1.0)
    if preset == "epsilon":
        return RssParams(response_time=0.2, lon_accel_max=2.0, lon_brake_min=4.0, lon_brake_min_correct=4.0,
                         lon_brake_max=5.0, lat_accel_max=1.0, lat_brake_min=1.0, lat_fluctuation_margin=0.5)
    return RssParams(response_time=tau, lon_accel_max=0.0, lon_brake_min=decel,  # krauss
                     lon_brake_min_correct=decel, lon_brake_max=decel)


def apply_overrides(params: RssParams, overrides: Mapping[str, float]) -> RssParams:
    unknown = sorted(set(overrides) - set(PARAM_NAMES))
    if unknown:
        raise ValueError(f"unknown RSS parameter {unknown[0]!r}; expected one of {', '.join(PARAM_NAMES)}")
    return replace(params, **{k: float(v) for k, v in overrides.items()})


def resolve_params(preset: str, role: str, vtype_id: str | None, *,
                   role_overrides: Mapping[str, Mapping[str, float]],
                   vtype_overrides: Mapping[str, Mapping[str, float]],
                   tau: float = SUMO_DEFAULT_TAU, decel: float = SUMO_DEFAULT_DECEL) -> RssParams:
    """Preset → role overrides → vType overrides; raises ``ValueError`` listing every broken rule."""
    params = preset_params(preset, role, tau=tau, decel=decel)
    params = apply_overrides(params, role_overrides.get(role, {}))
    if vtype_id is not None:
        params = apply_overrides(params, vtype_overrides.get(vtype_id, {}))
    problems = params.problems()
    if problems:
        raise ValueError("; ".join(problems))
    return params


@dataclass(frozen=True, eq=False)
class RssParamArrays:
    """Struct-of-arrays form of many :class:`RssParams` (one row per vehicle or per pair); the formulas
    accept it wherever they accept an ``RssParams``."""

    response_time: np.ndarray
    lon_accel_max: np.ndarray
    lon_brake_min: np.ndarray
    lon_brake_min_correct: np.ndarray
    lon_brake_max: np.ndarray
    lat_accel_max: np.ndarray
    lat_brake_min: np.ndarray
    lat_fluctuation_margin: np.ndarray
    min_lon_gap: np.ndarray
    max_speed_on_accel: np.ndarray

    @classmethod
    def stack(cls, params: Sequence[RssParams]) -> RssParamArrays:
        table = np.array([[getattr(p, name) for name in PARAM_NAMES] for p in params], dtype=float)
        table = table.reshape(len(params), len(PARAM_NAMES))
        return cls(*(table[:, k] for k in range(len(PARAM_NAMES))))

    def take(self, index: np.ndarray) -> RssParamArrays:
        """Rows ``index`` (e.g. the first car of every pair)."""
        return RssParamArrays(*(getattr(self, name)[index] for name in PARAM_NAMES))


@dataclass(frozen=True)
class EvasiveParams:
    """Rule 5's settings (rss.md §8), the same for every preset (:func:`evasive_params`)."""

    horizon_s: float = 3.0  # T [s]: how far ahead an evasive manoeuvre must avoid the collision
    lookback_s: float = 5.0  # [s] a collision's steps this far back are asked (the steps kept: docs/rss.md)
    enabled: bool = False  # off by default (docs/rss.md, rule 5)

    def problems(self) -> list[str]:
        """Every range rule this set breaks (empty when valid)."""
        out = []
        if not 0.0 < self.horizon_s <= 10.0:
            out.append(f"evasive_horizon_s must be in (0, 10] s, is {self.horizon_s:g}")
        if not 0.0 < self.lookback_s <= 60.0:
            out.append(f"evasive_lookback_s must be in (0, 60] s, is {self.lookback_s:g}")
        return out


def evasive_params(preset: str, horizon_s: float | None = None, lookback_s: float | None = None,
                   enabled: bool = False) -> EvasiveParams:
    """Rule 5's settings of ``preset`` (T = 3 s, a look-back of 5 s for all of PRESETS), with the given
    overrides; raises ``ValueError`` listing every broken rule."""
    if preset not in PRESETS:
        raise ValueError(f"unknown RSS preset {preset!r}; expected one of {', '.join(PRESETS)}")
    params = EvasiveParams(enabled=enabled)
    params = replace(params, **{k: float(v) for k, v in (("horizon_s", horizon_s), ("lookback_s", lookback_s))
                                if v is not None})
    problems = params.problems()
    if problems:
        raise ValueError("; ".join(problems))
    return params
