"""Differential tests: our vectorised formulas against Intel's ad_rss (test-only oracle), 10,000 random cases each.

Inputs stay away from ad_physics' own 1e-3 comparison tolerances (documented in adrss_oracle): speeds not within
1e-2 m/s of the speed cap, λ of the two cars equal or at least 1e-2 m apart, a_acc = 0 or >= 0.1 m/s², and
results not within 1e-3 m of the max(0, ·) clamp. Agreement: 1e-6 relative or 1e-6 m.
"""
from __future__ import annotations

import numpy as np
import pytest

from adrss_oracle import lateral, opposite_direction, same_direction
from sumo_rss.rss.formulas import (lat_safe_distance, lon_safe_distance_opposite, lon_safe_distance_same_dir,
                                   stopping_distance, worst_case_stopping_distance)
from sumo_rss.rss.params import PARAM_NAMES, RssParamArrays, RssParams

CASES = 10_000
REL, ABS = 1e-6, 1e-6


def _random_params(rng: np.random.Generator, n: int) -> RssParamArrays:
    b_corr = rng.uniform(1.0, 6.0, n)
    b_min = b_corr + rng.uniform(0.0, 3.0, n)
    b_max = b_min + rng.uniform(0.0, 5.0, n)
    accel = np.where(rng.random(n) < 0.1, 0.0, rng.uniform(0.1, 5.0, n))
    gap = np.where(rng.random(n) < 0.5, 0.0, rng.choice([0.5, 1.0, 2.0], n))
    cap = np.where(rng.random(n) < 0.3, rng.uniform(5.0, 40.0, n), 100.0)
    table = dict(response_time=rng.uniform(0.1, 3.0, n), lon_accel_max=accel, lon_brake_min=b_min,
                 lon_brake_min_correct=b_corr, lon_brake_max=b_max, lat_accel_max=rng.uniform(0.0, 2.0, n),
                 lat_brake_min=rng.uniform(0.2, 3.0, n), lat_fluctuation_margin=rng.uniform(0.0, 1.0, n),
                 min_lon_gap=gap, max_speed_on_accel=cap)
    return RssParamArrays(**{name: table[name] for name in PARAM_NAMES})


def _row(params: RssParamArrays, k: int) -> RssParams:
    return RssParams(**{name: float(getattr(params, name)[k]) for name in PARAM_NAMES})


def _speeds_away_from_cap(rng: np.random.Generator, params: RssParamArrays, n: int) -> np.ndarray:
    v = rng.uniform(0.0, 50.0, n)
    near = np.abs(v - params.max_speed_on_accel) < 1e-2
    return np.where(near, v + 0.05, v)


def _compare(ours: np.ndarray, theirs: np.ndarray, keep: np.ndarray) -> None:
    assert keep.sum() > 0.9 * CASES  # the exclusions are rare edge cases, not the bulk
    np.testing.assert_allclose(ours[keep], theirs[keep], rtol=REL, atol=ABS)


def test_same_direction_matches_ad_rss():
    rng = np.random.default_rng(1)
    p_rear, p_front = _random_params(rng, CASES), _random_params(rng, CASES)
    v_rear, v_front = _speeds_away_from_cap(rng, p_rear, CASES), rng.uniform(0.0, 50.0, CASES)
    ours = lon_safe_distance_same_dir(v_rear, v_front, p_rear, p_front)
    theirs = np.array([same_direction(v_rear[k], v_front[k], _row(p_rear, k), _row(p_front, k))
                       for k in range(CASES)])
    raw = worst_case_stopping_distance(v_rear, p_rear.lon_accel_max, p_rear.response_time,
                                       p_rear.max_speed_on_accel, p_rear.lon_brake_min) - \
        stopping_distance(v_front, p_front.lon_brake_max)  # before the max(0, ·) clamp
    _compare(ours, theirs, keep=np.abs(raw) > 1e-3)


def test_opposite_direction_matches_ad_rss():
    rng = np.random.default_rng(2)
    p_c, p_o = _random_params(rng, CASES), _random_params(rng, CASES)
    p_o = RssParamArrays(**{**{n: getattr(p_o, n) for n in PARAM_NAMES}, "min_lon_gap": np.where(
        np.abs(p_o.min_lon_gap - p_c.min_lon_gap) < 1e-2, p_c.min_lon_gap, p_o.min_lon_gap)})
    v_c, v_o = _speeds_away_from_cap(rng, p_c, CASES), _speeds_away_from_cap(rng, p_o, CASES)
    ours = lon_safe_distance_opposite(v_c, v_o, p_c, p_o)
    theirs = np.array([opposite_direction(v_c[k], v_o[k], _row(p_c, k), _row(p_o, k)) for k in range(CASES)])
    _compare(ours, theirs, keep=np.ones(CASES, dtype=bool))


def test_lateral_matches_ad_rss():
    rng = np.random.default_rng(3)
    p_l, p_r = _random_params(rng, CASES), _random_params(rng, CASES)
    v_l, v_r = rng.uniform(-3.0, 3.0, CASES), rng.uniform(-3.0, 3.0, CASES)
    ours = lat_safe_distance(v_l, v_r, p_l, p_r)
    theirs = np.array([lateral(v_l[k], v_r[k], _row(p_l, k), _row(p_r, k)) for k in range(CASES)])
    # Away from the clamp boundary: ad_rss may return a tiny negative number instead of 0 right at it.
    raw = _lateral_unclamped(v_l, v_r, p_l, p_r)
    _compare(ours, theirs, keep=np.abs(raw) > 1e-3)


def _lateral_unclamped(v_l, v_r, p_l, p_r):
    def reach(u, p):
        u_rho = u + p.lat_accel_max * p.response_time
        return (u + u_rho) / 2 * p.response_time + np.maximum(u_rho, 0.0) ** 2 / (2 * p.lat_brake_min)

    return reach(-v_l, p_l) + reach(v_r, p_r) + 0.5 * (p_l.lat_fluctuation_margin + p_r.lat_fluctuation_margin)


@pytest.mark.parametrize("v_rear, v_front", [(20.0, 10.0), (0.0, 0.0), (33.3, 33.3), (50.0, 0.0)])
def test_ad_rss_defaults_agree_on_named_cases(v_rear, v_front):
    p = RssParams()
    assert lon_safe_distance_same_dir(v_rear, v_front, p, p) == pytest.approx(same_direction(v_rear, v_front, p, p),
                                                                              rel=REL, abs=ABS)
