"""The SSC QP on osqp (epsilon.md §6.6-§6.7) against its own constraints and against a dense scipy solve, the
low-speed primitive, and the motion layer's failure handling."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import LinearConstraint, minimize

from sumo_rss.planner.motion.bezier import JERK_HESSIAN, PiecewiseBezier, bernstein
from sumo_rss.planner.motion.primitive import knot_indices, low_speed_primitive, path_derivatives
from sumo_rss.planner.motion.ssc_qp import BASIS, DynamicBounds, MotionFailure, QpProblem, SscSolver, assemble, \
    control_points, relative_to_start

TOL = 1e-6
BOUNDS = DynamicBounds()


def _swerve(s_start: float = 250.0, weight: float = 1e3, middle_left: float = 0.7) -> QpProblem:
    """Three cubes over 0..0.4..1.0..1.6 s at 10 m/s; the reference swings 0.6 m to the left and back; the middle
    cube reaches ``middle_left`` [m] to the left."""
    knots = np.array([0.0, 0.4, 1.0, 1.6])
    cubes = np.array([[[s_start - 1.0, s_start + 10.0], [-0.5, 0.7]],
                      [[s_start + 2.0, s_start + 12.0], [-0.5, middle_left]],
                      [[s_start + 8.0, s_start + 18.0], [-0.5, 0.7]]])
    ref_t = np.linspace(0.0, 1.6, 9)
    ref = np.column_stack([s_start + 10.0 * ref_t, 0.6 * np.sin(np.pi * ref_t / 1.6)])
    return QpProblem(knots, cubes, np.array([[s_start, 10.0, 0.0], [0.0, 0.0, 0.0]]),
                     np.array([[s_start + 16.0, 10.0], [0.0, 0.0]]), ref_t, ref, weight, BOUNDS)


def _squeezed() -> tuple[QpProblem, float]:
    """The swerve with the middle cube's left bound at half the free solution's largest lateral control point
    there, so that bound must be active; and that bound [m]."""
    free = SscSolver().solve(_swerve())
    bound = 0.5 * float(free.control_points(0)[1, 1].max())
    return _swerve(middle_left=bound), bound


def _limits(curve: PiecewiseBezier, knot: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k-th derivative just before and just after a knot, from the segments on either side."""
    j = int(np.searchsorted(curve.knots, knot)) - 1
    left = PiecewiseBezier(curve.knots[j:j + 2], curve.ctrl[j:j + 1]).evaluate(np.array([knot]), k)[0]
    right = PiecewiseBezier(curve.knots[j + 1:j + 3], curve.ctrl[j + 1:j + 2]).evaluate(np.array([knot]), k)[0]
    return left, right


def test_equalities_hold_to_1e_6():
    problem, _ = _squeezed()
    curve = SscSolver().solve(problem)
    for k in range(3):
        assert np.allclose(curve.evaluate(np.array([0.0]), k)[0], problem.start[:, k], atol=TOL, rtol=0.0)
    for k in range(2):
        assert np.allclose(curve.evaluate(np.array([1.6]), k)[0], problem.end[:, k], atol=TOL, rtol=0.0)
    for knot in problem.knots[1:-1]:
        for k in range(3):  # position, velocity and acceleration are continuous
            left, right = _limits(curve, knot, k)
            assert np.allclose(left, right, atol=TOL, rtol=0.0), (knot, k)


def test_every_sampled_point_is_inside_its_cube_and_the_dynamic_bounds():
    problem, bound = _squeezed()
    curve = SscSolver().solve(problem)
    for j in range(problem.segments):
        t = np.linspace(problem.knots[j], problem.knots[j + 1], 41)
        p = curve.evaluate(t, 0)
        assert np.all(p >= problem.cubes[j, :, 0] - TOL) and np.all(p <= problem.cubes[j, :, 1] + TOL)
        v, a = curve.evaluate(t, 1), curve.evaluate(t, 2)
        assert BOUNDS.s_speed[0] - TOL <= v[:, 0].min() and v[:, 0].max() <= BOUNDS.s_speed[1] + TOL
        assert np.abs(v[:, 1]).max() <= BOUNDS.d_speed[1] + TOL
        assert BOUNDS.s_accel[0] - TOL <= a[:, 0].min() and a[:, 0].max() <= BOUNDS.s_accel[1] + TOL
        assert np.abs(a[:, 1]).max() <= BOUNDS.d_accel[1] + TOL
    # The middle cube's lateral bound shapes the swerve: a control point of the solution lies on it.
    assert bound > 0.05 and curve.control_points(0)[1, 1].max() == pytest.approx(bound, abs=TOL)


def test_constraint_rows_are_the_curves_values_for_each_problems_own_segment_durations():
    """A·x on a random curve: the start's position, velocity and acceleration, the end's position and velocity,
    and every segment's position, velocity and acceleration control points. Two problems with the same number of
    segments (the matrix pattern is built once per N) but different durations each get their own values."""
    rng = np.random.default_rng(7)
    for knots in (np.array([0.0, 0.4, 1.0, 1.6]), np.array([0.0, 1.1, 1.3, 2.9])):
        problem = replace(_swerve(), knots=knots)
        m = assemble(problem)
        curve = PiecewiseBezier(knots, rng.uniform(-5.0, 5.0, (3, 2, 6)))
        ax = m.A @ (curve.ctrl @ np.linalg.inv(BASIS.T)).ravel()
        start = np.stack([curve.evaluate(knots[:1], k)[0] for k in range(3)], axis=1)  # [dim, (p, v, a)]
        end = np.stack([curve.evaluate(knots[-1:], k)[0] for k in range(2)], axis=1)
        assert np.allclose(ax[:6], start.ravel(), rtol=0.0, atol=1e-9)
        assert np.allclose(ax[6:10], end.ravel(), rtol=0.0, atol=1e-9)
        hull = np.concatenate([curve.control_points(k) for k in range(3)], axis=-1)  # [N, dim, 6 + 5 + 4]
        assert np.allclose(ax[m.n_eq:], hull.ravel(), rtol=0.0, atol=1e-9)


def test_the_cost_is_jerk_plus_reference_tracking():
    """On the solution, ½xᵀPx + qᵀx + w·Σ‖ref_k‖² equals ∫‖jerk‖²dt (by quadrature) + w·Σ‖p(t_k) − ref_k‖²."""
    problem = _swerve(s_start=0.0, weight=np.array([1.0, 30.0]))
    m = assemble(problem)
    curve = SscSolver().solve(problem)
    x = (curve.ctrl @ np.linalg.inv(BASIS.T)).ravel()  # back to the solver's variables
    P = m.P.toarray()
    P = P + np.triu(P, 1).T
    objective = 0.5 * x @ P @ x + m.q @ x + np.sum(problem.weight * problem.ref ** 2)
    t = np.linspace(0.0, 1.6, 16001)
    jerk = curve.evaluate(t, 3)
    integral = np.trapezoid(np.sum(jerk * jerk, axis=1), t)
    tracking = np.sum(problem.weight * (curve.evaluate(problem.ref_t, 0) - problem.ref) ** 2)
    assert objective == pytest.approx(integral + tracking, rel=1e-5)
    # The jerk part from the control points: Σ_j cᵀHc / T³ per dimension.
    hessian = sum(c @ JERK_HESSIAN @ c / T ** 3 for cs, T in zip(curve.ctrl, np.diff(problem.knots)) for c in cs)
    assert hessian == pytest.approx(integral, rel=1e-5)


def test_osqp_matches_a_dense_scipy_solve_of_the_same_qp():
    """scipy's trust-constr (an interior-point method on the dense matrices) as the reference."""
    problem, _ = _squeezed()
    m = assemble(relative_to_start(problem))
    P = m.P.toarray()
    P = P + np.triu(P, 1).T
    reference = minimize(lambda x: 0.5 * x @ P @ x + m.q @ x, np.zeros(P.shape[0]), jac=lambda x: P @ x + m.q,
                         hess=lambda x: P, constraints=[LinearConstraint(m.A.toarray(), m.l, m.u)],
                         method="trust-constr", options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 5000})
    assert reference.status in (1, 2), reference.message
    curve = SscSolver().solve(problem)
    dense = PiecewiseBezier(problem.knots, control_points(problem, reference.x))
    t = np.linspace(0.0, 1.6, 161)
    shift = np.array([problem.start[0, 0], 0.0])
    assert np.allclose(curve.evaluate(t, 0), dense.evaluate(t, 0) + shift, atol=1e-4, rtol=0.0)
    assert np.allclose(curve.evaluate(t, 1), dense.evaluate(t, 1), atol=1e-3, rtol=0.0)
    # osqp's (polished) optimum is at least as good as the interior-point one.
    x = (replace(curve, ctrl=curve.ctrl - (shift[:, None] / np.diff(problem.knots)[:, None, None]))
         .ctrl @ np.linalg.inv(BASIS.T)).ravel()
    assert 0.5 * x @ P @ x + m.q @ x <= reference.fun + 1e-9 * abs(reference.fun)


def test_the_solution_does_not_depend_on_where_along_the_road_it_is():
    """s is solved relative to the start: the same manoeuvre 3 km further gives the same curve, shifted."""
    near, far = SscSolver().solve(_swerve(0.0)), SscSolver().solve(_swerve(3000.0))
    t = np.linspace(0.0, 1.6, 33)
    assert np.allclose(far.evaluate(t, 0) - near.evaluate(t, 0), [3000.0, 0.0], atol=1e-6)


def test_an_infeasible_corridor_is_reported_not_crashed_on():
    problem = _swerve()
    cubes = problem.cubes.copy()
    cubes[1, 0] = (problem.start[0, 0] + 40.0, problem.start[0, 0] + 50.0)  # 40 m in 0.4 s from 10 m/s
    cubes[2, 0] = (problem.start[0, 0] + 40.0, problem.start[0, 0] + 50.0)
    with pytest.raises(MotionFailure) as failure:
        SscSolver().solve(QpProblem(problem.knots, cubes, problem.start, problem.end, problem.ref_t, problem.ref,
                                    problem.weight, BOUNDS))
    assert failure.value.reason == "qp_infeasible"


def test_a_stop_whose_polishing_fails_is_refined_not_refused():
    """An ego at 1.8 m/s stopping 1.45 m on (the corridor of a straight lane): osqp's polishing fails on the
    degenerate active set (ṡ ≥ 0 meeting the stop) and its ADMM iterate breaks ṡ ≥ 0 by 2.8e-5 m/s; refined, the
    feasible QP is solved to the tolerance instead of being refused as 'qp_inaccurate'."""
    v0, stop = 1.8, 1.45
    brake = v0 * v0 / (2.0 * stop)
    knots = np.append(np.round(np.arange(0.0, 4.81, 0.4), 10), 5.0)
    s_low = np.array([98.5, 97.5, 96.5, 93.5] + [89.5] * 9)
    cubes = np.stack([np.column_stack([s_low, np.full(13, 101.5)]), np.tile([-4.1, 4.1], (13, 1))], axis=1)
    ref_t = np.round(np.arange(0.0, 5.01, 0.2), 10)
    ref_s = 100.0 + np.where(ref_t < v0 / brake, v0 * ref_t - 0.5 * brake * ref_t ** 2, stop)
    problem = QpProblem(knots, cubes, np.array([[100.0, v0, -brake], [0.0, 0.0, 0.0]]),
                        np.array([[100.0 + stop, 0.0], [0.0, 0.0]]), ref_t, np.column_stack([ref_s, 0 * ref_t]),
                        np.array([1.0, 100.0]), BOUNDS)
    solver = SscSolver()
    curve = solver.solve(problem)
    assert solver.refinements == 1
    t = np.linspace(0.0, 5.0, 2001)
    assert curve.evaluate(t, 1)[:, 0].min() >= -TOL
    assert curve.evaluate(np.array([5.0]), 0)[0] == pytest.approx([100.0 + stop, 0.0], abs=TOL)
    assert np.all(np.diff(curve.evaluate(t, 0)[:, 0]) >= -TOL)


def test_bernstein_basis_partitions_unity():
    tau = np.linspace(0.0, 1.0, 11)
    assert np.allclose(bernstein(5, tau).sum(axis=1), 1.0)


def test_low_speed_primitive_joins_the_states_and_never_reverses():
    t = np.round(np.arange(0.0, 5.0 + 1e-9, 0.1), 10)
    motion = np.array([[10.0, 1.0, 0.0], [14.0, 0.0, 0.0]])  # (s, ṡ, s̈): from 1 m/s to stopped 4 m on
    path = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])  # (d, d', d''): ending 0.5 m to the left, straight
    s, d, vs, vd, a_s, a_d = low_speed_primitive(t, np.array([5.0]), motion, path)
    assert (s[0], d[0], vs[0]) == pytest.approx((10.0, 0.0, 1.0))
    assert (s[-1], d[-1], vs[-1]) == pytest.approx((14.0, 0.5, 0.0), abs=1e-9)
    assert np.all(np.diff(s) >= -1e-12) and np.all(vs >= 0.0)
    # d follows arc length: no sideways motion without forward motion.
    assert np.all(np.abs(vd[vs == 0.0]) == 0.0)
    assert np.allclose(np.gradient(s, t), vs, atol=0.05)


def test_low_speed_primitive_moves_sideways_only_while_it_moves_forward():
    """From 2 m/s to stopped 0.6 m on in 1 s, then on to 2 m on: the first s(t) quintic overshoots its knot to
    0.6246 m and is held there into the next second; d(s) (slope 0.3) must hold too, not jump to the next piece's
    value at 0.0246 m past its start (it moved 7 mm sideways at standstill)."""
    t = np.round(np.arange(0.0, 2.0 + 1e-9, 0.05), 10)
    motion = np.array([[0.0, 2.0, 0.0], [0.6, 0.0, 0.0], [2.0, 2.0, 0.0]])
    path = np.array([[0.0, 0.3, 0.0], [0.18, 0.3, 0.0], [0.6, 0.3, 0.0]])
    s, d, vs, vd, _, _ = low_speed_primitive(t, np.array([1.0, 2.0]), motion, path)
    assert s.max() == pytest.approx(2.0) and np.any(s[(t > 1.0) & (t < 1.5)] > 0.62)  # held past the knot
    assert np.allclose(d, 0.3 * s, atol=1e-9)  # the straight path, wherever the car is on it
    still = np.diff(s) == 0.0
    assert still.any() and np.all(np.diff(d)[still] == 0.0) and np.all(vd[vs == 0.0] == 0.0)


def test_low_speed_primitive_keeps_its_heading_while_creeping_over_a_standing_piece():
    """The behaviour layer stops the ego angled 19.7° into a gap at the end of an acceleration lane (2.3 mm on, then
    standing); the first s(t) quintic overshoots that knot at ~0.11 m/s into the standing pieces. Their lateral
    slope was 0, so the heading from (ṡ, ḋ) snapped to the frame's axis in one 0.1 s step and the front bumper
    swung 0.79 m sideways (merge_onramp, demand 0.5, seed 0, 83.6 s)."""
    t = np.round(np.arange(0.0, 3.0 + 1e-9, 0.1), 10)
    slope = np.tan(np.radians(19.68))
    motion = np.array([[200.0, 0.151, -0.24]] + [[200.0023, 0.0, 0.0]] * 3)
    path = np.array([[0.4241, slope, 0.0]] * 4)
    s, d, vs, vd, _, _ = low_speed_primitive(t, np.array([1.0, 2.0, 3.0]), motion, path)
    moving = vs > 0.05
    assert np.any(moving[1:]) and np.any(s > 200.0023 + 0.01)  # it creeps past the knot: what this test is about
    np.testing.assert_allclose(np.degrees(np.arctan2(vd[moving], vs[moving])), 19.68, atol=1e-6)
    assert np.allclose(d, 0.4241)


def test_low_speed_primitive_keeps_the_behaviour_timing_and_path():
    # The ego waits 2 s at the end of an acceleration lane, then accelerates (jerk 1 m/s³) along a path that
    # bends left with constant d'' = 0.2 /m (a circle-like arc: d = 0.1 Δs²).
    t_ref = np.round(np.arange(0.0, 5.0 + 1e-9, 0.2), 10)
    go = np.maximum(t_ref - 2.0, 0.0)
    s_ref, v_ref, a_ref = 100.0 + go ** 3 / 6.0, 0.5 * go ** 2, go
    d_ref = 0.1 * (s_ref - 100.0) ** 2
    heading = np.arctan(0.2 * (s_ref - 100.0))
    k = np.concatenate([[0], knot_indices(t_ref, len(t_ref) - 1)])
    assert np.allclose(t_ref[k], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    path = path_derivatives(s_ref, d_ref, heading)
    moved = path[k]
    assert np.allclose(moved[k > 10, 2], 0.2, atol=0.02)  # d'' where the car moves; 0 while it stands
    t = np.round(np.arange(0.0, 5.0 + 1e-9, 0.1), 10)
    motion = np.column_stack([s_ref, v_ref, a_ref])[k]
    s, d, vs, vd, a_s, _ = low_speed_primitive(t, t_ref[k[1:]], motion, moved)
    at_knots = np.isin(t, t_ref[k])
    assert np.allclose(s[at_knots], s_ref[k], atol=1e-9) and np.allclose(vs[at_knots], v_ref[k], atol=1e-9)
    assert np.allclose(d[at_knots], d_ref[k], atol=1e-9)
    # Standing for the first 2 s: no motion at all, forward or sideways; then it moves as asked, not later.
    waiting = t <= 2.0
    assert np.allclose(s[waiting], 100.0) and np.allclose(d[waiting], 0.0) and np.all(vd[waiting] == 0.0)
    assert vs[t == 3.0][0] == pytest.approx(0.5) and np.all(np.diff(s) >= -1e-12)
    # Between the knots it stays on the path: heading atan(ḋ/ṡ) as the path's, within 0.01 rad.
    moving = vs > 0.05
    path_heading = np.arctan(0.2 * (s[moving] - 100.0))
    assert np.allclose(np.arctan2(vd[moving], vs[moving]), path_heading, atol=0.01)
    assert np.allclose(d, 0.1 * (s - 100.0) ** 2, atol=0.01)
