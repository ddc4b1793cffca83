"""End conditions: the target point, and the residuals and errors of eqs. 5-7.

* Interception (eq. 5): ``r(t_f) = r_g(t_f)``.
* Rendezvous (eq. 6): ``r(t_f) = r_g(t_f)``, ``v(t_f) = v_g(t_f)``.
* Transfer (eq. 7): ``(a, e, i, RAAN, argp)(t_f)`` equal the target's (osculating, at
  ``t_f``). Written without the singular angles: ``a``, the eccentricity vector's two
  components in the target's plane and the orbit normal's two components in that plane
  (zero when the planes agree) are equal, which holds exactly when the five elements do
  (for e > 0 and i > 0) and stays regular as e -> 0 or i -> 0. Each is expressed in
  metres (vector residuals times the target's a). The stage is then on the target's
  orbit; its *position error* is its distance to the target orbit's point at the same
  argument of latitude, and the velocity error likewise.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.elements import coe_to_rv, eccentricity_vector_from_dots, rv_to_coe
from ovtraj.astro.vectors import cross

__all__ = ["orbit_point", "orbit_point_at_latitude", "transfer_residuals"]


def orbit_point_at_latitude(
    orbit_state: NDArray[np.float64], u: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """States (S, 6) on the osculating orbits of ``orbit_state`` (S, 6) at argument of
    latitude ``u`` (S,) [rad]."""
    el = rv_to_coe(orbit_state[:, :3], orbit_state[:, 3:], mu=mu)
    r, v = coe_to_rv(el.a, el.e, el.i, el.raan, el.argp, u - el.argp, mu=mu)
    return np.hstack([r, v])


def orbit_point(
    orbit_state: NDArray[np.float64], position: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """The point (6,) of the osculating orbit of ``orbit_state`` (6,) whose argument of
    latitude is that of ``position`` (3,) projected on the orbit's plane."""
    el = rv_to_coe(orbit_state[:3], orbit_state[3:], mu=mu)
    node = np.array([np.cos(el.raan), np.sin(el.raan), 0.0])
    normal = cross(orbit_state[:3], orbit_state[3:])
    ahead = cross(normal / np.linalg.norm(normal), node)
    u = np.arctan2(position @ ahead, position @ node)
    return orbit_point_at_latitude(orbit_state[None, :], np.array([u]), mu)[0]


def transfer_residuals(
    state: NDArray[np.float64], target: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """Five residuals [m] of eq. 7 between orbits of ``state`` and ``target`` (6,)."""

    def invariants(s: NDArray[np.float64]) -> tuple[float, NDArray, NDArray]:
        r, v = s[:3], s[3:]
        rn = float(np.linalg.norm(r))
        v_sq = v @ v
        a = 1.0 / (2.0 / rn - float(v_sq) / mu)
        ecc = eccentricity_vector_from_dots(r, v, rn, v_sq, r @ v, mu)
        h = cross(r, v)
        return a, ecc, h / np.linalg.norm(h)

    a, ecc, h_hat = invariants(state)
    a_t, ecc_t, h_t = invariants(target)
    p_hat = target[:3] / np.linalg.norm(target[:3])
    q_hat = cross(h_t, p_hat)
    d_ecc = ecc - ecc_t
    return np.array(
        [
            a - a_t,
            a_t * (d_ecc @ p_hat),
            a_t * (d_ecc @ q_hat),
            a_t * (h_hat @ p_hat),
            a_t * (h_hat @ q_hat),
        ]
    )
