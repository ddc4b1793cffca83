"""A trust-region interior-point method for small dense NLPs (the J2 correction's solver).

Solves

    minimise f(x)   subject to   c(x) = 0,   lower <= x <= upper

for a handful of variables with exact first derivatives and a Hessian of the
Lagrangian supplied by the caller. It is the barrier method of scipy's
``trust-constr`` (Byrd, Hribar & Nocedal, "An interior point algorithm for
large-scale nonlinear programming", SIAM J. Optim. 9 (1999) 877-900), written for
dense problems of ~5 variables, where scipy's sparse-operator machinery (linear
operators, projections, projected CG) cost more than the propagations it drove: on
the mission chain's correction problems this solver takes half the iterations and
~3.4x less time for the same optima (``benchmarks/interior_point.py``; its
arithmetic per iteration runs in numba kernels, the loop around the caller's
evaluations in Python):

* the bounds become ``h(x) - s = 0`` with slacks ``s > 0`` carrying the log barrier
  ``-mu sum(ln s)``, and the trust region is scaled by the slacks, so a variable on its
  bound only shortens its own slack's step; ``mu`` is lowered superlinearly once the
  barrier subproblem is solved to ``kappa_eps * mu`` (Wächter & Biegler, Math.
  Program. 106 (2006) 25-57, eq. 7), and every step keeps the fraction ``tau`` of each
  slack;
* each barrier subproblem is solved by Byrd-Omojokun trust-region SQP (Nocedal &
  Wright, *Numerical Optimization*, 2nd ed., sec. 18.5): a normal step towards
  feasibility within ``0.8`` of the radius, then a tangential step in the null space of
  the constraint Jacobian; the null space has ``n - m`` (here 1 or 2) dimensions, so
  the tangential trust-region subproblem is solved exactly (Moré & Sorensen 1983;
  Nocedal & Wright sec. 4.3), negative curvature included;
* steps are accepted on the ratio of actual to predicted reduction of the l2 merit
  function, with a second-order correction against the Maratos effect (N&W sec. 15.6)
  and least-squares multipliers (N&W eq. 18.21).

The algorithm's own constants are the published defaults of those sources; the
caller's tolerance, iteration limit, first barrier parameter and first trust radius
come from configs/.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg.lapack import dgeqrf, dorgqr

from ovtraj.deadline import Deadline

# The method's own constants, as published (and as scipy's trust-constr sets them).
# Wächter & Biegler (2006), Table 1: the barrier parameter's update.
_KAPPA_EPS = 10.0  # a barrier subproblem is solved to kappa_eps * mu, then ...
_KAPPA_MU = 0.2  # ... mu falls linearly ...
_THETA_MU = 1.5  # ... or superlinearly, whichever is smaller
# Byrd, Hribar & Nocedal (1999) and Lalee, Nocedal & Plantenga, SIAM J. Optim. 8
# (1998) 682-706, p. 885-892 (scipy: BOUNDARY_PARAMETER, TR_FACTOR, PENALTY_FACTOR,
# SUFFICIENT_REDUCTION_RATIO).
_TAU_MIN = 0.995  # fraction to the boundary
_ZETA = 0.8  # the normal step's share of the radius
_RHO = 0.3  # penalty parameter rule
_ETA = 1e-8  # smallest accepted ratio of actual to predicted reduction
# Nocedal & Wright, Algorithm 4.1: the radius doubles after a good step (ratio above
# 3/4) and falls to a quarter of a rejected step.
_GOOD_RATIO = 0.75
_SHRINK = 0.25
_MAX_RADIUS = 1e3  # scaled variables: far beyond any useful step
# Dependent constraints: a pivot of the Jacobian's QR below this share of the largest.
_RANK_TOLERANCE = 1e-12
# The stop on a vanishing step: the radius below tol times this (scipy's xtol for
# trust-constr as the correction set it, optimality_tol * 1e-4).
_STEP_TOLERANCE_FACTOR = 1e-4
# Slacks start at least this far inside (scaled variables): a start on a bound.
_MIN_SLACK = 1e-8
# Trust-region subproblem: relative size below which an eigenvalue gap or a gradient
# component counts as zero (the hard case), and the boundary's relative tolerance.
_HARD_CASE_TOLERANCE = 1e-12
_BOUNDARY_TOLERANCE = 1e-10
_SECULAR_ITERATIONS = 100  # safeguarded Newton on the secular equation (converges in <10)

CONVERGED = "converged"
STEP_TOLERANCE = "step below tolerance"
ITERATION_LIMIT = "iteration limit"
TIME_LIMIT = "time limit"
SINGULAR = "singular constraint Jacobian"

Evaluation = tuple[float, np.ndarray, np.ndarray, np.ndarray]  # f, grad f, c, dc/dx


@dataclass(frozen=True)
class InteriorPointResult:
    x: np.ndarray
    multipliers: np.ndarray  # of the equality constraints
    iterations: int
    status: str  # CONVERGED, STEP_TOLERANCE, ITERATION_LIMIT, TIME_LIMIT or SINGULAR
    optimality: float  # the KKT error at x (max norm)

    @property
    def message(self) -> str:
        return f"interior point: {self.status} (KKT error {self.optimality:.1e})"


class _Bounds:
    """The finite bounds as linear inequalities ``h(x) = B x + b >= 0``."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray) -> None:
        n = lower.size
        rows, offsets = [], []
        for k in np.flatnonzero(np.isfinite(lower)):
            rows.append(np.eye(n)[k])
            offsets.append(-lower[k])
        for k in np.flatnonzero(np.isfinite(upper)):
            rows.append(-np.eye(n)[k])
            offsets.append(upper[k])
        self.matrix = np.array(rows).reshape(len(rows), n)
        self.offset = np.array(offsets)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.matrix @ x + self.offset


def _factor(
    jacobian: np.ndarray, bound_matrix: np.ndarray, slack: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The scaled problem's constraint Jacobian (m + k, n + k) and its QR factors.

    Rows: the equalities ``dc/dx`` and the bounds ``h(x) - s = 0`` with the slack columns
    scaled by ``S``. Returns the matrix, an orthonormal basis of its rows' span (``Q_1``),
    one of its null space (``Q_2``), the triangular ``R`` of ``matrix.T = Q_1 R``, and
    whether the rows are independent (with equalities, each pivot of ``R`` above
    ``_RANK_TOLERANCE`` of the largest). LAPACK's Householder QR (``dgeqrf``, ``dorgqr``)
    called directly: the factors of ``np.linalg.qr(..., mode="complete")`` to the bit at
    ~half its cost on these ~9 x 7 matrices, where the wrapper's checks are most of it
    (numba's QR takes ~9 s to compile).
    """
    m, n = jacobian.shape
    k = slack.size
    matrix = np.zeros((m + k, n + k))
    matrix[:m, :n] = jacobian
    matrix[m:, :n] = bound_matrix
    matrix[m:, n:] = -np.diag(slack)
    q, r = _complete_qr(matrix.T)
    pivots = np.abs(np.diag(r))
    independent = not m or bool(pivots.min() > _RANK_TOLERANCE * pivots.max())
    return (
        matrix,
        np.ascontiguousarray(q[:, : m + k]),
        np.ascontiguousarray(q[:, m + k :]),
        r,
        independent,
    )


def _complete_qr(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Q`` (rows x rows) and the upper-triangular ``R`` (columns x columns) of a tall
    matrix ``a = Q[:, :columns] R``."""
    rows, columns = a.shape
    factored, tau, _, info = dgeqrf(a)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR factorisation failed (LAPACK dgeqrf info {info})")
    reflectors = np.zeros((rows, rows), order="F")
    reflectors[:, :columns] = factored
    q, _, info = dorgqr(reflectors, tau, overwrite_a=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"QR factorisation failed (LAPACK dorgqr info {info})")
    return q, np.ascontiguousarray(np.triu(factored[:columns]))


# Small dense products as plain loops: numba compiles them in a fraction of the time its
# BLAS-backed ``@`` and ``norm`` take (seconds each on first use), for the same sums.
@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    total = 0.0
    for i in range(a.size):
        total += a[i] * b[i]
    return total


@njit(cache=True)
def _norm(a: np.ndarray) -> float:
    return math.sqrt(_dot(a, a))


@njit(cache=True)
def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for a matrix ``a`` and a vector ``b``."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[i] += a[i, j] * b[j]
    return out


@njit(cache=True)
def _transposed_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a.T @ b`` for a matrix ``a`` and a vector ``b`` (the same sums, in the same order)."""
    return _product(a.T, b)


@njit(cache=True)
def _least_norm(span: np.ndarray, r: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The least-norm ``v`` with ``J v = rhs`` (``J.T = span r``): ``span r^-T rhs``."""
    z = np.empty(rhs.size)
    for i in range(rhs.size):  # forward substitution with the lower triangle r.T
        total = rhs[i]
        for j in range(i):
            total -= r[j, i] * z[j]
        z[i] = total / r[i, i]
    return _product(span, z)


@njit(cache=True)
def _least_squares_multipliers(
    span: np.ndarray, r: np.ndarray, g: np.ndarray, k: int, mu: float
) -> np.ndarray:
    """Least-squares multipliers of the equalities and of ``h(x) - s = 0`` (N&W eq.
    18.21): the ``y`` minimising ``|J.T y + (g, -mu)|``, ``r^-1 span.T (-g, mu)``; the
    bound multipliers are the negatives of the last ``k``."""
    rhs = np.full(g.size + k, mu)
    for i in range(g.size):
        rhs[i] = -g[i]
    b = _transposed_product(span, rhs)
    y = np.empty(b.size)
    for i in range(b.size - 1, -1, -1):  # back substitution
        total = b[i]
        for j in range(i + 1, b.size):
            total -= r[i, j] * y[j]
        y[i] = total / r[i, i]
    return y


@njit(cache=True)
def _residuals(
    c: np.ndarray, x: np.ndarray, slack: np.ndarray, bound_matrix: np.ndarray, offset: np.ndarray
) -> np.ndarray:
    """The scaled problem's constraint values: ``c(x)`` and ``h(x) - s``."""
    bounds = _product(bound_matrix, x)
    out = np.empty(c.size + slack.size)
    for i in range(c.size):
        out[i] = c[i]
    for i in range(slack.size):
        out[c.size + i] = bounds[i] + offset[i] - slack[i]
    return out


@njit(cache=True)
def _kkt_error(
    g: np.ndarray,
    jacobian: np.ndarray,
    bound_matrix: np.ndarray,
    residual: np.ndarray,
    slack: np.ndarray,
    multipliers: np.ndarray,
    mu: float,
) -> float:
    """KKT error (max norms of stationarity, feasibility, complementarity) of the barrier
    problem; with ``mu = 0``, of the problem."""
    m = jacobian.shape[0]
    y, w = multipliers[:m], multipliers[m:]
    from_equalities = _transposed_product(jacobian, y)
    from_bounds = _transposed_product(bound_matrix, w)
    error = 0.0
    for i in range(g.size):
        error = max(error, abs(g[i] + from_equalities[i] + from_bounds[i]))
    for value in residual:
        error = max(error, abs(value))
    for i in range(slack.size):
        error = max(error, abs(-slack[i] * w[i] - mu))
    return error


@njit(cache=True)
def _merit(f: float, slack: np.ndarray, residual: np.ndarray, mu: float, penalty: float) -> float:
    """The l2 merit function of the barrier problem (inf outside the slacks' domain)."""
    barrier = 0.0
    for value in slack:
        if value <= 0.0:
            return math.inf
        barrier -= mu * math.log(value)
    return f + barrier + penalty * _norm(residual)


@njit(cache=True)
def _fraction_to_boundary(scaled_slack_step: np.ndarray, tau: float) -> float:
    """Largest alpha in (0, 1] with 1 + alpha * step >= 1 - tau for every slack."""
    alpha = 1.0
    for value in scaled_slack_step:
        if value < 0.0:
            alpha = min(alpha, -tau / value)
    return alpha


@njit(cache=True)
def trust_region_step(hessian: np.ndarray, gradient: np.ndarray, radius: float) -> np.ndarray:
    """Exact minimiser of ``g.u + u.H.u / 2`` over ``|u| <= radius`` (small dense H).

    Moré & Sorensen (1983) in the eigenbasis of H: ``u = -(H + lam I)^-1 g`` with the
    smallest ``lam >= max(0, -lambda_min)`` that keeps ``|u| <= radius``, found by
    safeguarded Newton on ``1/|u(lam)| - 1/radius``; in the hard case (no gradient along
    the lowest eigenvector) that eigenvector fills the step to the boundary.
    """
    values, vectors = np.linalg.eigh(np.ascontiguousarray(hessian))
    g = _transposed_product(vectors, gradient)
    size = g.size
    lowest = values[0]
    u = np.empty(size)
    if lowest > 0.0:
        for i in range(size):
            u[i] = -g[i] / values[i]
        if _norm(u) <= radius:
            return _product(vectors, u)
    lam_lo = max(0.0, -lowest)
    g_norm = _norm(g)
    lowest_band = _HARD_CASE_TOLERANCE * max(1.0, abs(lowest))
    hard = lowest <= 0.0
    for i in range(size):
        if values[i] - lowest <= lowest_band and abs(g[i]) > _HARD_CASE_TOLERANCE * max(
            g_norm, 1e-300
        ):
            hard = False
    if hard:
        first_lowest = -1
        for i in range(size):
            if values[i] - lowest <= lowest_band:
                u[i] = 0.0
                if first_lowest < 0:
                    first_lowest = i
            else:
                u[i] = -g[i] / (values[i] + lam_lo)
        fill = radius**2 - _dot(u, u)
        if fill >= 0.0:
            u[first_lowest] = math.sqrt(fill)
            return _product(vectors, u)
    lo, hi = lam_lo, lam_lo + g_norm / radius + abs(values[-1])
    lam = hi
    for _ in range(_SECULAR_ITERATIONS):
        length_squared, slope = 0.0, 0.0
        for i in range(size):
            shifted = values[i] + lam
            length_squared += (g[i] / shifted) ** 2
            slope += g[i] ** 2 / shifted**3
        length = math.sqrt(length_squared)
        if abs(length - radius) <= _BOUNDARY_TOLERANCE * radius:
            break
        if length > radius:
            lo = lam
        else:
            hi = lam
        lam += (length - radius) * length**2 / (radius * slope) if slope > 0.0 else 0.0
        if not lo < lam < hi:
            lam = 0.5 * (lo + hi)
    for i in range(size):
        u[i] = -g[i] / (values[i] + lam)
    return _product(vectors, u)


@njit(cache=True)
def _propose(
    g: np.ndarray,
    lagrangian_hessian: np.ndarray,
    residual: np.ndarray,
    matrix: np.ndarray,
    span: np.ndarray,
    null: np.ndarray,
    r: np.ndarray,
    mu: float,
    radius: float,
    tau: float,
    penalty: float,
) -> tuple[np.ndarray, float, float]:
    """One Byrd-Omojokun step of the barrier subproblem in (x, S^-1 s): the step, the
    predicted reduction of the merit function and the updated penalty parameter."""
    n = g.size
    size = matrix.shape[1]
    gradient = np.full(size, -mu)
    hessian = np.zeros((size, size))
    for i in range(n):
        gradient[i] = g[i]
        for j in range(n):
            hessian[i, j] = lagrangian_hessian[i, j]
    for i in range(n, size):
        hessian[i, i] = mu
    # Normal step: the least-norm Gauss-Newton step to feasibility, within zeta * radius
    # and keeping half the fraction to the boundary for the tangential step.
    normal = _least_norm(span, r, residual)  # to -residual: the signs flip below
    shrink = -min(1.0, _ZETA * radius / max(_norm(normal), 1e-300))
    for i in range(size):
        normal[i] *= shrink
    shrink = _fraction_to_boundary(normal[n:], 0.5 * tau)
    for i in range(size):
        normal[i] *= shrink
    # Tangential step in the null space, exact in its n - m dimensions.
    rest = math.sqrt(max(radius**2 - _dot(normal, normal), 0.0))
    step = normal.copy()
    dimensions = null.shape[1]
    if dimensions and rest > 0.0:
        reduced = np.empty((dimensions, dimensions))
        column = np.empty(size)
        for j in range(dimensions):
            for i in range(size):
                column[i] = null[i, j]
            reduced_column = _transposed_product(null, _product(hessian, column))
            for i in range(dimensions):
                reduced[i, j] = reduced_column[i]
        pull = _product(hessian, normal)
        for i in range(size):
            pull[i] += gradient[i]
        tangential = _product(
            null, trust_region_step(reduced, _transposed_product(null, pull), rest)
        )
        for i in range(size):
            step[i] += tangential[i]
    shrink = _fraction_to_boundary(step[n:], tau)
    for i in range(size):
        step[i] *= shrink
    # Predicted reductions of the quadratic model and of the linearised infeasibility.
    model = _dot(gradient, step) + 0.5 * _dot(step, _product(hessian, step))
    linearised = _product(matrix, step)
    for i in range(residual.size):
        linearised[i] += residual[i]
    infeasibility_drop = _norm(residual) - _norm(linearised)
    if infeasibility_drop > 0.0:
        penalty = max(penalty, model / ((1.0 - _RHO) * infeasibility_drop))
    return step, -model + penalty * infeasibility_drop, penalty


def minimize_interior_point(
    evaluate: Callable[[np.ndarray], Evaluation],
    lagrangian_hessian: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    tol: float,
    max_iterations: int,
    barrier_parameter: float,
    trust_radius: float,
    deadline: Deadline | None = None,
) -> InteriorPointResult:
    """Minimise ``f`` subject to ``c(x) = 0`` and the bounds, from ``x0`` (strictly inside).

    ``evaluate(x)`` returns ``(f, grad f, c, dc/dx)``; it may raise ``FloatingPointError``
    where the problem is undefined (the step is then rejected and the radius shrunk).
    ``lagrangian_hessian(x, y)`` returns the Hessian of ``f + y . c``.
    Stops when the KKT error (stationarity, feasibility, complementarity: max norms) is
    at most ``tol``, when the radius falls below ``tol * 1e-4``, after ``max_iterations``
    steps (accepted or not), or at ``deadline``.
    """
    deadline = deadline or Deadline.unlimited()
    bounds = _Bounds(np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))
    point = _Iterate(evaluate, bounds, np.asarray(x0, dtype=float).copy())
    mu = barrier_parameter
    mu_floor = tol / 10.0
    radius = trust_radius
    penalty = 0.0
    iteration = 0
    try:
        independent = point.factor(mu)
        while independent:
            residual = point.residual()
            error = point.kkt_error(residual, 0.0)
            status = _stop_status(error, radius, iteration, tol, max_iterations, deadline)
            if status is not None:
                return point.result(iteration, status, error)
            mu = point.lowered_barrier(residual, mu, mu_floor)
            tau = max(_TAU_MIN, 1.0 - mu)
            iteration += 1

            hessian = np.asarray(
                lagrangian_hessian(point.x, point.equality_multipliers), dtype=float
            )
            accepted, step, penalty = point.step(hessian, residual, mu, radius, tau, penalty)
            step_norm = float(np.linalg.norm(step))
            if accepted is None:
                radius = _SHRINK * step_norm if step_norm > 0.0 else _SHRINK * radius
                continue
            if point.accept(accepted) >= _GOOD_RATIO:
                radius = min(max(radius, 2.0 * step_norm), _MAX_RADIUS)
            independent = point.factor(mu)
    except np.linalg.LinAlgError:
        pass  # an eigen- or linear solve failed: as dependent constraints
    # Dependent constraints (a rank-deficient Jacobian): no step is defined.
    return point.result(iteration, SINGULAR, math.nan)


def _stop_status(
    error: float, radius: float, iteration: int, tol: float, max_iterations: int, deadline: Deadline
) -> str | None:
    """Why the iterations stop here (the deadline asked last), or None to go on."""
    if error <= tol:
        return CONVERGED
    if radius < tol * _STEP_TOLERANCE_FACTOR:
        return STEP_TOLERANCE
    if iteration >= max_iterations:
        return ITERATION_LIMIT
    if deadline.expired():
        return TIME_LIMIT
    return None


# A trial point: x, the slacks, the evaluation there and its reduction ratio.
_Trial = tuple[np.ndarray, np.ndarray, Evaluation, float]


class _Iterate:
    """The current point of :func:`minimize_interior_point`: ``x`` and the slacks ``s = h(x)
    > 0`` carrying the barrier, its evaluation, the factors of the scaled constraint
    Jacobian and the least-squares multipliers (updated after each accepted step; the
    numeric work is compiled, ~35 iterations a mission evaluation)."""

    def __init__(
        self, evaluate: Callable[[np.ndarray], Evaluation], bounds: _Bounds, x: np.ndarray
    ) -> None:
        self.evaluate = evaluate
        self.bound_matrix, self.offset = bounds.matrix, bounds.offset
        self.x = x
        self.n, self.k = x.size, bounds.offset.size
        # The trust region is scaled by the slacks (the step in s is S times the scaled
        # step), so a bound that is nearly active only shortens the step of its own slack.
        self.slack = np.maximum(bounds(x), _MIN_SLACK)
        self.f, self.g, self.c, self.jac = evaluate(x)
        self.m = self.c.size
        self.multipliers = np.zeros(self.m + self.k)

    @property
    def equality_multipliers(self) -> np.ndarray:
        return self.multipliers[: self.m]

    def result(self, iteration: int, status: str, error: float) -> InteriorPointResult:
        return InteriorPointResult(self.x, self.equality_multipliers, iteration, status, error)

    def factor(self, mu: float) -> bool:
        """Factor the Jacobian at (x, s); when its rows are independent (returned), the
        multipliers follow for the barrier parameter ``mu``."""
        self.matrix, self.span, self.null, self.r, independent = _factor(
            self.jac, self.bound_matrix, self.slack
        )
        if independent:
            self.multipliers = _least_squares_multipliers(self.span, self.r, self.g, self.k, mu)
        return independent

    def residual(self) -> np.ndarray:
        return _residuals(self.c, self.x, self.slack, self.bound_matrix, self.offset)

    def kkt_error(self, residual: np.ndarray, mu: float) -> float:
        return _kkt_error(
            self.g, self.jac, self.bound_matrix, residual, self.slack, self.multipliers, mu
        )

    def lowered_barrier(self, residual: np.ndarray, mu: float, mu_floor: float) -> float:
        """The barrier parameter lowered while its subproblem is solved to kappa_eps * mu
        (the multipliers follow each value)."""
        while mu > mu_floor and self.kkt_error(residual, mu) <= _KAPPA_EPS * mu:
            mu = max(mu_floor, min(_KAPPA_MU * mu, mu**_THETA_MU))
            self.multipliers = _least_squares_multipliers(self.span, self.r, self.g, self.k, mu)
        return mu

    def step(
        self,
        hessian: np.ndarray,
        residual: np.ndarray,
        mu: float,
        radius: float,
        tau: float,
        penalty: float,
    ) -> tuple[_Trial | None, np.ndarray, float]:
        """A step from the point within ``radius``: the trial point if accepted (else None),
        the step last tried, and the penalty parameter of the merit function."""
        step, predicted, penalty = _propose(
            self.g,
            hessian,
            residual,
            self.matrix,
            self.span,
            self.null,
            self.r,
            mu,
            radius,
            tau,
            penalty,
        )
        current = _merit(self.f, self.slack, residual, mu, penalty)
        accepted, step = self._trial(
            step,
            current=current,
            predicted=predicted,
            mu=mu,
            penalty=penalty,
            tau=tau,
            radius=radius,
        )
        return accepted, step, penalty

    def _trial(
        self,
        step: np.ndarray,
        *,
        current: float,
        predicted: float,
        mu: float,
        penalty: float,
        tau: float,
        radius: float,
    ) -> tuple[_Trial | None, np.ndarray]:
        """The step's trial point if its merit falls enough, after at most one second-order
        correction, and the step last tried."""
        n = self.n
        for attempt in range(2):
            trial_x, trial_s = self.x + step[:n], self.slack * (1.0 + step[n:])
            trial = _try(self.evaluate, trial_x)
            if trial is None:
                break
            trial_residual = _residuals(trial[2], trial_x, trial_s, self.bound_matrix, self.offset)
            ratio = _ratio(
                current, _merit(trial[0], trial_s, trial_residual, mu, penalty), predicted
            )
            if ratio >= _ETA:
                return (trial_x, trial_s, trial, ratio), step
            if attempt == 1:
                break
            # Second-order correction: back onto the constraints' curvature.
            corrected = step + _least_norm(self.span, self.r, -trial_residual)
            if float(np.linalg.norm(corrected)) > 2.0 * radius:
                break
            step = corrected * _fraction_to_boundary(corrected[n:], tau)
        return None, step

    def accept(self, trial: _Trial) -> float:
        """Move to the trial point; returns its reduction ratio."""
        self.x, self.slack, (self.f, self.g, self.c, self.jac), ratio = trial
        return ratio


def _try(evaluate: Callable[[np.ndarray], Evaluation], x: np.ndarray) -> Evaluation | None:
    try:
        result = evaluate(x)
    except FloatingPointError:
        return None
    return result if math.isfinite(result[0]) and np.all(np.isfinite(result[2])) else None


def _ratio(current: float, trial: float, predicted: float) -> float:
    if not math.isfinite(trial):
        return -math.inf
    if predicted <= 0.0:
        return -math.inf if trial > current else 1.0
    return (current - trial) / predicted
