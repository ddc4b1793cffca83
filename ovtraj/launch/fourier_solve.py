"""The least-squares solve of the launch fit's Fourier series in normalised variables
(:mod:`ovtraj.launch.fourier`; patent CN 2021-07-16, section 5.1).

* Altitude is normalised to ``s = (h - h_min) / (h_max - h_min)`` in [0, 1] and y to
  ``(y - y_mid) / (y_max - y_min)``; the series is fitted in ``s`` with a normalised
  frequency ``W`` (rad per unit s, ``W = w (h_max - h_min)``). Because
  ``k W s = k w h - k w h_min``, the normalised coefficients are converted back by an
  exact rotation per harmonic (see :func:`to_absolute`).
* For fixed ``W`` the problem is linear in the coefficients: a (ridge-)linear least
  squares. Several starting ``W`` are scored by that linear solve, the best is refined
  jointly (``W`` and the coefficients) by ``scipy.optimize.least_squares`` with ``W``
  bounded (:class:`SolverSettings`), and the coefficients are then re-solved exactly at
  the refined ``W`` (never worse than the best start).
* Ridge (Tikhonov): extra residuals ``sqrt(ridge) * k**2 * alpha_k`` and
  ``sqrt(ridge) * k**2 * beta_k`` for k >= 1 on the normalised coefficients (a0 is not
  penalised). Since y is scaled by its range, ``ridge`` is dimensionless. The
  objective is ``sum_i r_i**2 + ridge * sum_k k**4 (alpha_k**2 + beta_k**2)``; the
  penalty is unchanged by the shift to absolute altitude because the rotation keeps
  ``a_k**2 + b_k**2 = alpha_k**2 + beta_k**2`` for every harmonic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares


@dataclass(frozen=True)
class SolverSettings:
    """How the normalised series is fitted: its ``order``, the dimensionless ``ridge``, the
    bounds of W (rad per unit s, ``frequency_bounds``), and the joint refinement's relative
    tolerance (ftol, xtol, gtol) and cap on residual evaluations (max_nfev)."""

    order: int
    ridge: float
    frequency_bounds: tuple[float, float]
    solver_tolerance: float
    max_refine_evaluations: int


def _design(s: np.ndarray, frequency: float, order: int) -> np.ndarray:
    """Columns [1, cos(k W s) for k=1..n, sin(k W s) for k=1..n]; s, W dimensionless."""
    phase = frequency * np.outer(s, np.arange(1, order + 1, dtype=float))
    return np.hstack([np.ones((s.size, 1)), np.cos(phase), np.sin(phase)])


def _design_dfrequency(s: np.ndarray, frequency: float, order: int) -> np.ndarray:
    """d(design)/dW: [0, -k s sin(k W s), k s cos(k W s)]."""
    k = np.arange(1, order + 1, dtype=float)
    ks = np.outer(s, k)
    phase = frequency * ks
    return np.hstack([np.zeros((s.size, 1)), -ks * np.sin(phase), ks * np.cos(phase)])


def _penalty_weights(order: int) -> np.ndarray:
    """k**2 for every alpha_k and beta_k (k >= 1), in coefficient order without c0."""
    k2 = np.arange(1, order + 1, dtype=float) ** 2
    return np.concatenate([k2, k2])


def predict_normalised(s: np.ndarray, frequency: float, coef: np.ndarray) -> np.ndarray:
    """Normalised series c0 + sum_k alpha_k cos(k W s) + beta_k sin(k W s)."""
    order = (coef.size - 1) // 2
    return _design(np.asarray(s, dtype=float), frequency, order) @ coef


def _linear_solve(
    s: np.ndarray, yn: np.ndarray, frequency: float, order: int, ridge: float
) -> tuple[np.ndarray, float]:
    """Coefficients minimising the ridge objective at fixed W, and that objective."""
    design = _design(s, frequency, order)
    if ridge > 0.0:
        penalty = np.hstack(
            [np.zeros((2 * order, 1)), np.diag(math.sqrt(ridge) * _penalty_weights(order))]
        )
        design = np.vstack([design, penalty])
        rhs = np.concatenate([yn, np.zeros(2 * order)])
    else:
        rhs = yn
    coef, *_ = np.linalg.lstsq(design, rhs, rcond=None)
    cost = float(np.sum((design @ coef - rhs) ** 2))
    return coef, cost


def _objective_residuals(
    params: np.ndarray, s: np.ndarray, yn: np.ndarray, order: int, ridge: float
) -> np.ndarray:
    """Data residuals, then ridge residuals sqrt(ridge) k**2 (alpha_k, beta_k)."""
    frequency, coef = params[0], params[1:]
    residual = _design(s, frequency, order) @ coef - yn
    if ridge > 0.0:
        residual = np.concatenate([residual, math.sqrt(ridge) * _penalty_weights(order) * coef[1:]])
    return residual


def _objective_jacobian(
    params: np.ndarray, s: np.ndarray, yn: np.ndarray, order: int, ridge: float
) -> np.ndarray:
    """Analytic Jacobian of :func:`_objective_residuals` w.r.t. (W, coefficients)."""
    frequency, coef = params[0], params[1:]
    data_rows = np.hstack(
        [
            (_design_dfrequency(s, frequency, order) @ coef)[:, None],
            _design(s, frequency, order),
        ]
    )
    if ridge <= 0.0:
        return data_rows
    penalty_rows = np.zeros((2 * order, params.size))
    penalty_rows[:, 2:] = np.diag(math.sqrt(ridge) * _penalty_weights(order))
    return np.vstack([data_rows, penalty_rows])


def fit_normalised(
    s: np.ndarray, yn: np.ndarray, settings: SolverSettings, frequency_starts: Sequence[float]
) -> tuple[float, np.ndarray]:
    """Best (W, coefficients) in normalised variables: multi-start from
    ``frequency_starts`` (W, rad per unit s), joint refine, polish."""
    order, ridge = settings.order, settings.ridge
    lo, hi = settings.frequency_bounds
    starts = sorted({float(np.clip(w, lo, hi)) for w in frequency_starts})
    scored = [(_linear_solve(s, yn, w, order, ridge), w) for w in starts]
    (best_coef, best_cost), best_w = min(scored, key=lambda item: item[0][1])

    x0 = np.concatenate([[best_w], best_coef])
    lower = np.full(x0.size, -np.inf)
    upper = np.full(x0.size, np.inf)
    lower[0], upper[0] = lo, hi
    result = least_squares(
        _objective_residuals,
        x0,
        jac=_objective_jacobian,
        bounds=(lower, upper),
        method="trf",
        x_scale="jac",
        ftol=settings.solver_tolerance,
        xtol=settings.solver_tolerance,
        gtol=settings.solver_tolerance,
        max_nfev=settings.max_refine_evaluations,
        args=(s, yn, order, ridge),
    )
    refined_w = float(np.clip(result.x[0], lo, hi))
    refined_coef, refined_cost = _linear_solve(s, yn, refined_w, order, ridge)
    if refined_cost <= best_cost:
        return refined_w, refined_coef
    return best_w, best_coef


def to_absolute(
    frequency: float,
    coef: np.ndarray,
    *,
    h_min_m: float,
    span_m: float,
    y_offset: float,
    y_scale: float,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Normalised (W, c) -> patent (w in rad/m, a0..a_n, b1..b_n) in absolute h.

    With s = (h - h_min)/span, w = W/span and phi_k = k w h_min, k W s = k w h - phi_k:
    alpha cos(k W s) + beta sin(k W s)
      = (alpha cos phi_k - beta sin phi_k) cos(k w h)
      + (alpha sin phi_k + beta cos phi_k) sin(k w h),
    then y = y_offset + y_scale * (normalised y). Exact: no approximation is involved.
    """
    order = (coef.size - 1) // 2
    w = frequency / span_m
    phi = np.arange(1, order + 1, dtype=float) * w * h_min_m
    alpha = y_scale * coef[1 : order + 1]
    beta = y_scale * coef[order + 1 :]
    a = np.concatenate([[y_offset + y_scale * coef[0]], alpha * np.cos(phi) - beta * np.sin(phi)])
    b = alpha * np.sin(phi) + beta * np.cos(phi)
    return w, a, b
