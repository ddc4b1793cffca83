"""J2 secular rates and the first-order J2 mean <-> osculating element conversion.

Theory
------
Brouwer (1959), "Solution of the problem of artificial satellite theory
without drag", Astronomical Journal 64, 378, restricted to J2 and to its
first-order *short-period* terms, in the nonsingular form of Lyddane (1963),
"Small eccentricities or inclinations in the Brouwer theory of the artificial
satellite", Astronomical Journal 68, 555. The same terms are printed in
Schaub & Junkins, "Analytical Mechanics of Space Systems", Appendix F, and,
directly in (a, u, i, ex, ey, raan), by Gim & Alfriend (2003), "State
transition matrix of relative motion for the perturbed noncircular reference
orbit", J. Guidance, Control, and Dynamics 26(6), 956, Appendix.

The element corrections of Brouwer's short-period generating function,
evaluated with the mean elements (gamma2 = J2 R^2 / (2 a^2),
gamma2' = gamma2 / eta^4, eta = sqrt(1 - e^2), c = cos i, s = sin i,
f the true anomaly, l the mean anomaly, g = argp, h = raan, 2g + 2f = 2u):

* da = a gamma2 [(3c^2 - 1)((a/r)^3 - eta^-3) + 3 s^2 (a/r)^3 cos 2u]
* de, e dg, dl + dg, dh, di as in Brouwer's eqs. for the short-period parts.

Brouwer's de and dg carry a 1/e, and dl the opposite one: the code never
forms them alone. It builds d(ex + i ey) = exp(i g) (de + i e dg), where e dg
is finite, and d(lambda) = dl + dg, lambda = M + argp the mean argument of
latitude, where the 1/e terms cancel to eta^2 (1 - eta) / e = eta^2 e / (1 + eta).
Everything is then regular at e = 0 (argp is taken as 0 there: the
combinations only depend on u). The terms are exact in e (not expanded), so
e up to ~0.1 and beyond is fine for the short-period part.

What is left out, and why:
* Brouwer's long-period terms. With J2 alone they come from the J2^2 part of
  the Hamiltonian, are O(J2 e) in (ex, ey) and O(J2 e^2) in the angles, and
  carry the 1 / (1 - 5 cos^2 i) critical-inclination singularity: for the
  near-circular orbits of this project they are metres, and leaving them out
  keeps the conversion regular at 63.4 deg. The mean elements here are
  therefore "Brouwer mean without long-period terms".
* Second-order (J2^2) short-period terms. Truncating the transformation at
  first order leaves an O(J2^2 a) uncertainty, ~5-20 m in LEO, in the mean
  semi-major axis, hence an along-track drift of ~3 pi times that per
  revolution (50-180 m per revolution at 345 km). Brouwer's J2^2 secular
  rates are available (``second_order=True`` in :func:`secular_rates` and
  :func:`propagate_mean`) and remove the J2^2 drift of raan and argp; by
  default the rates are first order. Measured against a numerical J2
  integration of a 345 km circular orbit over one day: 5.3 km (28.5 deg) and
  1.0 km (51.6 deg) with first-order rates, 1.7 km and 0.5 km with the J2^2
  rates, where a two-body prediction errs by 1000-1600 km.

Elements
--------
Inputs and outputs are :class:`~ovtraj.astro.elements.NonsingularElements`
(a, ex, ey, i, raan, u) with u the *true* argument of latitude, for mean and
osculating sets alike: the mean u is argp'' + nu'', nu'' being what the mean
anomaly M'' and the mean e'' give through Kepler's equation. Internally the
secular theory advances the mean argument of latitude lambda = M + argp
linearly in time. The set is singular for i -> 0 (raan undefined), but the
short-period corrections themselves stay finite there (none divides by
sin i), so small inclinations only make raan and u individually ill
conditioned.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ovtraj.astro.angles import wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.elements import (
    FloatOrArray,
    NonsingularElements,
    mean_motion,
    mean_to_true_argument_of_latitude,
    nonsingular_to_rv,
    rv_to_nonsingular,
    true_to_mean_argument_of_latitude,
)

_EPS = float(np.finfo(float).eps)
# The fixed-point inversion contracts by a factor ~J2 per step; it stops when
# the relative correction is at rounding level (a few ulps) in every element.
_INVERSION_TOL = 64.0 * _EPS
_INVERSION_MAX_ITER = 30


def _as_float(x: ArrayLike) -> NDArray[np.float64]:
    return np.asarray(x, dtype=float)


def _scalar_or_array(x: NDArray[np.float64]) -> FloatOrArray:
    return x[()] if np.ndim(x) == 0 else x


# --------------------------------------------------------------------------- #
# Secular rates
# --------------------------------------------------------------------------- #
def secular_rates(
    a: ArrayLike,
    e: ArrayLike,
    i: ArrayLike,
    *,
    mu: float,
    radius: float,
    j2: float,
    second_order: bool = False,
) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
    """J2 secular rates of raan, argp and mean anomaly [rad/s], first order by default.

    With n = sqrt(mu / a^3), p = a (1 - e^2), eta = sqrt(1 - e^2), c = cos i:

    * raan_dot = -3/2 n J2 (R/p)^2 c
    * argp_dot = 3/4 n J2 (R/p)^2 (5 c^2 - 1)
    * M_dot = n [1 + 3/4 J2 (R/p)^2 eta (3 c^2 - 1)]

    (Brouwer 1959, first-order secular terms; the same rates are in Vallado
    2013, ch. 9, and in Schaub & Junkins' J2 secular drift).
    ``mean_anomaly_dot`` includes n. ``a``, ``e``, ``i`` must be the
    Brouwer mean elements, the ones :func:`osculating_to_mean` produces:
    a [m], i [rad], mu [m^3/s^2], radius [m] (equatorial), j2 [-].

    ``second_order=True`` adds Brouwer's (1959) J2^2 secular terms
    (gamma2' = J2/2 (R/p)^2; J4 is not part of this model):

    * raan: 3/8 n gamma2'^2 [(-5 + 12 eta + 9 eta^2) c + (-35 - 36 eta - 5 eta^2) c^3]
    * argp: 3/32 n gamma2'^2 [-35 + 24 eta + 25 eta^2 + (90 - 192 eta - 126 eta^2) c^2
      + (385 + 360 eta + 45 eta^2) c^4]
    * M: 3/32 n gamma2'^2 eta [-15 + 16 eta + 25 eta^2 + (30 - 96 eta - 90 eta^2) c^2
      + (105 + 144 eta + 25 eta^2) c^4]

    which reduce at e = 0 to the J2^2 rates of SGP4 (Hoots & Roehrich 1980,
    Spacetrack Report No. 3). The short-period conversion stays first order;
    the J2^2 terms matter over many revolutions: they cut the one-day error of
    a 345 km orbit at 28.5 deg from ~5.3 km to ~1.7 km (see the tests).
    """
    a, e, i = _as_float(a), _as_float(e), _as_float(i)
    n = np.asarray(mean_motion(a, mu=mu))
    eta_sq = 1.0 - e * e
    eta = np.sqrt(eta_sq)
    gamma2p = 0.5 * j2 * (radius / (a * eta_sq)) ** 2
    c = np.cos(i)
    c_sq = c * c
    raan_dot = -3.0 * n * gamma2p * c
    argp_dot = 1.5 * n * gamma2p * (5.0 * c_sq - 1.0)
    mean_anomaly_dot = n * (1.0 + 1.5 * gamma2p * eta * (3.0 * c_sq - 1.0))
    if second_order:
        scale = n * gamma2p * gamma2p
        raan_dot = raan_dot + 0.375 * scale * (
            (-5.0 + 12.0 * eta + 9.0 * eta_sq) * c + (-35.0 - 36.0 * eta - 5.0 * eta_sq) * c * c_sq
        )
        argp_dot = argp_dot + 0.09375 * scale * (
            -35.0
            + 24.0 * eta
            + 25.0 * eta_sq
            + (90.0 - 192.0 * eta - 126.0 * eta_sq) * c_sq
            + (385.0 + 360.0 * eta + 45.0 * eta_sq) * c_sq * c_sq
        )
        mean_anomaly_dot = mean_anomaly_dot + 0.09375 * scale * eta * (
            -15.0
            + 16.0 * eta
            + 25.0 * eta_sq
            + (30.0 - 96.0 * eta - 90.0 * eta_sq) * c_sq
            + (105.0 + 144.0 * eta + 25.0 * eta_sq) * c_sq * c_sq
        )
    return (
        _scalar_or_array(raan_dot),
        _scalar_or_array(argp_dot),
        _scalar_or_array(mean_anomaly_dot),
    )


def propagate_mean(
    mean: NonsingularElements,
    dt: ArrayLike,
    *,
    mu: float,
    radius: float,
    j2: float,
    second_order: bool = False,
) -> NonsingularElements:
    """Advance Brouwer mean elements by ``dt`` [s] with the J2 secular rates.

    a, e, i stay constant; raan and argp (the eccentricity vector turns with
    it) drift linearly, and so does lambda = M + argp. ``dt`` broadcasts
    against the elements. Mean elements in, mean elements out (true u).
    ``second_order`` is passed to :func:`secular_rates`.
    """
    a, ex, ey, i, raan, u = np.broadcast_arrays(
        *(_as_float(x) for x in (mean.a, mean.ex, mean.ey, mean.i, mean.raan, mean.u))
    )
    dt = _as_float(dt)
    e = np.hypot(ex, ey)
    raan_dot, argp_dot, mean_anomaly_dot = secular_rates(
        a, e, i, mu=mu, radius=radius, j2=j2, second_order=second_order
    )
    lam = np.asarray(true_to_mean_argument_of_latitude(u, ex, ey))
    turn = np.asarray(argp_dot) * dt
    cos_turn, sin_turn = np.cos(turn), np.sin(turn)
    ex_t = ex * cos_turn - ey * sin_turn
    ey_t = ex * sin_turn + ey * cos_turn
    lam_t = lam + (np.asarray(mean_anomaly_dot) + np.asarray(argp_dot)) * dt
    u_t = np.asarray(mean_to_true_argument_of_latitude(lam_t, ex_t, ey_t))
    a_t, i_t = np.broadcast_arrays(a, i, ex_t)[:2]
    return NonsingularElements(
        a=_scalar_or_array(np.array(a_t)),
        ex=_scalar_or_array(ex_t),
        ey=_scalar_or_array(ey_t),
        i=_scalar_or_array(np.array(i_t)),
        raan=_scalar_or_array(wrap_to_two_pi(raan + np.asarray(raan_dot) * dt)),
        u=_scalar_or_array(wrap_to_two_pi(u_t)),
    )


# --------------------------------------------------------------------------- #
# Short-period corrections
# --------------------------------------------------------------------------- #
def _short_period_corrections(
    a: NDArray[np.float64],
    ex: NDArray[np.float64],
    ey: NDArray[np.float64],
    i: NDArray[np.float64],
    u: NDArray[np.float64],
    lam: NDArray[np.float64],
    *,
    radius: float,
    j2: float,
) -> tuple[NDArray[np.float64], ...]:
    """Brouwer's first-order J2 short-period terms in (a, ex, ey, i, raan, lambda).

    Brouwer (1959) short-period parts of a, e, i, l, g, h (J2 only), as in
    Schaub & Junkins Appendix F, recombined without 1/e (Lyddane 1963):
    e dl = -eta^3 gamma2' B / 4, e dg = eta^2 gamma2' B / 4 + e gamma2' C / 4. One
    group of the formula at a time: da (:func:`_da`), de (:func:`_de`), Brouwer's B
    (:func:`_b_term`) and C (:func:`_c_parts`), then e dg and dl + dg, dh and di, and
    de, e dg turned into (ex, ey). Returns the corrections (da, dex, dey, di, draan,
    dlambda) to add to the mean elements.
    """
    q = _ShortPeriodArguments(a, ex, ey, i, u, lam, radius=radius, j2=j2)
    da = _da(a, q)
    de = _de(q)
    b = _b_term(q)
    centre_plus, harmonics = _c_parts(q)
    c = 6.0 * (5.0 * q.cos_sq - 1.0) * centre_plus + (3.0 - 5.0 * q.cos_sq) * harmonics

    # e dg = eta^2 gamma2' B / 4 + e gamma2' C / 4 and dl + dg, whose 1/e terms cancel.
    e_dargp = 0.25 * q.gamma2p * (q.eta_sq * b + q.e * c)
    dlam = 0.25 * q.gamma2p * (q.eta_sq * q.e * b / (1.0 + q.eta) + c)
    # dh and di.
    draan = -0.5 * q.gamma2p * q.cos_i * (6.0 * centre_plus - harmonics)
    di = (
        0.5
        * q.gamma2p
        * q.cos_i
        * q.sin_i
        * (3.0 * q.cos_2u + q.e * (3.0 * q.cos_2u_m_f + q.cos_2u_p_f))
    )

    # d(ex + i ey) = exp(i g) (de + i e dg).
    cos_g, sin_g = np.cos(q.argp), np.sin(q.argp)
    dex = cos_g * de - sin_g * e_dargp
    dey = sin_g * de + cos_g * e_dargp
    return da, dex, dey, di, draan, dlam


class _ShortPeriodArguments:
    """What every group of :func:`_short_period_corrections` takes from the mean elements:
    e, argp, eta, the inclination's and the true anomaly's cosines and sines, gamma2 and
    gamma2' = gamma2 / eta^4, a/r, the harmonics of 2u and 2u -+ f, and the equation of
    the centre."""

    def __init__(
        self,
        a: NDArray[np.float64],
        ex: NDArray[np.float64],
        ey: NDArray[np.float64],
        i: NDArray[np.float64],
        u: NDArray[np.float64],
        lam: NDArray[np.float64],
        *,
        radius: float,
        j2: float,
    ) -> None:
        e = np.hypot(ex, ey)
        # argp is arbitrary for e = 0 (atan2 gives 0); the combinations built
        # below only depend on u there, so any value is right.
        argp = np.arctan2(ey, ex)
        f = u - argp
        eta_sq = 1.0 - e * e
        cos_i, sin_i = np.cos(i), np.sin(i)
        gamma2 = 0.5 * j2 * (radius / a) ** 2
        self.e, self.argp, self.eta_sq, self.eta = e, argp, eta_sq, np.sqrt(eta_sq)
        self.cos_i, self.sin_i = cos_i, sin_i
        self.cos_sq, self.sin_sq = cos_i * cos_i, sin_i * sin_i
        self.gamma2, self.gamma2p = gamma2, gamma2 / eta_sq**2

        self.cos_f, self.sin_f = np.cos(f), np.sin(f)
        self.e_cos_f, self.e_sin_f = e * self.cos_f, e * self.sin_f
        self.a_over_r = (1.0 + self.e_cos_f) / eta_sq
        # 2g + 2f = 2u, 2g + f = 2u - f, 2g + 3f = 2u + f
        self.cos_2u, self.sin_2u = np.cos(2.0 * u), np.sin(2.0 * u)
        self.cos_2u_m_f, self.sin_2u_m_f = np.cos(2.0 * u - f), np.sin(2.0 * u - f)
        self.cos_2u_p_f, self.sin_2u_p_f = np.cos(2.0 * u + f), np.sin(2.0 * u + f)
        # true minus mean anomaly (equation of the centre), bounded by ~2e
        self.centre = wrap_to_pi(u - lam)


def _da(a: NDArray[np.float64], q: _ShortPeriodArguments) -> NDArray[np.float64]:
    """da = a gamma2 [(3c^2 - 1)((a/r)^3 - eta^-3) + 3 s^2 (a/r)^3 cos 2u]."""
    return (
        a
        * q.gamma2
        * (
            (3.0 * q.cos_sq - 1.0) * (q.a_over_r**3 - 1.0 / (q.eta_sq * q.eta))
            + 3.0 * q.sin_sq * q.a_over_r**3 * q.cos_2u
        )
    )


def _de(q: _ShortPeriodArguments) -> NDArray[np.float64]:
    """de = gamma2'/2 [(3c^2 - 1) A1 + 3 s^2 A2 cos(2g + 2f) - eta^2 s^2 (3 cos(2g + f) +
    cos(2g + 3f))], A1 = ((1 + e cos f)^3 - eta^3) / e and A2 = ((1 + e cos f)^3 - eta^2) / e
    expanded so that nothing divides by e."""
    cos_f, e_cos_f, e, eta, eta_sq = q.cos_f, q.e_cos_f, q.e, q.eta, q.eta_sq
    cubic_over_e = 3.0 * cos_f + 3.0 * e_cos_f * cos_f + e_cos_f * e_cos_f * cos_f
    a1 = cubic_over_e + e * (1.0 + eta + eta_sq) / (1.0 + eta)
    a2 = cubic_over_e + e
    return (
        0.5
        * q.gamma2p
        * (
            (3.0 * q.cos_sq - 1.0) * a1
            + 3.0 * q.sin_sq * a2 * q.cos_2u
            - eta_sq * q.sin_sq * (3.0 * q.cos_2u_m_f + q.cos_2u_p_f)
        )
    )


def _b_term(q: _ShortPeriodArguments) -> NDArray[np.float64]:
    """B = 2 (3c^2 - 1) (eta^2 (a/r)^2 + a/r + 1) sin f + 3 s^2 [(1 - eta^2 (a/r)^2 - a/r)
    sin(2g + f) + (eta^2 (a/r)^2 + a/r + 1/3) sin(2g + 3f)]."""
    r_term = q.eta_sq * q.a_over_r**2 + q.a_over_r
    return 2.0 * (3.0 * q.cos_sq - 1.0) * (r_term + 1.0) * q.sin_f + 3.0 * q.sin_sq * (
        (1.0 - r_term) * q.sin_2u_m_f + (r_term + 1.0 / 3.0) * q.sin_2u_p_f
    )


def _c_parts(q: _ShortPeriodArguments) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The two parts of C = 6 (5c^2 - 1) (f - l + e sin f) + (3 - 5c^2) [3 sin(2g + 2f)
    + 3 e sin(2g + f) + e sin(2g + 3f)]: f - l + e sin f and the bracket (dh is made of
    the same two)."""
    centre_plus = q.centre + q.e_sin_f
    harmonics = 3.0 * q.sin_2u + q.e * (3.0 * q.sin_2u_m_f + q.sin_2u_p_f)
    return centre_plus, harmonics


def _mean_to_osculating_lambda(
    x: tuple[NDArray[np.float64], ...], *, radius: float, j2: float
) -> tuple[NDArray[np.float64], ...]:
    """The map on (a, ex, ey, i, raan, lambda) tuples, lambda the mean argument of latitude."""
    a, ex, ey, i, _, lam = x
    u = np.asarray(mean_to_true_argument_of_latitude(lam, ex, ey))
    corrections = _short_period_corrections(a, ex, ey, i, u, lam, radius=radius, j2=j2)
    return tuple(xk + dk for xk, dk in zip(x, corrections, strict=True))


def _to_lambda_tuple(el: NonsingularElements) -> tuple[NDArray[np.float64], ...]:
    a, ex, ey, i, raan, u = np.broadcast_arrays(
        *(_as_float(x) for x in (el.a, el.ex, el.ey, el.i, el.raan, el.u))
    )
    lam = np.asarray(true_to_mean_argument_of_latitude(u, ex, ey))
    return a, ex, ey, i, raan, lam


def _from_lambda_tuple(x: tuple[NDArray[np.float64], ...]) -> NonsingularElements:
    a, ex, ey, i, raan, lam = x
    u = np.asarray(mean_to_true_argument_of_latitude(lam, ex, ey))
    return NonsingularElements(
        a=_scalar_or_array(a),
        ex=_scalar_or_array(ex),
        ey=_scalar_or_array(ey),
        i=_scalar_or_array(i),
        raan=_scalar_or_array(wrap_to_two_pi(raan)),
        u=_scalar_or_array(wrap_to_two_pi(u)),
    )


def mean_to_osculating(
    mean: NonsingularElements, *, mu: float, radius: float, j2: float
) -> NonsingularElements:
    """Osculating nonsingular elements from Brouwer mean ones, first order in J2.

    Adds Brouwer's (1959) short-period J2 terms in Lyddane's (1963)
    nonsingular form (see the module docstring), regular for e = 0 and valid
    for any e < 1 (derived exact in e), any inclination including the
    critical one. a [m], angles [rad], radius [m] (equatorial), j2 [-].
    ``mu`` is accepted for a signature uniform with the rest of the module:
    the first-order short-period terms do not depend on it.
    """
    del mu  # the short-period terms are geometric (ratios of a, r and R)
    x = _to_lambda_tuple(mean)
    return _from_lambda_tuple(_mean_to_osculating_lambda(x, radius=radius, j2=j2))


def osculating_to_mean(
    osc: NonsingularElements,
    *,
    mu: float,
    radius: float,
    j2: float,
    tol: float = _INVERSION_TOL,
    max_iter: int = _INVERSION_MAX_ITER,
) -> NonsingularElements:
    """Brouwer mean nonsingular elements from osculating ones, first order in J2.

    The inverse of :func:`mean_to_osculating`.

    Fixed-point iteration x <- x + (x_osc - F(x)) on (a, ex, ey, i, raan,
    lambda), started at x = x_osc; F = :func:`mean_to_osculating` is the
    identity plus O(J2) terms, so each step gains about three digits. Stops
    when every correction is below ``tol`` (relative for a, absolute in
    rad / [-] for the others), raises ``RuntimeError`` after ``max_iter``
    steps. The result inverts F to rounding; it differs from the "true"
    Brouwer mean elements by O(J2^2), the truncation of F itself.
    """
    del mu
    target = _to_lambda_tuple(osc)
    x = target
    angle_slots = (4, 5)
    for _ in range(max_iter):
        image = _mean_to_osculating_lambda(x, radius=radius, j2=j2)
        residual = [t - y for t, y in zip(target, image, strict=True)]
        for k in angle_slots:
            residual[k] = wrap_to_pi(residual[k])
        x = tuple(xk + rk for xk, rk in zip(x, residual, strict=True))
        # One array of every correction (a is relative): one reduction per iteration.
        scaled = np.abs(np.array(residual, dtype=float))
        scaled[0] /= np.abs(x[0])
        if float(np.max(scaled)) <= tol:
            break
    else:
        raise RuntimeError(f"osculating_to_mean did not converge in {max_iter} iterations")
    return _from_lambda_tuple(x)


def state_to_mean(
    r: ArrayLike, v: ArrayLike, *, mu: float, radius: float, j2: float
) -> NonsingularElements:
    """Brouwer mean nonsingular elements (first order in J2) of a Cartesian state.

    r [m], v [m/s] shaped ``(..., 3)`` in the Earth-centred inertial frame
    (equator of date, the frame of J2's symmetry axis); mu [m^3/s^2],
    radius [m], j2 [-].
    """
    osc = rv_to_nonsingular(r, v, mu=mu)
    return osculating_to_mean(osc, mu=mu, radius=radius, j2=j2)


def mean_to_state(
    mean: NonsingularElements, *, mu: float, radius: float, j2: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cartesian state (r [m], v [m/s]) of Brouwer mean elements, first order in J2."""
    return nonsingular_to_rv(mean_to_osculating(mean, mu=mu, radius=radius, j2=j2), mu=mu)
