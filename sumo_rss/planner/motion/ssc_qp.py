"""The SSC quadratic programme (epsilon.md §6.7): a piecewise degree-5 Bézier in (s, d), one segment per corridor
cube, minimising jerk plus a pull towards the behaviour layer's trajectory, solved with osqp.

Variables: the scaled control points c[j, dim, i] (:mod:`.bezier`), 12 per segment.
Cost ½xᵀPx + qᵀx = Σ_j ∫ ‖jerk‖² dt + w·Σ_k ‖p(t_k) − p_ref(t_k)‖².
Equalities: start position, velocity and acceleration; end position and velocity; position, velocity and
acceleration continuity at every junction (6N + 4 rows). Inequalities (sufficient by the convex-hull property):
the 6 position control points of each segment inside its cube, the 5 velocity and 4 acceleration control points
inside the dynamic bounds (30 rows per segment).

The sparsity pattern depends only on the number of segments, so the matrices' structure is built once per N and
one osqp solver per N is kept: each cycle only the values are updated, and osqp warm-starts from that solver's
previous solution. Units: m, s, m/s, m/s².
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
import osqp
import scipy.sparse as sp

from .bezier import ACC_FACTOR, D1, D2, D3, DEGREE, JERK_HESSIAN, N_CTRL, VEL_FACTOR, PiecewiseBezier, bernstein

DIMS = 2  # s, d
PER_SEGMENT = DIMS * N_CTRL
INEQ_PER_DIM = N_CTRL + (N_CTRL - 1) + (N_CTRL - 2)  # 6 position, 5 velocity, 4 acceleration control points
SOLVED = osqp.SolverStatus.OSQP_SOLVED


class MotionFailure(Exception):
    """The motion layer found no trajectory this cycle; ``reason`` says why (a short, stable tag)."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


@dataclass(frozen=True)
class DynamicBounds:
    """Bounds on every segment's derivative control points (epsilon.md §6.5; braking capped at the ego's
    hard-brake limit of the forward simulation)."""

    s_speed: tuple[float, float] = (0.0, 50.0)  # [m/s]
    s_accel: tuple[float, float] = (-5.0, 3.0)  # [m/s²]
    d_speed: tuple[float, float] = (-2.5, 2.5)  # [m/s]
    d_accel: tuple[float, float] = (-1.25, 1.25)  # [m/s²]


@dataclass(frozen=True, eq=False)
class QpProblem:
    """One instance: ``knots`` [N+1] segment boundaries [s] (relative), ``cubes[j, dim]`` = (low, high) position
    bounds [m], ``start[dim]`` = (p, v, a) and ``end[dim]`` = (p, v), reference samples at ``ref_t`` [K] with
    positions ``ref[K, 2]``, weights ``weight`` [1/s⁵] (a number, or one per dimension (s, d))."""

    knots: np.ndarray
    cubes: np.ndarray  # [N, 2, 2]
    start: np.ndarray  # [2, 3]
    end: np.ndarray  # [2, 2]
    ref_t: np.ndarray
    ref: np.ndarray
    weight: float | np.ndarray
    bounds: DynamicBounds

    @property
    def segments(self) -> int:
        return len(self.knots) - 1


@dataclass(frozen=True, eq=False)
class QpMatrices:
    """osqp's form: minimise ½xᵀPx + qᵀx subject to l ≤ Ax ≤ u (P upper-triangular); the first ``n_eq`` rows
    are the equalities."""

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    l: np.ndarray
    u: np.ndarray
    n_eq: int


def _var(seg: np.ndarray, dim: np.ndarray, i: np.ndarray) -> np.ndarray:
    return (seg * DIMS + dim) * N_CTRL + i


# The solver's variables are, per segment and dimension, z = (c0, Δc0, Δ²c0, Δ³c0, Δ³c1, Δ³c2) with c = BASIS·z:
# the jerk cost then acts on the last three alone, so a diagonal scaling (osqp's Ruiz) separates the huge jerk
# curvature from the small tracking one. In the control points themselves osqp needs thousands of iterations.
BASIS = np.linalg.inv(np.vstack([np.eye(N_CTRL)[0], D1[0], D2[0], D3]))
_E = np.eye(N_CTRL)

# Row templates in control-point space: (row within the group, segment offset, coefficients on that segment's
# 6 control points, scaling by the segment's duration T: 'T' (×T), '1' or '/T' (÷T)).
_START = [(0, 0, _E[0], "T"), (1, 0, VEL_FACTOR * D1[0], "1"), (2, 0, ACC_FACTOR * D2[0], "/T")]
_END = [(0, 0, _E[5], "T"), (1, 0, VEL_FACTOR * D1[4], "1")]
_JOIN = [(0, 0, _E[5], "T"), (0, 1, -_E[0], "T"),
         (1, 0, VEL_FACTOR * D1[4], "1"), (1, 1, -VEL_FACTOR * D1[0], "1"),
         (2, 0, ACC_FACTOR * D2[3], "/T"), (2, 1, -ACC_FACTOR * D2[0], "/T")]
_INEQ = [(i, 0, _E[i], "T") for i in range(N_CTRL)] + \
    [(N_CTRL + i, 0, VEL_FACTOR * D1[i], "1") for i in range(N_CTRL - 1)] + \
    [(2 * N_CTRL - 1 + i, 0, ACC_FACTOR * D2[i], "/T") for i in range(N_CTRL - 2)]

_SCALES = ("T", "1", "/T")  # a template entry's scaling by its segment's duration T: ×T, ×1, ÷T


def _entries(template: list) -> tuple[np.ndarray, ...]:
    """The template's non-zero entries on the basis variables z: (row, segment offset, z index, coefficient,
    scaling as an index into _SCALES)."""
    out = []
    for row, offset, coefs, scale in template:
        on_z = coefs @ BASIS
        out += [(row, offset, int(i), float(on_z[i]), _SCALES.index(scale))
                for i in np.flatnonzero(np.abs(on_z) > 1e-12)]
    return tuple(np.array(x) for x in zip(*out))


_GROUPS = {name: _entries(template) for name, template in
           (("start", _START), ("end", _END), ("join", _JOIN), ("ineq", _INEQ))}


@dataclass(frozen=True, eq=False)
class _Pattern:
    """The stored entries of A and P for N segments, in osqp's column-major order (built once per N): A's entry
    value is ``a_coef`` scaled by its segment's ``a_seg`` duration as ``a_scale`` (an index into _SCALES) says;
    P's are the ``p_take`` elements of the cost's blocks [N, DIMS, 6, 6]."""

    a_shape: tuple[int, int]
    a_indices: np.ndarray
    a_indptr: np.ndarray
    a_coef: np.ndarray
    a_seg: np.ndarray
    a_scale: np.ndarray
    n_eq: int
    p_indices: np.ndarray
    p_indptr: np.ndarray
    p_take: np.ndarray


def _group(name: str, segments: np.ndarray, first_row: int, rows_per: int) -> tuple[np.ndarray, ...]:
    """Entries of a template repeated over ``segments`` × dims; group g = (segment index k, dim) starts at row
    first_row + (k·DIMS + dim)·rows_per. Returns (rows, columns, coefficients, segments, scale indices)."""
    r, off, c, coef, scale = _GROUPS[name]
    k, dim, e = np.meshgrid(np.arange(segments.size), np.arange(DIMS), np.arange(r.size), indexing="ij")
    seg = segments[k] + off[e]
    rows = first_row + (k * DIMS + dim) * rows_per + r[e]
    return tuple(x.ravel() for x in (rows, _var(seg, dim, c[e]), coef[e], seg, scale[e]))


def _column_major(rows: np.ndarray, cols: np.ndarray, n_cols: int) -> tuple[np.ndarray, np.ndarray]:
    """The order that stores entries (rows, cols) column by column, and the CSC column pointers."""
    order = np.lexsort((rows, cols))
    return order, np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=n_cols))])


@functools.lru_cache(maxsize=64)
def _pattern(N: int) -> _Pattern:
    """A's rows: the start and end equalities, the joins', then every segment's inequalities; P: the upper
    triangle of every segment's and dimension's 6×6 block."""
    groups = [("start", np.array([0]), 3), ("end", np.array([N - 1]), 2), ("join", np.arange(N - 1), 3),
              ("ineq", np.arange(N), INEQ_PER_DIM)]
    parts, first = [], 0
    for name, segments, per in groups:
        parts.append(_group(name, segments, first, per))
        first += segments.size * DIMS * per
    rows, cols, coef, seg, scale = (np.concatenate(x) for x in zip(*parts))
    order, a_indptr = _column_major(rows, cols, N * PER_SEGMENT)
    upper = np.triu_indices(N_CTRL)
    k, dim, e = np.meshgrid(np.arange(N), np.arange(DIMS), np.arange(upper[0].size), indexing="ij")
    p_rows, p_cols = _var(k, dim, upper[0][e]).ravel(), _var(k, dim, upper[1][e]).ravel()
    p_take = np.ravel_multi_index((k, dim, upper[0][e], upper[1][e]), (N, DIMS, N_CTRL, N_CTRL)).ravel()
    p_order, p_indptr = _column_major(p_rows, p_cols, N * PER_SEGMENT)
    return _Pattern((first, N * PER_SEGMENT), rows[order], a_indptr, coef[order], seg[order], scale[order],
                    (3 + 2 + 3 * (N - 1)) * DIMS, p_rows[p_order], p_indptr, p_take[p_order])


def assemble(problem: QpProblem) -> QpMatrices:
    """The QP's matrices on the basis variables (see :data:`BASIS`); the stored entries depend only on N."""
    N, b = problem.segments, problem.bounds
    T = np.diff(problem.knots)
    if np.any(T <= 0.0):
        raise MotionFailure("qp_shape", "segment durations must be positive")
    pat = _pattern(N)
    T_entry = T[pat.a_seg]
    factor = np.where(pat.a_scale == _SCALES.index("T"), T_entry,
                      np.where(pat.a_scale == _SCALES.index("/T"), 1.0 / T_entry, 1.0))
    A = sp.csc_matrix((pat.a_coef * factor, pat.a_indices, pat.a_indptr), shape=pat.a_shape)
    eq = np.concatenate([problem.start.ravel(), problem.end.ravel(), np.zeros(3 * (N - 1) * DIMS)])
    lo_pos, hi_pos = problem.cubes[..., 0], problem.cubes[..., 1]  # [N, 2]
    speed = np.array([b.s_speed, b.d_speed])
    accel = np.array([b.s_accel, b.d_accel])
    low = np.concatenate([np.repeat(lo_pos[..., None], N_CTRL, -1),
                          np.broadcast_to(speed[:, :1], (N, DIMS, N_CTRL - 1)),
                          np.broadcast_to(accel[:, :1], (N, DIMS, N_CTRL - 2))], axis=-1)
    high = np.concatenate([np.repeat(hi_pos[..., None], N_CTRL, -1),
                           np.broadcast_to(speed[:, 1:], (N, DIMS, N_CTRL - 1)),
                           np.broadcast_to(accel[:, 1:], (N, DIMS, N_CTRL - 2))], axis=-1)
    blocks, q = _cost(problem, T)
    P = sp.csc_matrix((blocks.ravel()[pat.p_take], pat.p_indices, pat.p_indptr), shape=(N * PER_SEGMENT,) * 2)
    return QpMatrices(P, q, A, np.concatenate([eq, low.ravel()]), np.concatenate([eq, high.ravel()]), pat.n_eq)


def _cost(problem: QpProblem, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Jerk (2H/T³ per segment and dim) plus reference tracking w·‖T·B(τ_k)·c − ref_k‖², on the basis
    variables: the Hessian's blocks [N, DIMS, 6, 6] and q."""
    N = problem.segments
    w = np.broadcast_to(np.asarray(problem.weight, dtype=float), (DIMS,))
    blocks = np.repeat((2.0 * JERK_HESSIAN)[None, None], N, 0) / (T ** 3)[:, None, None, None]  # [N, 1, 6, 6]
    blocks = np.repeat(blocks, DIMS, axis=1)  # [N, 2, 6, 6]
    q = np.zeros((N, DIMS, N_CTRL))
    seg = np.clip(np.searchsorted(problem.knots, problem.ref_t, side="right") - 1, 0, N - 1)
    tau = np.clip((problem.ref_t - problem.knots[seg]) / T[seg], 0.0, 1.0)
    row = T[seg, None] * bernstein(DEGREE, tau)  # [K, 6]: p(t_k) = row · c
    np.add.at(blocks, seg, 2.0 * w[None, :, None, None] * (row[:, :, None] * row[:, None, :])[:, None])
    np.add.at(q, seg, -2.0 * w[None, :, None] * problem.ref[:, :, None] * row[:, None, :])
    return BASIS.T @ blocks @ BASIS, (q @ BASIS).ravel()


def control_points(problem: QpProblem, x: np.ndarray) -> np.ndarray:
    """[N, 2, 6] scaled control points of a solution ``x`` on the basis variables."""
    return x.reshape(problem.segments, DIMS, N_CTRL) @ BASIS.T


def relative_to_start(problem: QpProblem) -> QpProblem:
    """The same problem with s measured from the start position (every s bound, state and reference shifted)."""
    s0 = float(problem.start[0, 0])
    on_s = np.array([[s0], [0.0]])
    return replace(problem, cubes=problem.cubes - on_s, start=problem.start - on_s * np.eye(1, 3),
                   end=problem.end - on_s * np.eye(1, 2), ref=problem.ref - on_s[:, 0])


class SscSolver:
    """osqp, one solver per number of segments: the matrices' values are updated in place and osqp warm-starts
    from that solver's previous solution. ADMM stops at ``eps``; polishing then solves the KKT system of the
    active set exactly. When polishing fails, osqp still reports "solved" with the ADMM iterate, whose constraints
    are only met to about ``eps``: such a solution is refined from where it is with ADMM at ``refine_eps``. A
    solution whose equalities or bounds are then still off by more than ``tolerance`` is refused."""

    def __init__(self, eps: float = 1e-5, max_iter: int = 4000, tolerance: float = 1e-6, refine_eps: float = 1e-9,
                 refine_max_iter: int = 20000):
        self.settings = dict(verbose=False, eps_abs=eps, eps_rel=eps, polishing=True, max_iter=max_iter,
                             warm_starting=True)
        self.refine = dict(eps_abs=refine_eps, eps_rel=refine_eps, max_iter=refine_max_iter)
        self.tolerance = tolerance
        self._solvers: dict[int, osqp.OSQP] = {}
        self.iterations = 0  # of the last solve (with its refinement)
        self.refinements = 0  # solves refined so far

    def solve(self, problem: QpProblem) -> PiecewiseBezier:
        """The optimal curve; raises :class:`MotionFailure` ('qp_infeasible', 'qp_not_solved', 'qp_inaccurate')
        otherwise. s is solved relative to the start (positions of hundreds of metres would swamp the absolute
        tolerance) and shifted back."""
        s0 = float(problem.start[0, 0])
        shifted = relative_to_start(problem)
        m = assemble(shifted)
        solver = self._solvers.get(problem.segments)
        if solver is None:
            solver = osqp.OSQP()
            solver.setup(m.P, m.q, m.A, m.l, m.u, **self.settings)
            self._solvers[problem.segments] = solver
        else:
            solver.update(Px=m.P.data, Ax=m.A.data, q=m.q, l=m.l, u=m.u)
        x = self._solved(solver)
        off = _constraint_error(m, x)
        if off > self.tolerance:  # polishing failed: refine the ADMM iterate, warm-started from it
            self.refinements += 1
            solver.update_settings(**self.refine)
            try:
                x = self._solved(solver, self.iterations)
            finally:
                solver.update_settings(eps_abs=self.settings["eps_abs"], eps_rel=self.settings["eps_rel"],
                                       max_iter=self.settings["max_iter"])
            off = _constraint_error(m, x)
            if off > self.tolerance:
                raise MotionFailure("qp_inaccurate", f"constraints off by {off:.1e}")
        ctrl = control_points(problem, x)
        ctrl[:, 0, :] += s0 / np.diff(problem.knots)[:, None]  # p = T·Σc·B and Σ B = 1
        return PiecewiseBezier(problem.knots, ctrl)

    def _solved(self, solver: osqp.OSQP, iterations_before: int = 0) -> np.ndarray:
        """The solver's solution; raises :class:`MotionFailure` unless osqp reports it solved."""
        result = solver.solve(raise_error=False)
        self.iterations = iterations_before + int(result.info.iter)
        if result.info.status_val != SOLVED:
            reason = "qp_infeasible" if "infeasible" in result.info.status else "qp_not_solved"
            raise MotionFailure(reason, result.info.status)
        return np.asarray(result.x)


def _constraint_error(m: QpMatrices, x: np.ndarray) -> float:
    """How far ``x`` is off the equalities and outside the bounds of ``m`` (0: it meets all of them)."""
    ax = m.A @ x
    return max(float(np.abs(ax[:m.n_eq] - m.l[:m.n_eq]).max()), float(np.max(m.l - ax)), float(np.max(ax - m.u)),
               0.0)
