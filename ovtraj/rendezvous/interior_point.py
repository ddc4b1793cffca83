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
~2.2x less time for the same optima (issue 20, ``benchmarks/interior_point.py``):

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


class _Jacobian:
    """QR factors of a full-row-rank constraint Jacobian (m, n): its range and null space."""

    def __init__(self, jacobian: np.ndarray) -> None:
        m = jacobian.shape[0]
        q, r = np.linalg.qr(jacobian.T, mode="complete")
        pivots = np.abs(np.diag(r[:m]))
        if m and not pivots.min() > _RANK_TOLERANCE * pivots.max():
            raise np.linalg.LinAlgError("the constraint Jacobian is rank-deficient")
        self.matrix = jacobian
        self.range, self.null, self.r = q[:, :m], q[:, m:], r[:m]

    def least_norm(self, rhs: np.ndarray) -> np.ndarray:
        """The least-norm ``v`` with ``J v = rhs``."""
        return self.range @ np.linalg.solve(self.r.T, rhs)

    def least_squares_transpose(self, rhs: np.ndarray) -> np.ndarray:
        """The ``y`` that minimises ``|J^T y - rhs|``."""
        return np.linalg.solve(self.r, self.range.T @ rhs)


def trust_region_step(hessian: np.ndarray, gradient: np.ndarray, radius: float) -> np.ndarray:
    """Exact minimiser of ``g.u + u.H.u / 2`` over ``|u| <= radius`` (small dense H).

    Moré & Sorensen (1983) in the eigenbasis of H: ``u = -(H + lam I)^-1 g`` with the
    smallest ``lam >= max(0, -lambda_min)`` that keeps ``|u| <= radius``, found by
    safeguarded Newton on ``1/|u(lam)| - 1/radius``; in the hard case (no gradient along
    the lowest eigenvector) that eigenvector fills the step to the boundary.
    """
    values, vectors = np.linalg.eigh(hessian)
    g = vectors.T @ gradient
    lowest = float(values[0])
    if lowest > 0.0:
        u = -g / values
        if float(np.linalg.norm(u)) <= radius:
            return vectors @ u
    lam_lo = max(0.0, -lowest)
    g_norm = float(np.linalg.norm(g))
    at_lowest = values - lowest <= _HARD_CASE_TOLERANCE * max(1.0, abs(lowest))
    hard = np.abs(g[at_lowest]) <= _HARD_CASE_TOLERANCE * max(g_norm, 1e-300)
    if lowest <= 0.0 and np.all(hard):
        u = np.zeros_like(g)
        u[~at_lowest] = -g[~at_lowest] / (values[~at_lowest] + lam_lo)
        fill = radius**2 - float(u @ u)
        if fill >= 0.0:
            u[int(np.argmax(at_lowest))] = math.sqrt(fill)
            return vectors @ u
    lo, hi = lam_lo, lam_lo + g_norm / radius + abs(float(values[-1]))
    lam = hi
    for _ in range(_SECULAR_ITERATIONS):
        shifted = values + lam
        length = float(np.linalg.norm(g / shifted))
        if abs(length - radius) <= _BOUNDARY_TOLERANCE * radius:
            break
        if length > radius:
            lo = lam
        else:
            hi = lam
        slope = float(np.sum(g**2 / shifted**3))
        lam += (length - radius) * length**2 / (radius * slope) if slope > 0.0 else 0.0
        if not lo < lam < hi:
            lam = 0.5 * (lo + hi)
    return vectors @ (-g / (values + lam))


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
    x = np.asarray(x0, dtype=float).copy()
    n, k = x.size, bounds.offset.size
    # Slack variables s = h(x) > 0 carry the barrier; the trust region is scaled by them
    # (the step in s is S times the scaled step), so a bound that is nearly active only
    # shortens the step of its own slack.
    slack = np.maximum(bounds(x), _MIN_SLACK)
    mu = barrier_parameter
    mu_floor = tol / 10.0
    radius = trust_radius
    penalty = 0.0
    f, g, c, jac = evaluate(x)
    m = c.size

    def scaled_jacobian() -> _Jacobian:
        matrix = np.zeros((m + k, n + k))
        matrix[:m, :n] = jac
        matrix[m:, :n] = bounds.matrix
        matrix[m:, n:] = -np.diag(slack)
        return _Jacobian(matrix)

    def residuals(c_value: np.ndarray, x_value: np.ndarray, s_value: np.ndarray) -> np.ndarray:
        return np.concatenate((c_value, bounds(x_value) - s_value))

    def kkt_error(mu_value: float) -> float:
        """KKT error of the barrier problem; with ``mu_value = 0``, of the problem."""
        y, w = multipliers[:m], multipliers[m:]
        stationarity = g + jac.T @ y + bounds.matrix.T @ w
        return max(
            float(np.max(np.abs(stationarity))),
            float(np.max(np.abs(residuals(c, x, slack)))) if m + k else 0.0,
            float(np.max(np.abs(-slack * w - mu_value))) if k else 0.0,
        )

    def merit(f_value: float, s_value: np.ndarray, residual: np.ndarray) -> float:
        if np.any(s_value <= 0.0):
            return math.inf
        barrier = -mu * float(np.sum(np.log(s_value)))
        return f_value + barrier + penalty * float(np.linalg.norm(residual))

    def least_squares_multipliers() -> np.ndarray:
        # Of the equalities and of h(x) - s = 0; the bound multipliers are their negatives.
        return factors.least_squares_transpose(np.concatenate((-g, np.full(k, mu))))

    multipliers = np.zeros(m + k)
    iteration = 0
    try:
        factors = scaled_jacobian()
        multipliers = least_squares_multipliers()
        while True:
            error = kkt_error(0.0)
            if error <= tol:
                return InteriorPointResult(x, multipliers[:m], iteration, CONVERGED, error)
            if radius < tol * _STEP_TOLERANCE_FACTOR:
                return InteriorPointResult(x, multipliers[:m], iteration, STEP_TOLERANCE, error)
            if iteration >= max_iterations:
                return InteriorPointResult(x, multipliers[:m], iteration, ITERATION_LIMIT, error)
            if deadline.expired():
                return InteriorPointResult(x, multipliers[:m], iteration, TIME_LIMIT, error)
            while mu > mu_floor and kkt_error(mu) <= _KAPPA_EPS * mu:
                mu = max(mu_floor, min(_KAPPA_MU * mu, mu**_THETA_MU))
                multipliers = least_squares_multipliers()
            tau = max(_TAU_MIN, 1.0 - mu)
            iteration += 1

            # The scaled problem in (x, S^-1 s): gradient, Hessian (barrier block mu I).
            gradient = np.concatenate((g, np.full(k, -mu)))
            hessian = np.zeros((n + k, n + k))
            hessian[:n, :n] = lagrangian_hessian(x, multipliers[:m])
            hessian[n:, n:] = mu * np.eye(k)
            residual = residuals(c, x, slack)
            # Normal step: the least-norm Gauss-Newton step to feasibility, within zeta *
            # radius and keeping half the fraction to the boundary for the tangential step.
            normal = factors.least_norm(-residual)
            normal *= min(1.0, _ZETA * radius / max(float(np.linalg.norm(normal)), 1e-300))
            normal *= _fraction_to_boundary(normal[n:], 0.5 * tau)
            # Tangential step in the null space, exact in its n - m dimensions.
            basis = factors.null
            rest = math.sqrt(max(radius**2 - float(normal @ normal), 0.0))
            step = normal
            if basis.shape[1] and rest > 0.0:
                u = trust_region_step(
                    basis.T @ hessian @ basis, basis.T @ (gradient + hessian @ normal), rest
                )
                step = normal + basis @ u
            step = step * _fraction_to_boundary(step[n:], tau)

            # Predicted reductions of the quadratic model and of the linearised infeasibility.
            model = float(gradient @ step + 0.5 * step @ hessian @ step)
            residual_norm = float(np.linalg.norm(residual))
            linearised = float(np.linalg.norm(residual + factors.matrix @ step))
            infeasibility_drop = residual_norm - linearised
            if infeasibility_drop > 0.0:
                penalty = max(penalty, model / ((1.0 - _RHO) * infeasibility_drop))
            predicted = -model + penalty * infeasibility_drop
            current = merit(f, slack, residual)

            accepted = None
            for attempt in range(2):
                trial_x, trial_s = x + step[:n], slack * (1.0 + step[n:])
                trial = _try(evaluate, trial_x)
                if trial is None:
                    break
                trial_residual = residuals(trial[2], trial_x, trial_s)
                ratio = _ratio(current, merit(trial[0], trial_s, trial_residual), predicted)
                if ratio >= _ETA:
                    accepted = trial_x, trial_s, trial, ratio
                    break
                if attempt == 1:
                    break
                # Second-order correction: back onto the constraints' curvature.
                corrected = step + factors.least_norm(-trial_residual)
                if float(np.linalg.norm(corrected)) > 2.0 * radius:
                    break
                step = corrected * _fraction_to_boundary(corrected[n:], tau)
            step_norm = float(np.linalg.norm(step))
            if accepted is None:
                radius = _SHRINK * step_norm if step_norm > 0.0 else _SHRINK * radius
                continue
            x, slack, (f, g, c, jac), ratio = accepted
            if ratio >= _GOOD_RATIO:
                radius = min(max(radius, 2.0 * step_norm), _MAX_RADIUS)
            factors = scaled_jacobian()
            multipliers = least_squares_multipliers()
    except np.linalg.LinAlgError:
        # A singular constraint Jacobian (dependent constraints): no step is defined.
        return InteriorPointResult(x, multipliers[:m], iteration, SINGULAR, math.nan)


def _fraction_to_boundary(scaled_slack_step: np.ndarray, tau: float) -> float:
    """Largest alpha in (0, 1] with 1 + alpha * step >= 1 - tau for every slack."""
    falling = scaled_slack_step < 0.0
    if not np.any(falling):
        return 1.0
    return float(min(1.0, np.min(-tau / scaled_slack_step[falling])))


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
