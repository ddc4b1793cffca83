"""Fourier-series surrogate of the launch segment as a function of target altitude.

Reference: patent CN 2021-07-16 'whole-process trajectory optimisation based on a
proxy model', section 5.1 (launch-segment simplification). Each launch output y
(payload mass, time to insertion, argument of latitude at insertion) is fitted as an
order-``n`` Fourier series in the target orbit altitude ``h``:

    f(h) = a0 + sum_{k=1..n} ( a_k cos(k w h) + b_k sin(k w h) )          (patent 5.1)

with the coefficients a0..a_n, b1..b_n *and* the frequency ``w`` fitted (for the
patent's n = 8: 17 coefficients + w = 18 parameters). Units: ``h`` in m, ``w`` in
rad/m, the coefficients in the unit of y. The stored coefficients are exactly those
of the formula above in absolute altitude.

Fitting (all SI; internal variables are dimensionless):

* Altitude is normalised to ``s = (h - h_min) / (h_max - h_min)`` in [0, 1] and y to
  ``(y - y_mid) / (y_max - y_min)``; the series is fitted in ``s`` with a normalised
  frequency ``W`` (rad per unit s, ``W = w (h_max - h_min)``). Because
  ``k W s = k w h - k w h_min``, the normalised coefficients are converted back by an
  exact rotation per harmonic (see :func:`_to_absolute`).
* For fixed ``W`` the problem is linear in the coefficients: a (ridge-)linear least
  squares. Several starting ``W`` (:data:`DEFAULT_FREQUENCY_STARTS`) are scored by
  that linear solve, the best is refined jointly (``W`` and the coefficients) by
  ``scipy.optimize.least_squares`` with ``W`` bounded to
  ``[DEFAULT_MIN_FREQUENCY, pi / (order * max ds))`` (the upper end is where the
  highest harmonic would alias on the grid), and the coefficients are then re-solved
  exactly at the refined ``W`` (never worse than the best start).
* Ridge (Tikhonov): extra residuals ``sqrt(ridge) * k**2 * alpha_k`` and
  ``sqrt(ridge) * k**2 * beta_k`` for k >= 1 on the normalised coefficients (a0 is not
  penalised). Since y is scaled by its range, ``ridge`` is dimensionless. The
  objective is ``sum_i r_i**2 + ridge * sum_k k**4 (alpha_k**2 + beta_k**2)``; the
  penalty is unchanged by the shift to absolute altitude because the rotation keeps
  ``a_k**2 + b_k**2 = alpha_k**2 + beta_k**2`` for every harmonic.
* Leave-one-out (LOO): each point is dropped in turn, the series refitted (same
  normalisation, ridge and frequency bounds, warm-started from the full fit's ``W``)
  and the dropped point predicted; RMS and max absolute LOO errors judge the fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

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
# Evaluation slack at the ends of the validity range, relative to its width.
RANGE_RELATIVE_TOLERANCE = 1e-9

_KM = 1000.0


class FourierRangeError(ValueError):
    """A launch fit was evaluated outside the altitude range it was fitted on."""


# --------------------------------------------------------------------------- evaluation


def evaluate_fourier_series(
    h_m: np.ndarray,
    frequency_rad_per_m: float,
    a: Sequence[float] | np.ndarray,
    b: Sequence[float] | np.ndarray,
) -> np.ndarray:
    """Patent 5.1 series f(h) = a0 + sum_k a_k cos(k w h) + b_k sin(k w h).

    ``h_m`` in m (any shape), ``frequency_rad_per_m`` = w in rad/m, ``a`` = a0..a_n and
    ``b`` = b1..b_n in the unit of f. No range check (see :class:`FourierSeries`).
    """
    h = np.asarray(h_m, dtype=float)
    a_arr = np.asarray(a, dtype=float)
    b_arr = np.asarray(b, dtype=float)
    k = np.arange(1, b_arr.size + 1, dtype=float)
    phase = frequency_rad_per_m * h[..., None] * k
    return a_arr[0] + np.cos(phase) @ a_arr[1:] + np.sin(phase) @ b_arr


def evaluate_fourier_derivative(
    h_m: np.ndarray,
    frequency_rad_per_m: float,
    a: Sequence[float] | np.ndarray,
    b: Sequence[float] | np.ndarray,
) -> np.ndarray:
    """df/dh of the patent 5.1 series: sum_k k w (b_k cos(k w h) - a_k sin(k w h)).

    ``h_m`` in m, ``frequency_rad_per_m`` in rad/m; result in (unit of f) per m.
    """
    h = np.asarray(h_m, dtype=float)
    a_arr = np.asarray(a, dtype=float)
    b_arr = np.asarray(b, dtype=float)
    k = np.arange(1, b_arr.size + 1, dtype=float)
    phase = frequency_rad_per_m * h[..., None] * k
    kw = k * frequency_rad_per_m
    return np.cos(phase) @ (kw * b_arr) - np.sin(phase) @ (kw * a_arr[1:])


# --------------------------------------------------------------------- the fitted series


_DICT_KEYS = (
    "name",
    "unit",
    "order",
    "frequency_rad_per_m",
    "a",
    "b",
    "h_min_m",
    "h_max_m",
    "rms_residual",
    "loo_rms_error",
    "loo_max_error",
)


def _format_km(value_m: float, bounds_m: tuple[float, float]) -> str:
    """Altitude in km with one decimal, more if one decimal would hide the violation."""
    text = f"{value_m / _KM:.1f}"
    if any(text == f"{bound / _KM:.1f}" for bound in bounds_m):
        text = f"{value_m / _KM:.9f}"
    return text


@dataclass(frozen=True)
class FourierSeries:
    """One launch output as the patent 5.1 Fourier series in target altitude.

    f(h) = a0 + sum_{k=1..order} a_k cos(k w h) + b_k sin(k w h), h in m, w =
    ``frequency_rad_per_m`` in rad/m, coefficients and errors in ``unit``. Valid (no
    extrapolation) on [``h_min_m``, ``h_max_m``]. ``rms_residual`` is the RMS fit
    residual on the data; ``loo_rms_error``/``loo_max_error`` are the RMS and max
    absolute leave-one-out prediction errors (``None`` if not computed).
    Reference: patent CN 2021-07-16 'whole-process trajectory optimisation based on a
    proxy model', section 5.1.
    """

    name: str
    unit: str
    order: int
    frequency_rad_per_m: float
    a: tuple[float, ...]
    b: tuple[float, ...]
    h_min_m: float
    h_max_m: float
    rms_residual: float
    loo_rms_error: float | None
    loo_max_error: float | None

    def __post_init__(self) -> None:
        if isinstance(self.order, bool) or not isinstance(self.order, int) or self.order < 1:
            raise ValueError(f"order must be a positive int; got {self.order!r}")
        a = tuple(float(v) for v in self.a)
        b = tuple(float(v) for v in self.b)
        if len(a) != self.order + 1:
            raise ValueError(
                f"a must hold order + 1 = {self.order + 1} coefficients (a0..a{self.order}); "
                f"got {len(a)}"
            )
        if len(b) != self.order:
            raise ValueError(
                f"b must hold order = {self.order} coefficients (b1..b{self.order}); got {len(b)}"
            )
        if not all(math.isfinite(v) for v in (*a, *b)):
            raise ValueError("a and b must be finite")
        for field_name in ("frequency_rad_per_m", "h_min_m", "h_max_m", "rms_residual"):
            value = float(getattr(self, field_name))
            if not math.isfinite(value):
                raise ValueError(f"{field_name} must be finite; got {value}")
            object.__setattr__(self, field_name, value)
        for field_name in ("loo_rms_error", "loo_max_error"):
            value = getattr(self, field_name)
            if value is not None:
                object.__setattr__(self, field_name, float(value))
        if self.frequency_rad_per_m <= 0.0:
            raise ValueError(
                f"frequency_rad_per_m must be positive; got {self.frequency_rad_per_m}"
            )
        if not self.h_max_m > self.h_min_m:
            raise ValueError(
                f"h_max_m must exceed h_min_m; got {self.h_min_m} m and {self.h_max_m} m"
            )
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "b", b)

    # -- evaluation -----------------------------------------------------------------

    def _checked(self, h_m: float | np.ndarray) -> np.ndarray:
        h = np.asarray(h_m, dtype=float)
        slack = RANGE_RELATIVE_TOLERANCE * (self.h_max_m - self.h_min_m)
        inside = (h >= self.h_min_m - slack) & (h <= self.h_max_m + slack)
        if not np.all(inside):
            bad = np.atleast_1d(h[~inside])
            bounds = (self.h_min_m, self.h_max_m)
            shown = ", ".join(_format_km(v, bounds) for v in bad[:5])
            if bad.size > 5:
                shown += f", ... ({bad.size} values)"
            raise FourierRangeError(
                f"launch fit '{self.name}' is valid for target altitude "
                f"{self.h_min_m / _KM:.1f}-{self.h_max_m / _KM:.1f} km; "
                f"got {shown} km (no extrapolation)"
            )
        return h

    def __call__(self, h_m: float | np.ndarray) -> float | np.ndarray:
        """f(h) in ``unit`` for altitude(s) ``h_m`` in m (range-checked, vectorised)."""
        h = self._checked(h_m)
        value = evaluate_fourier_series(h, self.frequency_rad_per_m, self.a, self.b)
        return float(value) if h.ndim == 0 else value

    def derivative(self, h_m: float | np.ndarray) -> float | np.ndarray:
        """df/dh in ``unit`` per m for altitude(s) ``h_m`` in m (range-checked)."""
        h = self._checked(h_m)
        value = evaluate_fourier_derivative(h, self.frequency_rad_per_m, self.a, self.b)
        return float(value) if h.ndim == 0 else value

    # -- serialisation --------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain str/int/float/list/None mapping (JSON- and YAML-safe)."""
        return {
            "name": self.name,
            "unit": self.unit,
            "order": int(self.order),
            "frequency_rad_per_m": float(self.frequency_rad_per_m),
            "a": [float(v) for v in self.a],
            "b": [float(v) for v in self.b],
            "h_min_m": float(self.h_min_m),
            "h_max_m": float(self.h_max_m),
            "rms_residual": float(self.rms_residual),
            "loo_rms_error": None if self.loo_rms_error is None else float(self.loo_rms_error),
            "loo_max_error": None if self.loo_max_error is None else float(self.loo_max_error),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FourierSeries:
        """Inverse of :meth:`to_dict`; every error names the offending key."""
        if not isinstance(data, Mapping):
            raise TypeError(f"FourierSeries data must be a mapping; got {type(data).__name__}")
        missing = [key for key in _DICT_KEYS if key not in data]
        if missing:
            raise ValueError(f"FourierSeries data is missing key(s): {', '.join(missing)}")
        unknown = sorted(str(key) for key in data if key not in _DICT_KEYS)
        if unknown:
            raise ValueError(f"FourierSeries data has unknown key(s): {', '.join(unknown)}")
        for key in ("name", "unit"):
            if not isinstance(data[key], str):
                raise ValueError(f"'{key}' must be a string; got {data[key]!r}")
        order = data["order"]
        if isinstance(order, bool) or not isinstance(order, int) or order < 1:
            raise ValueError(f"'order' must be a positive integer; got {order!r}")

        def number(key: str, value: Any) -> float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"'{key}' must be a number; got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"'{key}' must be finite; got {value!r}")
            return float(value)

        coefficients: dict[str, tuple[float, ...]] = {}
        for key, length in (("a", order + 1), ("b", order)):
            values = data[key]
            if isinstance(values, str | bytes) or not isinstance(values, Sequence):
                raise ValueError(f"'{key}' must be a list of {length} numbers; got {values!r}")
            if len(values) != length:
                raise ValueError(
                    f"'{key}' must hold {length} coefficients for order {order}; got {len(values)}"
                )
            coefficients[key] = tuple(number(f"{key}[{i}]", v) for i, v in enumerate(values))
        loo: dict[str, float | None] = {}
        for key in ("loo_rms_error", "loo_max_error"):
            loo[key] = None if data[key] is None else number(key, data[key])
        return cls(
            name=data["name"],
            unit=data["unit"],
            order=order,
            frequency_rad_per_m=number("frequency_rad_per_m", data["frequency_rad_per_m"]),
            a=coefficients["a"],
            b=coefficients["b"],
            h_min_m=number("h_min_m", data["h_min_m"]),
            h_max_m=number("h_max_m", data["h_max_m"]),
            rms_residual=number("rms_residual", data["rms_residual"]),
            loo_rms_error=loo["loo_rms_error"],
            loo_max_error=loo["loo_max_error"],
        )


# ----------------------------------------------------------------- normalised internals


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


def _predict_normalised(s: np.ndarray, frequency: float, coef: np.ndarray) -> np.ndarray:
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


def _fit_normalised(
    s: np.ndarray,
    yn: np.ndarray,
    *,
    order: int,
    ridge: float,
    frequency_starts: Sequence[float],
    frequency_bounds: tuple[float, float],
    solver_tolerance: float,
    max_refine_evaluations: int,
) -> tuple[float, np.ndarray]:
    """Best (W, coefficients) in normalised variables: multi-start, joint refine, polish."""
    lo, hi = frequency_bounds
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
        ftol=solver_tolerance,
        xtol=solver_tolerance,
        gtol=solver_tolerance,
        max_nfev=max_refine_evaluations,
        args=(s, yn, order, ridge),
    )
    refined_w = float(np.clip(result.x[0], lo, hi))
    refined_coef, refined_cost = _linear_solve(s, yn, refined_w, order, ridge)
    if refined_cost <= best_cost:
        return refined_w, refined_coef
    return best_w, best_coef


def _to_absolute(
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


# ------------------------------------------------------------------------ validation


@dataclass(frozen=True)
class _Samples:
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


def _samples(h_m: np.ndarray, y: np.ndarray, *, order: int, compute_loo: bool) -> _Samples:
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
            f"duplicate(s) at {', '.join(f'{v / _KM:g} km' for v in dup)}"
        )
    h_min = float(h_sorted[0])
    span = float(h_sorted[-1] - h_sorted[0])
    y_min, y_max = float(np.min(y_sorted)), float(np.max(y_sorted))
    y_scale = y_max - y_min if y_max > y_min else 1.0
    y_offset = 0.5 * (y_min + y_max)
    return _Samples(
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


def _frequency_bounds(
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


def _loo_normalised(
    data: _Samples,
    *,
    order: int,
    ridge: float,
    frequency: float,
    bounds: tuple[float, float],
    solver_tolerance: float,
    max_refine_evaluations: int,
) -> np.ndarray:
    """Signed LOO errors (prediction - y) in sorted order, unit of y."""
    errors = np.empty(data.s.size)
    keep = np.ones(data.s.size, dtype=bool)
    for i in range(data.s.size):
        keep[i] = False
        w_i, coef_i = _fit_normalised(
            data.s[keep],
            data.yn[keep],
            order=order,
            ridge=ridge,
            frequency_starts=(frequency,),
            frequency_bounds=bounds,
            solver_tolerance=solver_tolerance,
            max_refine_evaluations=max_refine_evaluations,
        )
        keep[i] = True
        predicted = _predict_normalised(data.s[i : i + 1], w_i, coef_i)[0]
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
    data = _samples(h_m, y, order=order, compute_loo=True)
    bounds = _frequency_bounds(data.s, order, frequency_bounds)
    if initial_frequency_rad_per_m is None:
        frequency, _ = _fit_normalised(
            data.s,
            data.yn,
            order=order,
            ridge=ridge,
            frequency_starts=_check_starts(frequency_starts),
            frequency_bounds=bounds,
            solver_tolerance=solver_tolerance,
            max_refine_evaluations=max_refine_evaluations,
        )
    else:
        frequency = float(initial_frequency_rad_per_m) * data.span_m
        if not (math.isfinite(frequency) and frequency > 0.0):
            raise ValueError(
                f"initial_frequency_rad_per_m must be positive; got {initial_frequency_rad_per_m!r}"
            )
    sorted_errors = _loo_normalised(
        data,
        order=order,
        ridge=ridge,
        frequency=frequency,
        bounds=bounds,
        solver_tolerance=solver_tolerance,
        max_refine_evaluations=max_refine_evaluations,
    )
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
    data = _samples(h_m, y, order=order, compute_loo=compute_loo)
    bounds = _frequency_bounds(data.s, order, frequency_bounds)
    frequency, coef = _fit_normalised(
        data.s,
        data.yn,
        order=order,
        ridge=ridge,
        frequency_starts=starts,
        frequency_bounds=bounds,
        solver_tolerance=solver_tolerance,
        max_refine_evaluations=max_refine_evaluations,
    )
    fitted = data.y_offset + data.y_scale * _predict_normalised(data.s, frequency, coef)
    rms = float(np.sqrt(np.mean((fitted - data.y) ** 2)))
    w, a, b = _to_absolute(
        frequency,
        coef,
        h_min_m=data.h_min_m,
        span_m=data.span_m,
        y_offset=data.y_offset,
        y_scale=data.y_scale,
    )
    loo_rms: float | None = None
    loo_max: float | None = None
    if compute_loo:
        errors = leave_one_out_errors(
            data.h_m,
            data.y,
            order=order,
            ridge=ridge,
            frequency_bounds=bounds,
            initial_frequency_rad_per_m=w,
            solver_tolerance=solver_tolerance,
            max_refine_evaluations=max_refine_evaluations,
        )
        loo_rms = float(np.sqrt(np.mean(errors**2)))
        loo_max = float(np.max(np.abs(errors)))
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
