"""Fitting the launch fit's Fourier series (:mod:`ovtraj.launch.fourier`) to data: the
samples checked and normalised, the frequency bounds, the fit and its leave-one-out errors.

Reference: patent CN 2021-07-16 'whole-process trajectory optimisation based on a proxy
model', section 5.1. All SI; the solve runs in dimensionless variables
(:mod:`ovtraj.launch.fourier_solve`): several starting ``W``
(:data:`DEFAULT_FREQUENCY_STARTS`) are scored by the linear solve and the best is refined
with ``W`` bounded to ``[DEFAULT_MIN_FREQUENCY, pi / (order * max ds))`` (the upper end is
where the highest harmonic would alias on the grid).

Leave-one-out (LOO): each point is dropped in turn, the series refitted (same
normalisation, ridge and frequency bounds, warm-started from the full fit's ``W``) and
the dropped point predicted; RMS and max absolute LOO errors judge the fit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ovtraj.launch.fourier import FourierSeries
from ovtraj.launch.fourier_solve import (
    SolverSettings,
    fit_normalised,
    predict_normalised,
    to_absolute,
)
from ovtraj.units import M_PER_KM

# Normalised starting frequencies W (rad per unit s, i.e. per whole altitude range):
# 0.2*pi ... 1.0*pi. At W <= pi the fitted range spans at most half a period of the
# fundamental, so a monotone, nearly linear output is captured by the first harmonics
# and the basis stays well conditioned; below ~0.2*pi every harmonic is nearly
# polynomial across the range and the 2n+1 columns become almost collinear.
DEFAULT_FREQUENCY_STARTS: tuple[float, ...] = tuple(
    float(v) for v in np.pi * np.linspace(0.2, 1.0, 5)
)
# Lower bound on W during refinement (rad per unit s). It must stay positive (W = 0
# collapses the basis to a constant); 0.05*pi keeps the fundamental's phase change
# over the range at 9 deg, still distinguishable from a constant.
DEFAULT_MIN_FREQUENCY = 0.05 * np.pi
# Relative tolerance (ftol, xtol, gtol) of the joint least-squares refinement.
DEFAULT_SOLVER_TOLERANCE = 1e-12
# Cap on residual evaluations of the joint refinement. With ridge > 0 it converges in
# a few tens; with ridge = 0 and barely more points than parameters (e.g. the LOO
# refits) the objective is a long flat valley in which the trust region crawls, and
# the cap bounds the cost. The coefficients are re-solved exactly at the final W and
# the result is never worse than the best start, so a capped refinement is safe.
DEFAULT_MAX_REFINE_EVALUATIONS = 100


@dataclass(frozen=True)
class FitSamples:
    """Validated, sorted samples and their normalisation."""

    h_m: np.ndarray  # sorted, m
    y: np.ndarray  # in sorted order, unit of y
    order_index: np.ndarray  # h_m = input_h[order_index]
    s: np.ndarray
    yn: np.ndarray
    h_min_m: float
    span_m: float
    y_offset: float
    y_scale: float

    def absolute(self, frequency: float, coef: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """The normalised (W, c) of these samples as the patent's (w in rad/m, a0..a_n,
        b1..b_n) in absolute h (:func:`~ovtraj.launch.fourier_solve.to_absolute`)."""
        return to_absolute(
            frequency,
            coef,
            h_min_m=self.h_min_m,
            span_m=self.span_m,
            y_offset=self.y_offset,
            y_scale=self.y_scale,
        )


def _validate_options(
    order: int, ridge: float, solver_tolerance: float, max_refine_evaluations: int
) -> None:
    if isinstance(order, bool) or not isinstance(order, int | np.integer) or order < 1:
        raise ValueError(f"order must be a positive integer; got {order!r}")
    if not (isinstance(ridge, int | float) and math.isfinite(ridge) and ridge >= 0.0):
        raise ValueError(f"ridge must be a finite number >= 0; got {ridge!r}")
    if not (math.isfinite(solver_tolerance) and solver_tolerance > 0.0):
        raise ValueError(f"solver_tolerance must be positive; got {solver_tolerance!r}")
    if (
        isinstance(max_refine_evaluations, bool)
        or not isinstance(max_refine_evaluations, int | np.integer)
        or max_refine_evaluations < 1
    ):
        raise ValueError(
            f"max_refine_evaluations must be a positive integer; got {max_refine_evaluations!r}"
        )


def fit_samples(h_m: np.ndarray, y: np.ndarray, *, order: int, compute_loo: bool) -> FitSamples:
    """Check the data (1-D, finite, same length, distinct h, enough points) and normalise."""
    h_arr = np.asarray(h_m, dtype=float)
    y_arr = np.asarray(y, dtype=float)
    for arg, arr in (("h_m", h_arr), ("y", y_arr)):
        if arr.ndim != 1:
            raise ValueError(f"{arg} must be a 1-D array; got shape {arr.shape}")
    if h_arr.size != y_arr.size:
        raise ValueError(
            f"h_m and y must have the same length; got {h_arr.size} altitudes and "
            f"{y_arr.size} values"
        )
    for arg, arr in (("h_m", h_arr), ("y", y_arr)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ValueError(
                f"{arg} must be finite; got non-finite value(s) at index {bad.tolist()}"
            )
    n_params = 2 * order + 2
    needed = n_params + 1 if compute_loo else n_params
    if h_arr.size < needed:
        reason = f"2*order + 2 = {n_params} parameters (coefficients and frequency)" + (
            " plus one point left out for leave-one-out" if compute_loo else ""
        )
        raise ValueError(
            f"h_m and y need at least {needed} points for an order-{order} fit "
            f"({reason}); got {h_arr.size} points"
        )
    order_index = np.argsort(h_arr, kind="stable")
    h_sorted = h_arr[order_index]
    y_sorted = y_arr[order_index]
    steps = np.diff(h_sorted)
    if np.any(steps <= 0.0):
        dup = sorted({float(v) for v in h_sorted[1:][steps <= 0.0]})
        raise ValueError(
            "h_m must hold distinct altitudes (strictly increasing after sorting); got "
            f"duplicate(s) at {', '.join(f'{v / M_PER_KM:g} km' for v in dup)}"
        )
    h_min = float(h_sorted[0])
    span = float(h_sorted[-1] - h_sorted[0])
    y_min, y_max = float(np.min(y_sorted)), float(np.max(y_sorted))
    y_scale = y_max - y_min if y_max > y_min else 1.0
    y_offset = 0.5 * (y_min + y_max)
    return FitSamples(
        h_m=h_sorted,
        y=y_sorted,
        order_index=order_index,
        s=(h_sorted - h_min) / span,
        yn=(y_sorted - y_offset) / y_scale,
        h_min_m=h_min,
        span_m=span,
        y_offset=y_offset,
        y_scale=y_scale,
    )


def aliasing_frequency_limit(s: np.ndarray, order: int) -> float:
    """Largest normalised W before harmonic ``order`` aliases on the grid s (sorted, [0, 1]).

    Harmonic k = order advances ``order * W * ds`` rad between neighbours; at pi per
    step (Nyquist) it is indistinguishable from lower frequencies, so
    W < pi / (order * max(ds)).
    """
    return float(np.pi / (order * np.max(np.diff(s))))


def resolved_frequency_bounds(
    s: np.ndarray, order: int, frequency_bounds: tuple[float, float] | None
) -> tuple[float, float]:
    """Resolve user bounds (normalised W) and cap the upper one at the aliasing limit."""
    limit = aliasing_frequency_limit(s, order)
    lo, hi = (DEFAULT_MIN_FREQUENCY, limit) if frequency_bounds is None else frequency_bounds
    hi = min(float(hi), float(np.nextafter(limit, 0.0)))  # strictly below aliasing
    lo = float(lo)
    if not (math.isfinite(lo) and lo > 0.0 and hi > lo):
        raise ValueError(
            "frequency_bounds must satisfy 0 < lower < upper, the upper capped at the "
            f"aliasing limit pi/(order*max ds) = {limit:.6g}; got {frequency_bounds!r}"
        )
    return lo, hi


def _check_starts(frequency_starts: Sequence[float]) -> tuple[float, ...]:
    starts = tuple(float(v) for v in frequency_starts)
    if not starts or not all(math.isfinite(v) and v > 0.0 for v in starts):
        raise ValueError(
            f"frequency_starts must be a non-empty sequence of positive numbers; "
            f"got {frequency_starts!r}"
        )
    return starts


# ----------------------------------------------------------------------- public fitting


def _loo_normalised(data: FitSamples, settings: SolverSettings, frequency: float) -> np.ndarray:
    """Signed LOO errors (prediction - y) in sorted order, unit of y; each refit
    warm-started from the single normalised ``frequency``."""
    errors = np.empty(data.s.size)
    keep = np.ones(data.s.size, dtype=bool)
    for i in range(data.s.size):
        keep[i] = False
        w_i, coef_i = fit_normalised(data.s[keep], data.yn[keep], settings, (frequency,))
        keep[i] = True
        predicted = predict_normalised(data.s[i : i + 1], w_i, coef_i)[0]
        errors[i] = data.y_scale * (predicted - data.yn[i])
    return errors


def leave_one_out_errors(
    h_m: np.ndarray,
    y: np.ndarray,
    *,
    order: int = 8,
    ridge: float = 0.0,
    frequency_starts: Sequence[float] = DEFAULT_FREQUENCY_STARTS,
    frequency_bounds: tuple[float, float] | None = None,
    initial_frequency_rad_per_m: float | None = None,
    solver_tolerance: float = DEFAULT_SOLVER_TOLERANCE,
    max_refine_evaluations: int = DEFAULT_MAX_REFINE_EVALUATIONS,
) -> np.ndarray:
    """Signed leave-one-out errors f_{-i}(h_i) - y_i, one per input point, unit of y.

    Each refit drops one point but keeps the full data's normalisation (s from the
    full altitude range, y scaled by the full y range), the same ``ridge`` and the same
    normalised frequency bounds (resolved on the full grid), and is warm-started from
    a single W: the full fit's frequency ``initial_frequency_rad_per_m`` (rad/m), or,
    if that is ``None``, from a full multi-start fit done here first. ``h_m`` in m.
    Fitting as in patent CN 2021-07-16 'whole-process trajectory optimisation based on
    a proxy model', section 5.1 (see :func:`fit_fourier_series`).
    """
    _validate_options(order, ridge, solver_tolerance, max_refine_evaluations)
    data = fit_samples(h_m, y, order=order, compute_loo=True)
    bounds = resolved_frequency_bounds(data.s, order, frequency_bounds)
    settings = SolverSettings(order, ridge, bounds, solver_tolerance, max_refine_evaluations)
    if initial_frequency_rad_per_m is None:
        frequency, _ = fit_normalised(data.s, data.yn, settings, _check_starts(frequency_starts))
    else:
        frequency = float(initial_frequency_rad_per_m) * data.span_m
        if not (math.isfinite(frequency) and frequency > 0.0):
            raise ValueError(
                f"initial_frequency_rad_per_m must be positive; got {initial_frequency_rad_per_m!r}"
            )
    sorted_errors = _loo_normalised(data, settings, frequency)
    errors = np.empty_like(sorted_errors)
    errors[data.order_index] = sorted_errors
    return errors


def fit_fourier_series(
    h_m: np.ndarray,
    y: np.ndarray,
    *,
    name: str,
    unit: str,
    order: int = 8,
    ridge: float = 0.0,
    frequency_starts: Sequence[float] = DEFAULT_FREQUENCY_STARTS,
    frequency_bounds: tuple[float, float] | None = None,
    compute_loo: bool = True,
    solver_tolerance: float = DEFAULT_SOLVER_TOLERANCE,
    max_refine_evaluations: int = DEFAULT_MAX_REFINE_EVALUATIONS,
) -> FourierSeries:
    """Fit the patent 5.1 series f(h) = a0 + sum_k a_k cos(k w h) + b_k sin(k w h).

    Reference: patent CN 2021-07-16 'whole-process trajectory optimisation based on a
    proxy model', section 5.1.

    ``h_m``: altitudes in m (any order, distinct); ``y``: the output at each altitude
    (``unit``). Needs at least ``2*order + 2`` points (``2*order + 3`` with
    ``compute_loo``). ``ridge`` (dimensionless, y scaled by its range) adds the penalty
    ``ridge * sum_k k**4 (alpha_k**2 + beta_k**2)``; 0 is plain least squares.
    ``frequency_starts`` are normalised frequencies W = w * (h_max - h_min) in rad per
    whole range, scored by the linear solve; the best is refined jointly with
    ``scipy.optimize.least_squares`` within ``frequency_bounds`` (normalised; default
    ``(DEFAULT_MIN_FREQUENCY, aliasing limit)``, the upper bound always capped at
    ``pi / (order * max ds)``, see :func:`aliasing_frequency_limit`).
    ``solver_tolerance`` (ftol/xtol/gtol) and ``max_refine_evaluations`` (max_nfev)
    control that refinement. ``rms_residual`` and the LOO errors are in ``unit``.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string; got {name!r}")
    if not isinstance(unit, str):
        raise ValueError(f"unit must be a string; got {unit!r}")
    _validate_options(order, ridge, solver_tolerance, max_refine_evaluations)
    order = int(order)
    starts = _check_starts(frequency_starts)
    data = fit_samples(h_m, y, order=order, compute_loo=compute_loo)
    bounds = resolved_frequency_bounds(data.s, order, frequency_bounds)
    settings = SolverSettings(order, ridge, bounds, solver_tolerance, max_refine_evaluations)
    frequency, coef = fit_normalised(data.s, data.yn, settings, starts)
    fitted = data.y_offset + data.y_scale * predict_normalised(data.s, frequency, coef)
    rms = float(np.sqrt(np.mean((fitted - data.y) ** 2)))
    w, a, b = data.absolute(frequency, coef)
    loo_rms, loo_max = _loo_figures(data, settings, w) if compute_loo else (None, None)
    return FourierSeries(
        name=name,
        unit=unit,
        order=order,
        frequency_rad_per_m=float(w),
        a=tuple(float(v) for v in a),
        b=tuple(float(v) for v in b),
        h_min_m=float(data.h_min_m),
        h_max_m=float(data.h_min_m + data.span_m),
        rms_residual=rms,
        loo_rms_error=loo_rms,
        loo_max_error=loo_max,
    )


def _loo_figures(
    data: FitSamples, settings: SolverSettings, frequency_rad_per_m: float
) -> tuple[float, float]:
    """RMS and max absolute leave-one-out errors (unit of y) of the fit of ``data`` whose
    frequency is ``frequency_rad_per_m`` (rad/m): :func:`leave_one_out_errors` on the
    sorted samples, with the fit's settings, warm-started from that frequency."""
    errors = leave_one_out_errors(
        data.h_m,
        data.y,
        order=settings.order,
        ridge=settings.ridge,
        frequency_bounds=settings.frequency_bounds,
        initial_frequency_rad_per_m=frequency_rad_per_m,
        solver_tolerance=settings.solver_tolerance,
        max_refine_evaluations=settings.max_refine_evaluations,
    )
    return float(np.sqrt(np.mean(errors**2))), float(np.max(np.abs(errors)))


def fit_errors_relative_to_range(series: FourierSeries, y: np.ndarray) -> float:
    """LOO max error of ``series`` divided by max(y) - min(y) (dimensionless).

    Used to check e.g. "LOO error below 1 % of the payload range". ``y`` are the data
    the series was fitted on (same unit).
    """
    if series.loo_max_error is None:
        raise ValueError(
            f"series '{series.name}' has no leave-one-out error (fitted with compute_loo=False)"
        )
    y_arr = np.asarray(y, dtype=float)
    if y_arr.ndim != 1 or y_arr.size < 2 or not np.all(np.isfinite(y_arr)):
        raise ValueError("y must be a 1-D finite array with at least 2 values")
    y_range = float(np.max(y_arr) - np.min(y_arr))
    if y_range <= 0.0:
        raise ValueError("y has zero range; the relative LOO error is undefined")
    return series.loo_max_error / y_range
