"""The J2 correction's interior-point solver on problems with published optima.

References: Hock & Schittkowski, *Test Examples for Nonlinear Programming Codes*
(Springer, 1981), problems 6 and 7; a bound-active quadratic solved by hand; scipy's
``trust-constr`` (the same algorithm, a second implementation); and the optimality
conditions of the trust-region subproblem (Moré & Sorensen 1983; Nocedal & Wright,
*Numerical Optimization*, 2nd ed., Theorem 4.1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import NonlinearConstraint, minimize

from ovtraj.deadline import Deadline
from ovtraj.rendezvous.interior_point import (
    CONVERGED,
    ITERATION_LIMIT,
    SINGULAR,
    TIME_LIMIT,
    minimize_interior_point,
    trust_region_step,
)

INF = np.inf
SOLVER = {"tol": 1e-8, "max_iterations": 200, "barrier_parameter": 1e-4, "trust_radius": 0.1}


def hs6():
    """min (1 - x1)^2  s.t.  10 (x2 - x1^2) = 0; x* = (1, 1), f* = 0 (HS 6)."""

    def evaluate(x):
        f = (1 - x[0]) ** 2
        g = np.array([-2 * (1 - x[0]), 0.0])
        c = np.array([10 * (x[1] - x[0] ** 2)])
        return f, g, c, np.array([[-20 * x[0], 10.0]])

    def hessian(x, y):
        return np.array([[2.0 - 20 * y[0], 0.0], [0.0, 0.0]])

    return evaluate, hessian, np.array([-1.2, 1.0])


def hs7():
    """min ln(1 + x1^2) - x2  s.t.  (1 + x1^2)^2 + x2^2 = 4; x* = (0, sqrt 3) (HS 7)."""

    def evaluate(x):
        a = 1 + x[0] ** 2
        f = math.log(a) - x[1]
        g = np.array([2 * x[0] / a, -1.0])
        c = np.array([a**2 + x[1] ** 2 - 4])
        return f, g, c, np.array([[4 * a * x[0], 2 * x[1]]])

    def hessian(x, y):
        a = 1 + x[0] ** 2
        f_xx = (2 * a - 4 * x[0] ** 2) / a**2
        c_xx = 4 * a + 8 * x[0] ** 2
        return np.array([[f_xx + y[0] * c_xx, 0.0], [0.0, 2 * y[0]]])

    return evaluate, hessian, np.array([2.0, 2.0])


def bound_active():
    """min (x1 - 2)^2 + (x2 - 1)^2  s.t.  x1 + x2 = 1, x1 <= 0.5: x* = (0.5, 0.5), f* = 2.5.

    Without the bound the optimum is (1, 0): the bound is active and its multiplier is
    1 (by hand: 2 (x1 - 2) + y + z = 0 and 2 (x2 - 1) + y = 0 at (0.5, 0.5))."""

    def evaluate(x):
        f = (x[0] - 2) ** 2 + (x[1] - 1) ** 2
        g = np.array([2 * (x[0] - 2), 2 * (x[1] - 1)])
        return f, g, np.array([x[0] + x[1] - 1]), np.array([[1.0, 1.0]])

    def hessian(x, y):
        return 2.0 * np.eye(2)

    return evaluate, hessian, np.array([0.0, 0.0])


@pytest.mark.parametrize(
    ("problem", "lower", "upper", "x_star", "f_star"),
    [
        (hs6, [-INF, -INF], [INF, INF], [1.0, 1.0], 0.0),
        (hs7, [-INF, -INF], [INF, INF], [0.0, math.sqrt(3.0)], -math.sqrt(3.0)),
        (bound_active, [-INF, -INF], [0.5, INF], [0.5, 0.5], 2.5),
    ],
)
def test_published_optima(problem, lower, upper, x_star, f_star):
    evaluate, hessian, x0 = problem()
    result = minimize_interior_point(
        evaluate, hessian, x0, np.array(lower), np.array(upper), **SOLVER
    )
    assert result.status == CONVERGED, result.message
    np.testing.assert_allclose(result.x, x_star, atol=1e-6)
    assert evaluate(result.x)[0] == pytest.approx(f_star, abs=1e-8)
    assert result.optimality <= SOLVER["tol"]


def test_same_optimum_as_scipy_trust_constr():
    """A bounded, nonconvex problem: both implementations of the method agree."""

    def evaluate(x):
        f = 100 * (x[1] - x[0] ** 2) ** 2 + (1 - x[0]) ** 2 + x[2] ** 2
        g = np.array(
            [-400 * x[0] * (x[1] - x[0] ** 2) - 2 * (1 - x[0]), 200 * (x[1] - x[0] ** 2), 2 * x[2]]
        )
        c = np.array([x[0] ** 2 + x[1] ** 2 + x[2] ** 2 - 1.5])
        return f, g, c, 2 * x[None, :]

    def objective_hessian(x):
        return np.array(
            [
                [1200 * x[0] ** 2 - 400 * x[1] + 2, -400 * x[0], 0.0],
                [-400 * x[0], 200.0, 0.0],
                [0.0, 0.0, 2.0],
            ]
        )

    def hessian(x, y):
        return objective_hessian(x) + 2 * y[0] * np.eye(3)

    lower, upper = np.array([-2.0, -2.0, 0.1]), np.array([0.9, 2.0, 2.0])
    x0 = np.array([0.5, 0.5, 0.5])
    ours = minimize_interior_point(evaluate, hessian, x0, lower, upper, **SOLVER)
    reference = minimize(
        lambda x: evaluate(x)[0],
        x0,
        jac=lambda x: evaluate(x)[1],
        hess=objective_hessian,
        method="trust-constr",
        bounds=list(zip(lower, upper, strict=True)),
        constraints=[
            NonlinearConstraint(
                lambda x: evaluate(x)[2],
                0.0,
                0.0,
                jac=lambda x: evaluate(x)[3],
                hess=lambda x, v: 2 * v[0] * np.eye(3),
            )
        ],
        options={"gtol": 1e-10, "xtol": 1e-12, "barrier_tol": 1e-10, "maxiter": 2000},
    )
    assert ours.status == CONVERGED, ours.message
    # By hand: x1 sits on its bound 0.9; on x2^2 + x3^2 = 0.69, d/dx2 of
    # 100 (x2 - 0.81)^2 + 0.69 - x2^2 vanishes at x2 = 162 / 198 = 9 / 11.
    x_star = np.array([0.9, 9.0 / 11.0, math.sqrt(0.69 - (9.0 / 11.0) ** 2)])
    np.testing.assert_allclose(ours.x, x_star, atol=1e-7)
    np.testing.assert_allclose(ours.x, reference.x, atol=1e-4)
    # trust-constr stops a little short of the optimum (2.6e-7 above it here).
    assert evaluate(x_star)[0] - 1e-12 <= evaluate(ours.x)[0] <= reference.fun + 1e-12


def test_iteration_and_time_limits_stop_it():
    evaluate, hessian, x0 = hs6()
    free = np.array([-INF, -INF]), np.array([INF, INF])
    limited = minimize_interior_point(
        evaluate, hessian, x0, *free, **{**SOLVER, "max_iterations": 2}
    )
    assert (limited.status, limited.iterations) == (ITERATION_LIMIT, 2)
    expired = Deadline(1e-9, "test.time_limit_s")
    timed = minimize_interior_point(evaluate, hessian, x0, *free, **SOLVER, deadline=expired)
    assert (timed.status, timed.iterations) == (TIME_LIMIT, 0)


def test_a_step_into_an_undefined_region_is_rejected_not_fatal():
    """``evaluate`` raising FloatingPointError (e.g. a propagation that cannot finish)."""
    evaluate, hessian, _ = hs7()
    calls = {"refused": 0}

    def guarded(x):
        if np.linalg.norm(x) > 3.0:  # the first trial steps land out there
            calls["refused"] += 1
            raise FloatingPointError("outside the domain")
        return evaluate(x)

    result = minimize_interior_point(
        guarded,
        hessian,
        np.array([2.0, 2.0]),
        np.array([-INF, -INF]),
        np.array([INF, INF]),
        **{**SOLVER, "trust_radius": 5.0},
    )
    assert calls["refused"] > 0
    assert result.status == CONVERGED
    np.testing.assert_allclose(result.x, [0.0, math.sqrt(3.0)], atol=1e-6)


def _check_trust_region_optimality(hessian, gradient, radius, u):
    """Moré-Sorensen: (H + lam I) u = -g, lam >= 0, lam (radius - |u|) = 0, H + lam I >= 0."""
    length = float(np.linalg.norm(u))
    assert length <= radius * (1 + 1e-9)
    residual = hessian @ u + gradient
    lam = 0.0 if length < radius * (1 - 1e-9) else -float(u @ residual) / length**2
    assert lam >= -1e-9
    np.testing.assert_allclose(residual + lam * u, 0.0, atol=1e-8 * (1 + np.abs(gradient).max()))
    assert np.linalg.eigvalsh(hessian + lam * np.eye(len(u)))[0] >= -1e-8


@pytest.mark.parametrize("seed", range(40))
def test_trust_region_step_meets_the_optimality_conditions(seed):
    rng = np.random.default_rng(seed)
    n = 1 + seed % 3
    a = rng.normal(size=(n, n))
    hessian = a + a.T  # indefinite about half the time
    gradient = rng.normal(size=n)
    radius = float(rng.uniform(0.05, 3.0))
    u = trust_region_step(hessian, gradient, radius)
    _check_trust_region_optimality(hessian, gradient, radius, u)
    if n == 2:
        # A second method: the best of a dense polar grid over the disc.
        r, t = np.meshgrid(np.linspace(0, radius, 400), np.linspace(0, 2 * np.pi, 721))
        grid = np.stack([r * np.cos(t), r * np.sin(t)], axis=-1).reshape(-1, 2)
        values = grid @ gradient + 0.5 * np.einsum("ij,jk,ik->i", grid, hessian, grid)
        ours = float(u @ gradient + 0.5 * u @ hessian @ u)
        assert ours <= values.min() + 1e-9


def test_trust_region_step_hard_case():
    """No gradient along the negative-curvature direction: that direction fills the step."""
    hessian, gradient, radius = np.diag([-1.0, 2.0]), np.array([0.0, 1.0]), 2.0
    u = trust_region_step(hessian, gradient, radius)
    # lam = 1: u2 = -1 / (2 + 1), |u1| = sqrt(4 - 1/9).
    assert u[1] == pytest.approx(-1.0 / 3.0)
    assert abs(u[0]) == pytest.approx(math.sqrt(4.0 - 1.0 / 9.0))
    _check_trust_region_optimality(hessian, gradient, radius, u)


def test_dependent_constraints_end_with_a_status_not_an_exception():
    """Two copies of one constraint: the Jacobian has rank 1, no step is defined."""

    def evaluate(x):
        c = np.array([x[0] + x[1] - 1.0, 2.0 * (x[0] + x[1] - 1.0)])
        return float(x @ x), 2.0 * x, c, np.array([[1.0, 1.0], [2.0, 2.0]])

    result = minimize_interior_point(
        evaluate,
        lambda x, y: 2.0 * np.eye(2),
        np.array([0.3, 0.2]),
        np.array([-INF, -INF]),
        np.array([INF, INF]),
        **SOLVER,
    )
    assert (result.status, result.iterations) == (SINGULAR, 0)
    np.testing.assert_array_equal(result.x, [0.3, 0.2])  # where it was, not a wild step
