"""Orbital elements (classical, nonsingular, equinoctial) and Cartesian state.

Conventions
-----------
* SI units: metres, seconds, radians. States are arrays shaped ``(..., 3)``;
  every function vectorises over the leading axes and also accepts scalars.
* Angles returned by the state -> elements conversions are reduced to ``[0, 2*pi)``
  by :func:`ovtraj.astro.angles.wrap_to_two_pi` (an angle within half an ulp below 0
  comes out as 0, not as the ``2*pi`` a bare modulo would give); the inclination lies
  in ``[0, pi]``.
* The gravitational parameter ``mu`` [m^3/s^2] is always a keyword argument:
  nothing here reads a configuration.

Element sets
------------
* :class:`ClassicalElements` ``(a, e, i, raan, argp, nu)``, Vallado (2013),
  "Fundamentals of Astrodynamics and Applications", 4th ed., §2.5-2.6.
  Singular for circular orbits (``argp`` undefined) and for equatorial orbits
  (``raan`` undefined); :func:`rv_to_coe` fixes the free angles by the usual
  conventions (see there).
* :class:`NonsingularElements` ``(a, ex, ey, i, raan, u)`` with
  ``ex = e cos(argp)``, ``ey = e sin(argp)`` and ``u = argp + nu`` the *true*
  argument of latitude: regular as ``e -> 0``, still singular as ``i -> 0``.
* :class:`EquinoctialElements` ``(a, h, k, p, q, L)`` of Broucke & Cefola
  (1972), "On the equinoctial orbit elements", Celestial Mechanics 5, 303-310
  (direct set, retrograde factor +1): regular for ``e -> 0`` and ``i -> 0``,
  singular only at ``i = pi``. ``L`` is the *true* longitude
  ``raan + argp + nu`` (Walker, Ireland & Owens 1985 use the same true
  longitude in their modified set).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ovtraj.astro.angles import TWO_PI, wrap_to_two_pi
from ovtraj.astro.vectors import cross

FloatOrArray = float | NDArray[np.float64]

_EPS = float(np.finfo(float).eps)
# A computed eccentricity (or sin i) this small is rounding noise from r and v
# (their products carry a few ulps), so the angle it would define is arbitrary.
_DEGENERATE_TOL = 256.0 * _EPS
# Newton's iteration on Kepler's equation stops once the step is a few ulps.
_KEPLER_TOL = 4.0 * _EPS
_KEPLER_MAX_ITER = 50


# --------------------------------------------------------------------------- #
# Element containers
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class ClassicalElements:
    """Classical (Keplerian) elements; floats or arrays of one shape.

    a [m] (negative for hyperbolae), e [-], i, raan, argp, nu [rad];
    ``nu`` is the true anomaly.
    """

    a: FloatOrArray
    e: FloatOrArray
    i: FloatOrArray
    raan: FloatOrArray
    argp: FloatOrArray
    nu: FloatOrArray


@dataclass(frozen=True)
class NonsingularElements:
    """Nonsingular elements for near-circular orbits; floats or arrays.

    a [m]; ex = e cos(argp), ey = e sin(argp) [-]; i, raan [rad];
    u = argp + nu [rad], the *true* argument of latitude (osculating or mean:
    for a mean set, ``nu`` is the true anomaly that the mean anomaly and the
    mean eccentricity give through Kepler's equation).
    """

    a: FloatOrArray
    ex: FloatOrArray
    ey: FloatOrArray
    i: FloatOrArray
    raan: FloatOrArray
    u: FloatOrArray


@dataclass(frozen=True)
class EquinoctialElements:
    """Equinoctial elements (Broucke & Cefola 1972, with the true longitude).

    a [m]; h = e sin(argp + raan), k = e cos(argp + raan) [-];
    p = tan(i/2) sin(raan), q = tan(i/2) cos(raan) [-];
    L = raan + argp + nu [rad], the true longitude.
    """

    a: FloatOrArray
    h: FloatOrArray
    k: FloatOrArray
    p: FloatOrArray
    q: FloatOrArray
    L: FloatOrArray


# --------------------------------------------------------------------------- #
# Small helpers
# --------------------------------------------------------------------------- #
def _as_float(x: ArrayLike) -> NDArray[np.float64]:
    return np.asarray(x, dtype=float)


def _scalar_or_array(x: NDArray[np.float64]) -> FloatOrArray:
    """Give 0-d results back as numpy scalars (a subclass of float)."""
    return x[()] if np.ndim(x) == 0 else x


def _dot(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.einsum("...k,...k->...", x, y)


def _norm(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.sqrt(_dot(x, x))


def _angle_about(
    start: NDArray[np.float64], end: NDArray[np.float64], axis_hat: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Angle from ``start`` to ``end`` counted positively about ``axis_hat``.

    atan2 of the two projections stays accurate at every angle, where acos
    loses half the digits near 0 and pi.
    """
    return np.arctan2(_dot(axis_hat, cross(start, end)), _dot(start, end))


def _in_plane_basis(
    raan: NDArray[np.float64], i: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unit vectors along the ascending node and 90 deg ahead of it in the plane.

    First two columns of R3(-raan) R1(-i) (Vallado 2013, Algorithm 10 with argp = 0).
    """
    cos_raan, sin_raan = np.cos(raan), np.sin(raan)
    cos_i, sin_i = np.cos(i), np.sin(i)
    node_hat = np.stack([cos_raan, sin_raan, np.zeros_like(cos_raan)], axis=-1)
    ahead_hat = np.stack([-sin_raan * cos_i, cos_raan * cos_i, sin_i], axis=-1)
    return node_hat, ahead_hat


def eccentricity_vector(
    r: NDArray[np.float64], v: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """Eccentricity vector [-] of states ``r`` [m], ``v`` [m/s] shaped (..., 3).

    e = ((v^2 - mu/|r|) r - (r.v) v) / mu (Vallado 2013, Algorithm 9, RV2COE), its
    magnitude the eccentricity and its direction the periapsis; ``mu`` [m^3/s^2]. The
    dot products are taken with ``numpy.einsum`` over the last axis, for one state as
    for many: :func:`eccentricity_vector_from_dots` is the same formula on dot
    products the caller already holds.
    """
    return eccentricity_vector_from_dots(
        r, v, _norm(r)[..., None], _dot(v, v)[..., None], _dot(r, v)[..., None], mu
    )


def eccentricity_vector_from_dots(
    r: NDArray[np.float64],
    v: NDArray[np.float64],
    r_norm: FloatOrArray,
    v_sq: FloatOrArray,
    r_dot_v: FloatOrArray,
    mu: float,
) -> NDArray[np.float64]:
    """:func:`eccentricity_vector` from ``|r|`` [m], ``v.v`` [m^2/s^2] and ``r.v``
    [m^2/s] computed by the caller (broadcast against ``r`` and ``v``).

    For callers that need these products anyway (vis-viva, angular momentum) and take
    them with their own routine: a BLAS dot product (``r @ v``) and ``numpy.einsum`` can
    differ in the last bit, so passing them keeps each caller's results as they were.
    """
    return ((v_sq - mu / r_norm) * r - r_dot_v * v) / mu


def perigee_radius(a: FloatOrArray, e: FloatOrArray) -> FloatOrArray:
    """Periapsis radius r_p = a (1 - e) [unit of ``a``] of a conic of semi-major axis
    ``a`` and eccentricity ``e`` [-], a hyperbola (a < 0, e > 1) included (Vallado 2013,
    ch. 1, conic sections). Equal to :func:`perigee_radius_from_semi_latus_rectum` with
    p = a (1 - e^2) up to rounding."""
    return a * (1.0 - e)


def perigee_radius_from_semi_latus_rectum(p: FloatOrArray, e: FloatOrArray) -> FloatOrArray:
    """Periapsis radius r_p = p / (1 + e) [unit of ``p``]: the trajectory equation
    r = p / (1 + e cos(nu)) at nu = 0 (Vallado 2013, ch. 1; Battin, "An Introduction to
    the Mathematics and Methods of Astrodynamics", rev. ed., 1999, p. 117), with
    p = h^2 / mu the semi-latus rectum; regular for every conic, the parabola included."""
    return p / (1.0 + e)


def _semi_major_axis(
    r: NDArray[np.float64], v: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """Vis-viva integral: a = 1 / (2/r - v^2/mu); infinite for a parabola."""
    with np.errstate(divide="ignore"):
        return 1.0 / (2.0 / _norm(r) - _dot(v, v) / mu)


def _state_in_plane(
    semi_latus_rectum: NDArray[np.float64],
    ecc_x: NDArray[np.float64],
    ecc_y: NDArray[np.float64],
    angle: NDArray[np.float64],
    x_hat: NDArray[np.float64],
    y_hat: NDArray[np.float64],
    mu: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Position and velocity from in-plane components of the eccentricity vector.

    ``angle`` is the polar angle of the position counted from ``x_hat`` towards
    ``y_hat`` (orbit plane, direction of motion) and ``(ecc_x, ecc_y)`` the
    eccentricity vector in that basis. Conic equation r = p / (1 + e.r_hat) and
    v = sqrt(mu/p) (h_hat x (e + r_hat)): Vallado's (2013) perifocal
    COE2RV formulas (Algorithm 10) rotated by argp, so that e = 0 is regular.
    """
    cos_angle, sin_angle = np.cos(angle), np.sin(angle)
    radius = semi_latus_rectum / (1.0 + ecc_x * cos_angle + ecc_y * sin_angle)
    speed_scale = np.sqrt(mu / semi_latus_rectum)
    r = radius[..., None] * (cos_angle[..., None] * x_hat + sin_angle[..., None] * y_hat)
    v = speed_scale[..., None] * (
        -(sin_angle + ecc_y)[..., None] * x_hat + (cos_angle + ecc_x)[..., None] * y_hat
    )
    return r, v


@dataclass(frozen=True)
class _PlaneGeometry:
    """What rv -> elements needs about the orbit plane."""

    h_hat: NDArray[np.float64]
    node_hat: NDArray[np.float64]
    ahead_hat: NDArray[np.float64]
    i: NDArray[np.float64]
    raan: NDArray[np.float64]


def _plane_geometry(
    r: NDArray[np.float64], v: NDArray[np.float64], equatorial_tol: float
) -> _PlaneGeometry:
    """Inclination, node and in-plane basis; equatorial orbits take the x axis as node."""
    h = cross(r, v)
    h_norm = _norm(h)
    h_hat = h / h_norm[..., None]
    node = np.stack([-h[..., 1], h[..., 0], np.zeros_like(h_norm)], axis=-1)
    node_norm = _norm(node)
    i = np.arctan2(node_norm, h[..., 2])
    equatorial = node_norm <= equatorial_tol * h_norm
    safe_node_norm = np.where(equatorial, 1.0, node_norm)
    x_hat = np.broadcast_to(np.array([1.0, 0.0, 0.0]), node.shape)
    node_hat = np.where(equatorial[..., None], x_hat, node / safe_node_norm[..., None])
    raan = np.where(equatorial, 0.0, wrap_to_two_pi(np.arctan2(node[..., 1], node[..., 0])))
    ahead_hat = cross(h_hat, node_hat)
    return _PlaneGeometry(h_hat=h_hat, node_hat=node_hat, ahead_hat=ahead_hat, i=i, raan=raan)


# --------------------------------------------------------------------------- #
# Anomalies and Kepler's equation (elliptic orbits, 0 <= e < 1)
# --------------------------------------------------------------------------- #
def _beta(e: NDArray[np.float64]) -> NDArray[np.float64]:
    """beta = e / (1 + sqrt(1 - e^2)), the half-angle factor of the anomaly relations."""
    return e / (1.0 + np.sqrt(1.0 - e * e))


def eccentric_to_true_anomaly(E: ArrayLike, e: ArrayLike) -> FloatOrArray:
    """True anomaly [rad] from the eccentric anomaly E [rad], elliptic orbits.

    nu = E + 2 atan(beta sin E / (1 - beta cos E)), beta = e / (1 + sqrt(1 - e^2))
    (Broucke & Cefola 1973, Celestial Mechanics 7, 388-389). Equivalent to
    the half-angle relation tan(nu/2) = sqrt((1+e)/(1-e)) tan(E/2) but free of
    quadrant tests, and it keeps the revolution count of E.
    """
    E, beta = _as_float(E), _beta(_as_float(e))
    return _scalar_or_array(E + 2.0 * np.arctan(beta * np.sin(E) / (1.0 - beta * np.cos(E))))


def true_to_eccentric_anomaly(nu: ArrayLike, e: ArrayLike) -> FloatOrArray:
    """Eccentric anomaly [rad] from the true anomaly nu [rad], elliptic orbits.

    Inverse of :func:`eccentric_to_true_anomaly`:
    E = nu - 2 atan(beta sin nu / (1 + beta cos nu)); keeps the revolution count.
    """
    nu, beta = _as_float(nu), _beta(_as_float(e))
    return _scalar_or_array(nu - 2.0 * np.arctan(beta * np.sin(nu) / (1.0 + beta * np.cos(nu))))


def eccentric_to_mean_anomaly(E: ArrayLike, e: ArrayLike) -> FloatOrArray:
    """Kepler's equation M = E - e sin E [rad] (Vallado 2013, §2.2)."""
    E = _as_float(E)
    return _scalar_or_array(E - _as_float(e) * np.sin(E))


def mean_to_eccentric_anomaly(
    M: ArrayLike,
    e: ArrayLike,
    *,
    tol: float = _KEPLER_TOL,
    max_iter: int = _KEPLER_MAX_ITER,
) -> FloatOrArray:
    """Solve Kepler's equation M = E - e sin E for E [rad], 0 <= e < 1, vectorised.

    Newton-Raphson with Vallado's starter (Vallado 2013, Algorithm 2,
    ``KepEqtnE``): E0 = M + e if M in (0, pi), else M - e, on M reduced to
    (-pi, pi]; the revolution count of M is restored at the end. Iterates until
    every |dE| <= tol (radians, default a few ulps of 2 pi) or raises after
    ``max_iter`` steps.
    """
    M, e = np.broadcast_arrays(_as_float(M), _as_float(e))
    if np.any((e < 0.0) | (e >= 1.0)):
        raise ValueError("Kepler's equation here is for elliptic orbits, 0 <= e < 1")
    if M.ndim == 0:
        return _eccentric_anomaly_single(float(M), float(e), tol, max_iter)
    revolutions = np.round(M / TWO_PI)
    M_reduced = M - TWO_PI * revolutions
    E = np.where(M_reduced > 0.0, M_reduced + e, M_reduced - e)
    for _ in range(max_iter):
        step = (E - e * np.sin(E) - M_reduced) / (1.0 - e * np.cos(E))
        E = E - step
        if np.all(np.abs(step) <= tol * np.maximum(1.0, np.abs(E))):
            break
    else:
        raise RuntimeError(f"Kepler's equation did not converge in {max_iter} iterations")
    return _scalar_or_array(E + TWO_PI * revolutions)


def _eccentric_anomaly_single(M: float, e: float, tol: float, max_iter: int) -> float:
    """:func:`mean_to_eccentric_anomaly` of one angle on floats (the same iteration; the
    J2 mean-element inversion solves ~6 per state, a third of its time on 0-d arrays)."""
    revolutions = round(M / TWO_PI)
    M_reduced = M - TWO_PI * revolutions
    E = M_reduced + e if M_reduced > 0.0 else M_reduced - e
    for _ in range(max_iter):
        step = (E - e * math.sin(E) - M_reduced) / (1.0 - e * math.cos(E))
        E = E - step
        if abs(step) <= tol * max(1.0, abs(E)):
            break
    else:
        raise RuntimeError(f"Kepler's equation did not converge in {max_iter} iterations")
    return E + TWO_PI * revolutions


def true_to_mean_anomaly(nu: ArrayLike, e: ArrayLike) -> FloatOrArray:
    """Mean anomaly [rad] from true anomaly [rad], elliptic orbits (keeps revolutions)."""
    return eccentric_to_mean_anomaly(true_to_eccentric_anomaly(nu, e), e)


def mean_to_true_anomaly(
    M: ArrayLike, e: ArrayLike, *, tol: float = _KEPLER_TOL, max_iter: int = _KEPLER_MAX_ITER
) -> FloatOrArray:
    """True anomaly [rad] from mean anomaly [rad] through Kepler's equation, 0 <= e < 1."""
    E = mean_to_eccentric_anomaly(M, e, tol=tol, max_iter=max_iter)
    return eccentric_to_true_anomaly(E, e)


def true_to_mean_argument_of_latitude(u: ArrayLike, ex: ArrayLike, ey: ArrayLike) -> FloatOrArray:
    """Mean argument of latitude lambda = M + argp [rad] from the true one u = nu + argp.

    Regular as e -> 0 (argp = atan2(ey, ex) is then arbitrary, but
    lambda - u = M - nu vanishes with e). Keeps the revolution count of u.
    """
    u, ex, ey = _as_float(u), _as_float(ex), _as_float(ey)
    argp = np.arctan2(ey, ex)
    e = np.hypot(ex, ey)
    return _scalar_or_array(u + (np.asarray(true_to_mean_anomaly(u - argp, e)) - (u - argp)))


def mean_to_true_argument_of_latitude(
    lam: ArrayLike,
    ex: ArrayLike,
    ey: ArrayLike,
    *,
    tol: float = _KEPLER_TOL,
    max_iter: int = _KEPLER_MAX_ITER,
) -> FloatOrArray:
    """True argument of latitude u [rad] from the mean one lambda = M + argp [rad]."""
    lam, ex, ey = _as_float(lam), _as_float(ex), _as_float(ey)
    argp = np.arctan2(ey, ex)
    e = np.hypot(ex, ey)
    mean_anomaly = lam - argp
    nu = np.asarray(mean_to_true_anomaly(mean_anomaly, e, tol=tol, max_iter=max_iter))
    return _scalar_or_array(lam + (nu - mean_anomaly))


def mean_motion(a: ArrayLike, *, mu: float) -> FloatOrArray:
    """Mean motion n = sqrt(mu / |a|^3) [rad/s]; a [m], mu [m^3/s^2]."""
    a = _as_float(a)
    return _scalar_or_array(np.sqrt(mu / np.abs(a) ** 3))


def orbital_period(a: ArrayLike, *, mu: float) -> FloatOrArray:
    """Keplerian period T = 2 pi sqrt(a^3 / mu) [s]; a > 0 [m], mu [m^3/s^2]."""
    a = _as_float(a)
    return _scalar_or_array(TWO_PI * np.sqrt(a**3 / mu))


# --------------------------------------------------------------------------- #
# Classical elements
# --------------------------------------------------------------------------- #
def coe_to_rv(
    a: ArrayLike,
    e: ArrayLike,
    i: ArrayLike,
    raan: ArrayLike,
    argp: ArrayLike,
    nu: ArrayLike,
    *,
    mu: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cartesian state from classical elements (Vallado 2013, Algorithm 10, ``COE2RV``).

    a [m] (a < 0 with e > 1 for a hyperbola), e [-], i, raan, argp, nu [rad],
    mu [m^3/s^2]. Returns r [m] and v [m/s], each shaped ``(..., 3)``.
    Parabolae (e = 1, infinite a) are not handled.
    """
    a, e, i, raan, argp, nu = np.broadcast_arrays(
        *(_as_float(x) for x in (a, e, i, raan, argp, nu))
    )
    node_hat, ahead_hat = _in_plane_basis(raan, i)
    return _state_in_plane(
        a * (1.0 - e * e),
        e * np.cos(argp),
        e * np.sin(argp),
        argp + nu,
        node_hat,
        ahead_hat,
        mu,
    )


def rv_to_coe(
    r: ArrayLike,
    v: ArrayLike,
    *,
    mu: float,
    circular_tol: float = _DEGENERATE_TOL,
    equatorial_tol: float = _DEGENERATE_TOL,
) -> ClassicalElements:
    """Classical elements from a Cartesian state (Vallado 2013, Algorithm 9, ``RV2COE``).

    r [m], v [m/s] shaped ``(..., 3)``; mu [m^3/s^2]. Angles use atan2 of
    projections rather than Vallado's acos + quadrant tests. Degenerate cases
    follow Vallado's special orbits:

    * circular (e <= ``circular_tol``): argp := 0 and nu is the argument of
      latitude measured from the ascending node;
    * equatorial (sin i <= ``equatorial_tol``, prograde or retrograde):
      raan := 0, the node is taken along the x axis, so argp is the longitude
      of periapsis measured about the angular momentum;
    * circular equatorial: raan := argp := 0 and nu is the true longitude.

    Above the tolerances every angle is computed as is: for a nearly singular
    orbit argp (or raan) is ill conditioned, but nu = u - argp compensates, so
    the state is reproduced to rounding. Hyperbolic orbits give a < 0 and
    e > 1; a parabola gives an infinite a.
    """
    r, v = np.broadcast_arrays(_as_float(r), _as_float(v))
    plane = _plane_geometry(r, v, equatorial_tol)
    ecc_vec = eccentricity_vector(r, v, mu)
    e = _norm(ecc_vec)
    circular = e <= circular_tol
    argp = np.where(
        circular, 0.0, wrap_to_two_pi(_angle_about(plane.node_hat, ecc_vec, plane.h_hat))
    )
    u = _angle_about(plane.node_hat, r, plane.h_hat)
    return ClassicalElements(
        a=_scalar_or_array(_semi_major_axis(r, v, mu)),
        e=_scalar_or_array(e),
        i=_scalar_or_array(plane.i),
        raan=_scalar_or_array(plane.raan),
        argp=_scalar_or_array(argp),
        nu=_scalar_or_array(wrap_to_two_pi(u - argp)),
    )


def argument_of_latitude(r: ArrayLike, v: ArrayLike) -> FloatOrArray:
    """True argument of latitude u = argp + nu [rad], counted from the ascending node.

    r [m], v [m/s] (only the direction of r x v matters). Needs i != 0: for an
    equatorial orbit the node is undefined and this returns the angle from the
    x axis (the convention of :func:`rv_to_coe`).
    """
    r, v = np.broadcast_arrays(_as_float(r), _as_float(v))
    plane = _plane_geometry(r, v, _DEGENERATE_TOL)
    return _scalar_or_array(wrap_to_two_pi(_angle_about(plane.node_hat, r, plane.h_hat)))


# --------------------------------------------------------------------------- #
# Nonsingular elements (near-circular orbits)
# --------------------------------------------------------------------------- #
def nonsingular_to_rv(
    el: NonsingularElements, *, mu: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cartesian state from nonsingular elements, regular at e = 0.

    r = p / (1 + ex cos u + ey sin u) along u from the node,
    v = sqrt(mu/p) [-(sin u + ey) n_hat + (cos u + ex) m_hat], with p = a (1 - ex^2 - ey^2),
    n_hat the node direction and m_hat = h_hat x n_hat: Vallado's (2013)
    perifocal formulas (Algorithm 10) rotated by argp, P and Q written with ex, ey.
    a [m], angles [rad], mu [m^3/s^2]; returns r [m], v [m/s].
    """
    a, ex, ey, i, raan, u = np.broadcast_arrays(
        *(_as_float(x) for x in (el.a, el.ex, el.ey, el.i, el.raan, el.u))
    )
    node_hat, ahead_hat = _in_plane_basis(raan, i)
    return _state_in_plane(a * (1.0 - ex * ex - ey * ey), ex, ey, u, node_hat, ahead_hat, mu)


def rv_to_nonsingular(
    r: ArrayLike, v: ArrayLike, *, mu: float, equatorial_tol: float = _DEGENERATE_TOL
) -> NonsingularElements:
    """Nonsingular elements (a, ex, ey, i, raan, u) from a Cartesian state.

    ex, ey are the eccentricity vector's components along the node and 90 deg
    ahead of it in the orbit plane, u the angle of r from the node: all well
    defined for e -> 0. Not for i -> 0, where the node is undefined: below
    ``equatorial_tol`` (in sin i) raan := 0 and the node is the x axis, and
    for small nonzero i raan and u are individually ill conditioned (their sum
    is not). r [m], v [m/s], mu [m^3/s^2].
    """
    r, v = np.broadcast_arrays(_as_float(r), _as_float(v))
    plane = _plane_geometry(r, v, equatorial_tol)
    ecc_vec = eccentricity_vector(r, v, mu)
    return NonsingularElements(
        a=_scalar_or_array(_semi_major_axis(r, v, mu)),
        ex=_scalar_or_array(_dot(ecc_vec, plane.node_hat)),
        ey=_scalar_or_array(_dot(ecc_vec, plane.ahead_hat)),
        i=_scalar_or_array(plane.i),
        raan=_scalar_or_array(plane.raan),
        u=_scalar_or_array(
            wrap_to_two_pi(np.arctan2(_dot(r, plane.ahead_hat), _dot(r, plane.node_hat)))
        ),
    )


def classical_to_nonsingular(coe: ClassicalElements) -> NonsingularElements:
    """(a, e, i, raan, argp, nu) -> (a, e cos argp, e sin argp, i, raan, argp + nu)."""
    e, argp = _as_float(coe.e), _as_float(coe.argp)
    return NonsingularElements(
        a=coe.a,
        ex=_scalar_or_array(e * np.cos(argp)),
        ey=_scalar_or_array(e * np.sin(argp)),
        i=coe.i,
        raan=coe.raan,
        u=_scalar_or_array(wrap_to_two_pi(argp + _as_float(coe.nu))),
    )


def nonsingular_to_classical(el: NonsingularElements) -> ClassicalElements:
    """Back to classical elements; argp = atan2(ey, ex), which is 0 when e = 0."""
    ex, ey = _as_float(el.ex), _as_float(el.ey)
    argp = wrap_to_two_pi(np.arctan2(ey, ex))
    return ClassicalElements(
        a=el.a,
        e=_scalar_or_array(np.hypot(ex, ey)),
        i=el.i,
        raan=el.raan,
        argp=_scalar_or_array(argp),
        nu=_scalar_or_array(wrap_to_two_pi(_as_float(el.u) - argp)),
    )


# --------------------------------------------------------------------------- #
# Equinoctial elements (near-equatorial orbits)
# --------------------------------------------------------------------------- #
def _equinoctial_basis(
    p: NDArray[np.float64], q: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unit vectors f_hat, g_hat of the equinoctial frame (Broucke & Cefola 1972, eq. 3).

    f_hat = (1 - p^2 + q^2, 2pq, -2p) / (1 + p^2 + q^2),
    g_hat = (2pq, 1 + p^2 - q^2, 2q) / (1 + p^2 + q^2).
    """
    scale = 1.0 / (1.0 + p * p + q * q)
    f_hat = np.stack([1.0 - p * p + q * q, 2.0 * p * q, -2.0 * p], axis=-1) * scale[..., None]
    g_hat = np.stack([2.0 * p * q, 1.0 + p * p - q * q, 2.0 * q], axis=-1) * scale[..., None]
    return f_hat, g_hat


def equinoctial_to_rv(
    el: EquinoctialElements, *, mu: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cartesian state from equinoctial elements (Broucke & Cefola 1972).

    In the equinoctial frame (f_hat, g_hat) the eccentricity vector is (k, h)
    and the position lies at the true longitude L, so the conic is written as
    for the nonsingular set: r = a (1 - h^2 - k^2) / (1 + k cos L + h sin L).
    a [m], angles [rad], mu [m^3/s^2]; returns r [m], v [m/s].
    """
    a, h, k, p, q, L = np.broadcast_arrays(
        *(_as_float(x) for x in (el.a, el.h, el.k, el.p, el.q, el.L))
    )
    f_hat, g_hat = _equinoctial_basis(p, q)
    return _state_in_plane(a * (1.0 - h * h - k * k), k, h, L, f_hat, g_hat, mu)


def rv_to_equinoctial(r: ArrayLike, v: ArrayLike, *, mu: float) -> EquinoctialElements:
    """Equinoctial elements from a Cartesian state (Broucke & Cefola 1972).

    With w_hat = h / |h|: p = w_x / (1 + w_z), q = -w_y / (1 + w_z); then
    k = e.f_hat, h = e.g_hat, L = atan2(r.g_hat, r.f_hat). Regular for
    e = 0 and i = 0; singular only for retrograde equatorial orbits (i = pi).
    r [m], v [m/s], mu [m^3/s^2].
    """
    r, v = np.broadcast_arrays(_as_float(r), _as_float(v))
    ang_mom = cross(r, v)
    w_hat = ang_mom / _norm(ang_mom)[..., None]
    p = w_hat[..., 0] / (1.0 + w_hat[..., 2])
    q = -w_hat[..., 1] / (1.0 + w_hat[..., 2])
    f_hat, g_hat = _equinoctial_basis(p, q)
    ecc_vec = eccentricity_vector(r, v, mu)
    return EquinoctialElements(
        a=_scalar_or_array(_semi_major_axis(r, v, mu)),
        h=_scalar_or_array(_dot(ecc_vec, g_hat)),
        k=_scalar_or_array(_dot(ecc_vec, f_hat)),
        p=_scalar_or_array(p),
        q=_scalar_or_array(q),
        L=_scalar_or_array(wrap_to_two_pi(np.arctan2(_dot(r, g_hat), _dot(r, f_hat)))),
    )


def classical_to_equinoctial(coe: ClassicalElements) -> EquinoctialElements:
    """Broucke & Cefola (1972) eq. 1: longitude of periapsis varpi = raan + argp."""
    e, i, raan = _as_float(coe.e), _as_float(coe.i), _as_float(coe.raan)
    varpi = raan + _as_float(coe.argp)
    tan_half_i = np.tan(0.5 * i)
    return EquinoctialElements(
        a=coe.a,
        h=_scalar_or_array(e * np.sin(varpi)),
        k=_scalar_or_array(e * np.cos(varpi)),
        p=_scalar_or_array(tan_half_i * np.sin(raan)),
        q=_scalar_or_array(tan_half_i * np.cos(raan)),
        L=_scalar_or_array(wrap_to_two_pi(varpi + _as_float(coe.nu))),
    )


def equinoctial_to_classical(el: EquinoctialElements) -> ClassicalElements:
    """Inverse of :func:`classical_to_equinoctial`; raan := 0 when i = 0, argp := 0 when e = 0."""
    h, k, p, q = (_as_float(x) for x in (el.h, el.k, el.p, el.q))
    raan = wrap_to_two_pi(np.arctan2(p, q))
    e = np.hypot(h, k)
    argp = np.where(e > 0.0, wrap_to_two_pi(np.arctan2(h, k) - raan), 0.0)
    return ClassicalElements(
        a=el.a,
        e=_scalar_or_array(e),
        i=_scalar_or_array(2.0 * np.arctan(np.hypot(p, q))),
        raan=_scalar_or_array(raan),
        argp=_scalar_or_array(argp),
        nu=_scalar_or_array(wrap_to_two_pi(_as_float(el.L) - raan - argp)),
    )
