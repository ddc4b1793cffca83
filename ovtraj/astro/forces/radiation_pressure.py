"""Solar radiation pressure on a cannonball, with the Earth's conical shadow smoothed.

Force (Montenbruck & Gill 2000, eq. 3.75 for a sphere): a = -nu P (AU/|d|)^2 (C_R A / m)
d/|d|, d = s - r the satellite-to-Sun vector, P the pressure at 1 AU.

Shadow: in the conical model (Montenbruck & Gill 2000 sec. 3.4.2) the Sun's apparent
radius a = asin(R_sun/|d|), the Earth's b = asin(R_E/|r|) and their separation c give
full light for c >= a + b, umbra for c <= b - a and a partial disc between. Its
branches are not smooth, and a Taylor integrator needs smooth equations, so the lit
fraction is nu = (1 + tanh(k (c - b)/a))/2: the same centre (c = b, half the disc) and
width (the penumbra, c - b in [-a, a]); ``k`` is the settings' ``shadow_sharpness``, and
:func:`conical_lit_fraction` (NumPy) is the unsmoothed model it is checked against.
A Taylor integrator's step size reads the derivatives where it stands: in full Sun or in
the umbra the tanh is flat and the steps (~20 s) would stride over the ~10 s penumbra,
so the propagator ends a step at each edge (:func:`shadow_argument` = -+4, events).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "conical_lit_fraction",
    "lit_fraction",
    "radiation_pressure_acceleration",
    "shadow_argument",
]


def _norm(v: Sequence[Any]) -> Any:
    return hy.sqrt(sum(c * c for c in v))


def shadow_argument(
    r: Sequence[Any],
    sun: Sequence[Any],
    *,
    earth_radius_m: float,
    sun_radius_m: float,
    sharpness: float,
) -> Any:
    """k (c - b) / a: where the satellite at ``r`` [m] is in the Earth's penumbra, Sun at
    ``sun`` [m] (0 at its middle, -k and +k at its edges; module notes)."""
    d = [sun[i] - r[i] for i in range(3)]
    r_norm, d_norm = _norm(r), _norm(d)
    sun_apparent = hy.asin(sun_radius_m / d_norm)
    earth_apparent = hy.asin(earth_radius_m / r_norm)
    # Separation of the Sun's centre from the Earth's as seen from the satellite, by
    # atan2 (smooth where acos is not, at 0 and pi).
    minus_r = [-c for c in r]
    cross = [
        minus_r[1] * d[2] - minus_r[2] * d[1],
        minus_r[2] * d[0] - minus_r[0] * d[2],
        minus_r[0] * d[1] - minus_r[1] * d[0],
    ]
    dot = sum(minus_r[i] * d[i] for i in range(3))
    separation = hy.atan2(_norm(cross), dot)
    return sharpness * (separation - earth_apparent) / sun_apparent


def lit_fraction(
    r: Sequence[Any],
    sun: Sequence[Any],
    *,
    earth_radius_m: float,
    sun_radius_m: float,
    sharpness: float,
) -> Any:
    """The smoothed conical lit fraction (0 umbra, 1 full Sun) at ``r`` [m], Sun at ``sun``."""
    argument = shadow_argument(
        r, sun, earth_radius_m=earth_radius_m, sun_radius_m=sun_radius_m, sharpness=sharpness
    )
    return 0.5 * (1.0 + hy.tanh(argument))


def radiation_pressure_acceleration(
    r: Sequence[Any],
    sun: Sequence[Any],
    radiation_m2_kg: Any,
    lit: Any,
    *,
    pressure_n_m2: float,
    astronomical_unit_m: float,
) -> list[Any]:
    """Acceleration [m/s^2] away from the Sun; ``radiation_m2_kg`` = C_R A / m."""
    d = [sun[i] - r[i] for i in range(3)]
    d_norm = _norm(d)
    scale = -lit * pressure_n_m2 * radiation_m2_kg * astronomical_unit_m**2 / d_norm**3
    return [scale * c for c in d]


def conical_lit_fraction(
    r: ArrayLike, sun: ArrayLike, *, earth_radius_m: float, sun_radius_m: float
) -> np.ndarray:
    """The conical model's lit fraction (Montenbruck & Gill 2000 eqs. 3.79-3.87), NumPy,
    positions (..., 3) [m]: the reference of :func:`lit_fraction`."""
    r = np.asarray(r, dtype=float)
    d = np.asarray(sun, dtype=float) - r
    r_norm = np.linalg.norm(r, axis=-1)
    d_norm = np.linalg.norm(d, axis=-1)
    a = np.arcsin(sun_radius_m / d_norm)
    b = np.arcsin(earth_radius_m / r_norm)
    cos_c = np.clip(np.sum(-r * d, axis=-1) / (r_norm * d_norm), -1.0, 1.0)
    c = np.arccos(cos_c)
    with np.errstate(over="ignore", invalid="ignore"):  # c = 0 is the umbra's branch
        x = (c * c + a * a - b * b) / (2.0 * np.maximum(c, 1e-300))
        y = np.sqrt(np.maximum(a * a - x * x, 0.0))
        overlap = (
            a * a * np.arccos(np.clip(x / a, -1.0, 1.0))
            + b * b * np.arccos(np.clip((c - x) / b, -1.0, 1.0))
            - c * y
        )
        partial = 1.0 - overlap / (np.pi * a * a)
    return np.where(c >= a + b, 1.0, np.where(c <= b - a, 0.0, partial))
