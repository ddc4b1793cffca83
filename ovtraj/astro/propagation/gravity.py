"""Point-mass plus J2 gravitational acceleration.

The formula is written once, on plain arithmetic, so the same code builds the
numpy right-hand side (reference integrator) and the symbolic heyoka system.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit


def two_body_j2_acceleration(
    x: Any,
    y: Any,
    z: Any,
    mu: Any,
    radius: Any,
    j2: Any,
    sqrt: Callable[[Any], Any] = np.sqrt,
) -> tuple[Any, Any, Any]:
    """Acceleration of the Newtonian field plus the J2 zonal term, in ECI axes.

    a = -mu r / |r|^3 - (3/2) J2 mu R^2 / |r|^5 [x (1 - 5 z^2/r^2), y (1 - 5 z^2/r^2),
    z (3 - 5 z^2/r^2)]  (Vallado, 4th ed., eq. 8-30; Curtis, 3rd ed., eq. 10.30).

    Works on floats, numpy arrays and heyoka expressions alike (pass ``sqrt``), and
    compiles with numba (:data:`two_body_j2_acceleration_compiled`; no keyword-only
    parameters, which numba cannot bind).
    Units: positions in m, ``mu`` in m^3/s^2, ``radius`` in m; result in m/s^2.
    With ``j2 = 0`` this is the two-body field.
    """
    r2 = x * x + y * y + z * z
    r = sqrt(r2)
    r3 = r2 * r
    k = 1.5 * j2 * mu * radius * radius / (r2 * r3)
    z2_r2 = z * z / r2
    ax = -mu * x / r3 - k * x * (1.0 - 5.0 * z2_r2)
    ay = -mu * y / r3 - k * y * (1.0 - 5.0 * z2_r2)
    az = -mu * z / r3 - k * z * (3.0 - 5.0 * z2_r2)
    return ax, ay, az


# The same formula for compiled kernels (floats in, a tuple out).
two_body_j2_acceleration_compiled = njit(cache=True)(two_body_j2_acceleration)


def two_body_j2_rhs(state: np.ndarray, *, mu: float, radius: float, j2: float) -> np.ndarray:
    """Time derivative of a Cartesian state (..., 6) under :func:`two_body_j2_acceleration`."""
    state = np.asarray(state, dtype=float)
    ax, ay, az = two_body_j2_acceleration(
        state[..., 0], state[..., 1], state[..., 2], mu=mu, radius=radius, j2=j2
    )
    return np.concatenate([state[..., 3:6], np.stack([ax, ay, az], axis=-1)], axis=-1)
