"""A second, independent propagation: scipy's DOP853 on a J2 field written apart.

Used by tests (a second method) and by the benchmarks; the project's propagator is
:mod:`ovtraj.astro.propagation.taylor`. Neither the integrator nor the acceleration is
shared with it: the field here is the gradient of the zonal potential taken in spherical
coordinates (:func:`zonal_j2_acceleration`), not the Cartesian formula of
:mod:`ovtraj.astro.propagation.gravity`, so a test against it checks both the
integration and the force.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp


def zonal_j2_acceleration(
    position: np.ndarray, *, mu: float, radius: float, j2: float
) -> np.ndarray:
    """Acceleration [m/s^2] of the point mass plus J2 at an ECI position (3,) [m].

    Derived here from the potential, not from the Cartesian formula (Vallado eq. 8-30)
    of :func:`ovtraj.astro.propagation.gravity.two_body_j2_acceleration`::

        U(r, phi) = mu/r - mu J2 R^2 / r^3 P2(sin phi),   P2(s) = (3 s^2 - 1)/2

    (the spherical-harmonic expansion of the geopotential, Montenbruck & Gill 2000 sec.
    3.2, kept to its degree-2 zonal term, C20 = -J2; U is positive and a = grad U). Its
    gradient in spherical coordinates (r, geocentric latitude phi, longitude lam)::

        a_r   = dU/dr             = -mu/r^2 + 3 mu J2 R^2 / r^4 P2(sin phi)
        a_phi = (1/r) dU/dphi     = -mu J2 R^2 / r^4 P2'(sin phi) cos phi,  P2'(s) = 3 s
        a_lam = 1/(r cos phi) dU/dlam = 0  (zonal: no longitude dependence)

    taken along the local unit vectors r^ = (cos phi cos lam, cos phi sin lam, sin phi)
    and phi^ = (-sin phi cos lam, -sin phi sin lam, cos phi). The latitude comes from
    ``atan2(z, hypot(x, y))``, well conditioned at the poles; nothing divides by cos phi.
    """
    x, y, z = (float(c) for c in position)
    rho = math.hypot(x, y)
    r = math.hypot(rho, z)
    phi = math.atan2(z, rho)
    lam = math.atan2(y, x)
    sin_phi, cos_phi = math.sin(phi), math.cos(phi)
    cos_lam, sin_lam = math.cos(lam), math.sin(lam)
    p2 = 0.5 * (3.0 * sin_phi * sin_phi - 1.0)
    dp2 = 3.0 * sin_phi
    zonal = mu * j2 * radius * radius / r**4
    a_r = -mu / (r * r) + 3.0 * zonal * p2
    a_phi = -zonal * dp2 * cos_phi
    return np.array(
        [
            a_r * cos_phi * cos_lam - a_phi * sin_phi * cos_lam,
            a_r * cos_phi * sin_lam - a_phi * sin_phi * sin_lam,
            a_r * sin_phi + a_phi * cos_phi,
        ]
    )


def propagate_dop853(
    state0: np.ndarray,
    t0: float,
    t1: float,
    *,
    mu: float,
    radius: float,
    j2: float,
    rtol: float,
    atol: float,
    t_eval: np.ndarray | None = None,
) -> np.ndarray:
    """Propagate a Cartesian ECI state (m, m/s) from ``t0`` to ``t1`` [s] with DOP853
    under :func:`zonal_j2_acceleration`.

    Returns the final state (6,) or, with ``t_eval``, the states at those times (n, 6).
    """

    def rhs(_t: float, s: np.ndarray) -> np.ndarray:
        return np.concatenate([s[3:6], zonal_j2_acceleration(s[:3], mu=mu, radius=radius, j2=j2)])

    sol = solve_ivp(
        rhs,
        (t0, t1),
        np.asarray(state0, dtype=float),
        method="DOP853",
        rtol=rtol,
        atol=atol,
        t_eval=t_eval,
    )
    if not sol.success:
        raise RuntimeError(f"DOP853 failed: {sol.message}")
    return sol.y.T if t_eval is not None else sol.y[:, -1]
