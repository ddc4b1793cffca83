"""Fourier-series surrogate of the launch segment as a function of target altitude: the
series, its evaluation and its stored form.

Reference: patent CN 2021-07-16 'whole-process trajectory optimisation based on a
proxy model', section 5.1 (launch-segment simplification). Each launch output y
(payload mass, time to insertion, argument of latitude at insertion) is fitted as an
order-``n`` Fourier series in the target orbit altitude ``h``:

    f(h) = a0 + sum_{k=1..n} ( a_k cos(k w h) + b_k sin(k w h) )          (patent 5.1)

with the coefficients a0..a_n, b1..b_n *and* the frequency ``w`` fitted (for the
patent's n = 8: 17 coefficients + w = 18 parameters). Units: ``h`` in m, ``w`` in
rad/m, the coefficients in the unit of y. The stored coefficients are exactly those
of the formula above in absolute altitude. The fit itself: :mod:`ovtraj.launch.fourier_fit`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ovtraj.units import M_PER_KM

# Evaluation slack at the ends of the validity range, relative to its width.
RANGE_RELATIVE_TOLERANCE = 1e-9


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
    text = f"{value_m / M_PER_KM:.1f}"
    if any(text == f"{bound / M_PER_KM:.1f}" for bound in bounds_m):
        text = f"{value_m / M_PER_KM:.9f}"
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
                f"{self.h_min_m / M_PER_KM:.1f}-{self.h_max_m / M_PER_KM:.1f} km; "
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
