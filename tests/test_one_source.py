"""One source for the RSS formulas and the forward simulation's controllers (issue 48, decision 2): the functions
the auditor and the policy costs run with numpy over arrays are the ones the planner's kernel compiles with numba
over scalars (compiled here as the kernel is: cached, stamped by the sources it compiles). On random inputs (speeds from standstill to 60 m/s, gaps from -20 to 300 m, every parameter set of
the presets and random valid ones) the two paths agree to 1e-9."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss import jit
from sumo_rss.jit import RssRow, rss_row, select
from sumo_rss.planner.behavior import controllers, kernel  # noqa: F401 (registers the jitable functions)
from sumo_rss.planner.behavior.controllers import BicycleState, IdmParams, VehicleLimits
from sumo_rss.planner.behavior.forward_sim import rss_table
from sumo_rss.planner.behavior.lane_change import laterally_safe
from sumo_rss.planner.behavior.leaders import following_distance
from sumo_rss.rss import formulas
from sumo_rss.rss.params import PARAM_NAMES, PRESETS, RssParamArrays, RssParams, preset_params

N = 4000
RSS_OUTPUTS = 16
TOLERANCE = 1e-9


def _random_params(rng: np.random.Generator, n: int) -> RssParamArrays:
    """Parameter sets of the presets (both roles) and random valid ones, one per row."""
    presets = [preset_params(p, role) for p in PRESETS for role in ("ego", "background")]
    rows = []
    for k in range(n):
        if k % 3 == 0:
            rows.append(presets[k % len(presets)])
            continue
        b_corr = rng.uniform(1.0, 6.0)
        b_min = b_corr + rng.uniform(0.0, 3.0)
        rows.append(RssParams(response_time=rng.uniform(0.1, 2.5), lon_accel_max=rng.choice([0.0, rng.uniform(0, 5)]),
                              lon_brake_min=b_min, lon_brake_min_correct=b_corr,
                              lon_brake_max=b_min + rng.uniform(0.0, 5.0), lat_accel_max=rng.uniform(0.0, 2.0),
                              lat_brake_min=rng.uniform(0.2, 2.0), lat_fluctuation_margin=rng.uniform(0.0, 1.0),
                              min_lon_gap=rng.choice([0.0, rng.uniform(0, 3)]),
                              max_speed_on_accel=rng.uniform(5.0, 100.0)))
    return RssParamArrays.stack(rows)


@jit.jitable
def _every_formula(v1, v2, u1, u2, gap, p1, p2):  # noqa: ANN001, ANN202
    """Every formula, as floats: called over arrays as the auditor calls them, and compiled by _compiled_rss."""
    low, high = formulas.safe_speed_interval_same_dir(select(v1 > 50.0, np.inf, gap), v2, p2, gap + 10.0, v1, p2, p1)
    return (formulas.speed_after_response(v1, p1.lon_accel_max, p1.response_time, p1.max_speed_on_accel),
            formulas.distance_during_response(v1, p1.lon_accel_max, p1.response_time, p1.max_speed_on_accel),
            formulas.stopping_distance(v1, p1.lon_brake_max),
            formulas.worst_case_stopping_distance(v1, p1.lon_accel_max, p1.response_time, p1.max_speed_on_accel,
                                                  p1.lon_brake_min),
            formulas.lon_reach(v1, p1, p1.lon_brake_min_correct),
            formulas.lon_safe_distance_same_dir(v1, v2, p1, p2),
            formulas.lon_safe_distance_opposite(v1, v2, p1, p2),
            formulas.lon_safe_distance_opposite(v1, v2, p1, p2, True),
            formulas.lat_safe_distance(u1, u2, p1, p2),
            formulas.lateral_reach(u1, p1),
            select(formulas.is_safe_distance(gap, formulas.lon_safe_distance_same_dir(v1, v2, p1, p2)), 1.0, 0.0),
            formulas.max_safe_speed_behind(gap, v2, p1, p2),
            formulas.min_safe_speed_ahead(gap, v2, p1, p2),
            low, high,
            formulas.combine_opposite(v1, v2, p1.min_lon_gap, p2.min_lon_gap))


@jit.kernel
def _compiled_rss(v1, v2, u1, u2, gap, t1, t2):  # noqa: ANN001, ANN202
    """:func:`_every_formula` compiled, one scalar input set at a time (parameters as the kernel passes them)."""
    out = np.empty((RSS_OUTPUTS, v1.size))
    for k in range(v1.size):
        row = _every_formula(v1[k], v2[k], u1[k], u2[k], gap[k], rss_row(t1, k), rss_row(t2, k))
        for j in range(RSS_OUTPUTS):
            out[j, k] = row[j]
    return out


@jit.kernel
def _compiled_controllers(v, v0, v_lead, gap, floor, idm, heading, steer, limits, d, u, t1, t2, dt):  # noqa
    out = np.empty((11, v.size))
    p = kernel.IdmRow(idm[0], idm[1], idm[2], idm[3], idm[4], idm[5], idm[6], idm[7])
    lim = kernel.LimitsRow(limits[0], limits[1], limits[2], limits[3], limits[4], limits[5], limits[6], limits[7],
                           limits[8])
    for k in range(v.size):
        p1, p2 = rss_row(t1, k), rss_row(t2, k)
        moved = controllers.bicycle_step(BicycleState(gap[k], d[k], heading[k], v[k], floor[k] - 2.0, steer[k] * 0.1),
                                         v0[k], steer[k], lim, dt, 2.0)
        out[0, k] = controllers.acc_acceleration(v[k], v0[k], v_lead[k], gap[k], p, floor[k])
        out[1, k] = controllers.idm_speed_command(v[k], v0[k], v_lead[k], gap[k], p, dt, floor[k])
        out[2, k] = controllers.pure_pursuit_steer(0.0, 0.0, heading[k], gap[k], d[k], lim.wheelbase)
        out[3, k], out[4, k], out[5, k] = moved.x, moved.y, moved.heading
        out[6, k], out[7, k], out[8, k] = moved.speed, moved.accel, moved.curvature
        out[9, k] = 1.0 if laterally_safe(d[k], 0.0, u[k], -u[k], 1.8, 2.5, p1, p2) else 0.0
        out[10, k] = following_distance(v[k], v_lead[k], p1, p2, gap[k])
    return out


def test_rss_formulas_agree_compiled_and_vectorised():
    rng = np.random.default_rng(48)
    v1, v2 = rng.uniform(0.0, 60.0, N), rng.uniform(0.0, 60.0, N)
    v1[::7], v2[::11] = 0.0, 0.0  # standstill
    u1, u2 = rng.uniform(-3.0, 3.0, N), rng.uniform(-3.0, 3.0, N)
    gap = rng.uniform(-20.0, 300.0, N)
    p1, p2 = _random_params(rng, N), _random_params(rng, N)
    vectorised = np.array([np.broadcast_to(np.asarray(o, dtype=float), (N,))
                           for o in _every_formula(v1, v2, u1, u2, gap, p1, p2)])
    compiled = _compiled_rss(v1, v2, u1, u2, gap, rss_table(p1, N), rss_table(p2, N))
    assert np.array_equal(np.isfinite(vectorised), np.isfinite(compiled))
    assert np.isinf(vectorised).any() and np.isfinite(vectorised).all(axis=0).any()  # both kinds of input occur
    finite = np.isfinite(vectorised)
    assert np.max(np.abs(vectorised[finite] - compiled[finite])) <= TOLERANCE
    assert np.array_equal(vectorised[~finite], compiled[~finite])


@pytest.mark.parametrize("p", [IdmParams(), IdmParams(accel=2.0, approach_time=1.0)], ids=["idm", "approach"])
def test_controllers_agree_compiled_and_vectorised(p):
    """IDM/ACC, pure pursuit, the bicycle model, the lateral RSS test and the RSS following distance; IDM's
    free-road term and the one that reaches the desired speed at the acceleration limit, and a desired speed of 0
    ('stop') in every fifth input."""
    rng = np.random.default_rng(5)
    v, v_lead = rng.uniform(0.0, 40.0, N), rng.uniform(-1.0, 40.0, N)
    v0 = np.where(np.arange(N) % 5 == 0, 0.0, rng.uniform(0.0, 40.0, N))
    gap, floor = rng.uniform(0.0, 200.0, N), rng.uniform(0.0, 60.0, N)
    heading, steer = rng.uniform(-0.3, 0.3, N), rng.uniform(-0.8, 0.8, N)
    d, u = rng.uniform(-5.0, 5.0, N), rng.uniform(-2.0, 2.0, N)
    limits, dt = VehicleLimits(), 0.2
    p1, p2 = _random_params(rng, N), _random_params(rng, N)
    moved = controllers.bicycle_step(BicycleState(gap, d, heading, v, floor - 2.0, steer * 0.1), v0, steer, limits,
                                     dt, 2.0)
    vectorised = np.array([controllers.acc_acceleration(v, v0, v_lead, gap, p, floor),
                           controllers.idm_speed_command(v, v0, v_lead, gap, p, dt, floor),
                           controllers.pure_pursuit_steer(0.0, 0.0, heading, gap, d, limits.wheelbase), *moved,
                           laterally_safe(d, 0.0, u, -u, 1.8, 2.5, p1, p2), following_distance(v, v_lead, p1, p2, gap)],
                          dtype=float)
    compiled = _compiled_controllers(v, v0, v_lead, gap, floor, np.array([getattr(p, f) for f in p.__dataclass_fields__]),
                                     heading, steer, np.array([getattr(limits, f) for f in limits.__dataclass_fields__]),
                                     d, u, rss_table(p1, N), rss_table(p2, N), dt)
    # np.tanh (the ACC blend) is numpy's own vector code and libm's in numba: they differ in the last bit.
    assert np.max(np.abs(vectorised - compiled)) <= TOLERANCE
    assert 0.05 < vectorised[9].mean() < 0.95  # both outcomes of the lateral test occur


def test_rss_row_has_the_parameter_fields():
    assert RssRow._fields == PARAM_NAMES
    table = rss_table(RssParamArrays.stack([RssParams(), preset_params("epsilon", "ego")]), 2)
    assert table.shape == (2, len(PARAM_NAMES))
    assert table[1, PARAM_NAMES.index("response_time")] == pytest.approx(0.2)


def test_the_kernel_cache_is_stamped_by_every_source_it_compiles():
    """numba stamps a cached function by its own file only; the kernel's cache is stamped by a hash of every
    module whose functions it compiles, so an edit of the formulas recompiles it."""
    sources = jit.cache_sources()
    for module in ("sumo_rss.rss.formulas", "sumo_rss.planner.behavior.controllers",
                   "sumo_rss.planner.behavior.kernel", "sumo_rss.planner.behavior.leaders",
                   "sumo_rss.planner.behavior.lane_change", "sumo_rss.boxes", "sumo_rss.angles"):
        assert module in sources
