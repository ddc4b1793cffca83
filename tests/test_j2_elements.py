"""J2 secular rates and mean <-> osculating elements, checked against independent references.

The strongest check is a second method: a numerical integration of the J2
equations of motion (written here, not taken from the library), whose
osculating elements must follow the analytic short-period terms along the
secularly propagated mean orbit to O(J2^2).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ovtraj.astro.elements import (
    NonsingularElements,
    coe_to_rv,
    mean_motion,
    mean_to_true_anomaly,
    orbital_period,
    rv_to_coe,
    rv_to_nonsingular,
    true_to_mean_anomaly,
)
from ovtraj.astro.j2_elements import (
    mean_to_osculating,
    mean_to_state,
    osculating_to_mean,
    propagate_mean,
    secular_rates,
    state_to_mean,
)
from ovtraj.config.physical import default_earth

EARTH = default_earth()
MU, R_E, J2 = EARTH.mu, EARTH.radius, EARTH.j2
KW = dict(mu=MU, radius=R_E, j2=J2)
DAY = 86400.0


def _angle_diff(x, y):
    return np.abs(np.mod(np.asarray(x) - np.asarray(y) + np.pi, 2.0 * np.pi) - np.pi)


# --------------------------------------------------------------------------- #
# Secular rates
# --------------------------------------------------------------------------- #
def test_sun_synchronous_nodal_rate():
    """A ~700 km orbit at 98.19 deg is sun-synchronous: raan_dot = 360 deg per tropical year."""
    raan_dot, _, _ = secular_rates(7078.0e3, 0.0, np.radians(98.19), **KW)
    year = 365.2422 * DAY
    assert raan_dot == pytest.approx(2.0 * np.pi / year, rel=1e-3)
    assert raan_dot == pytest.approx(1.991e-7, rel=1e-3)


def test_critical_inclination_freezes_perigee():
    critical = np.arccos(np.sqrt(0.2))  # 63.4349 deg
    assert np.degrees(critical) == pytest.approx(63.435, abs=1e-3)
    a, e = 7.0e6, 0.05
    _, argp_dot, _ = secular_rates(a, e, critical, **KW)
    n = mean_motion(a, mu=MU)
    assert abs(argp_dot) < 1e-14 * n
    _, below, _ = secular_rates(a, e, critical - 0.01, **KW)
    _, above, _ = secular_rates(a, e, critical + 0.01, **KW)
    assert below > 0.0 > above


def test_rates_vanish_where_the_theory_says():
    a = 7.0e6
    raan_dot, _, _ = secular_rates(a, 0.01, np.pi / 2, **KW)
    assert abs(raan_dot) < 1e-20
    # the anomalistic rate equals n at the "magic" inclination cos^2 i = 1/3
    _, _, mean_anomaly_dot = secular_rates(a, 0.01, np.arccos(np.sqrt(1.0 / 3.0)), **KW)
    assert mean_anomaly_dot == pytest.approx(mean_motion(a, mu=MU), rel=1e-15)


def test_second_order_rates_reduce_to_sgp4_at_zero_eccentricity():
    """Hoots & Roehrich (1980), Spacetrack Report No. 3, SGP4 J2 and J2^2 secular rates.

    With k = 3/2 J2 n (R/a)^2 and k2 = k J2 (R/a)^2 / 2 (SGP4's temp1, temp2
    at e = 0, J4 dropped): M_dot = n + k/2 (3c^2 - 1) + k2/16 (13 - 78c^2 + 137c^4),
    argp_dot = -k/2 (1 - 5c^2) + k2/16 (7 - 114c^2 + 395c^4),
    raan_dot = -k c + k2/2 (4 - 19c^2) c.
    """
    a = np.full(5, 6.9e6)
    i = np.radians([0.0, 28.5, 51.6, 97.0, 140.0])
    c = np.cos(i)
    n = mean_motion(a, mu=MU)
    k = 1.5 * J2 * n * (R_E / a) ** 2
    k2 = 0.5 * k * J2 * (R_E / a) ** 2
    raan_dot, argp_dot, m_dot = secular_rates(a, 0.0, i, **KW, second_order=True)
    np.testing.assert_allclose(raan_dot, -k * c + 0.5 * k2 * (4 - 19 * c**2) * c, rtol=1e-13)
    np.testing.assert_allclose(
        argp_dot, -0.5 * k * (1 - 5 * c**2) + k2 / 16 * (7 - 114 * c**2 + 395 * c**4), rtol=1e-13
    )
    np.testing.assert_allclose(
        m_dot, n + 0.5 * k * (3 * c**2 - 1) + k2 / 16 * (13 - 78 * c**2 + 137 * c**4), rtol=1e-13
    )


# --------------------------------------------------------------------------- #
# Mean <-> osculating
# --------------------------------------------------------------------------- #
def _random_leo_mean_elements(rng, n):
    altitude = rng.uniform(150e3, 1000e3, n)
    e = rng.uniform(0.0, 0.1, n)
    e[: n // 10] = 0.0
    e = np.minimum(e, 1.0 - (R_E + 100e3) / (R_E + altitude))  # keep perigee above 100 km
    i = np.radians(rng.uniform(0.0, 100.0, n))
    i[n // 10 : n // 5] = 10.0 ** rng.uniform(-7, -3, n // 10)  # near equatorial
    i[n // 5 : 3 * n // 10] = np.pi / 2 + rng.uniform(-1e-3, 1e-3, n // 10)  # near polar
    i[3 * n // 10] = np.arccos(np.sqrt(0.2))  # critical inclination
    argp = rng.uniform(0, 2 * np.pi, n)
    return NonsingularElements(
        a=R_E + altitude,
        ex=e * np.cos(argp),
        ey=e * np.sin(argp),
        i=i,
        raan=rng.uniform(0, 2 * np.pi, n),
        u=rng.uniform(0, 2 * np.pi, n),
    )


def _assert_elements_close(x, y, a_rtol, atol):
    np.testing.assert_allclose(x.a, y.a, rtol=a_rtol, atol=0)
    np.testing.assert_allclose(x.ex, y.ex, atol=atol)
    np.testing.assert_allclose(x.ey, y.ey, atol=atol)
    np.testing.assert_allclose(x.i, y.i, atol=atol)
    assert np.max(_angle_diff(x.raan, y.raan)) < atol
    assert np.max(_angle_diff(x.u, y.u)) < atol


def test_mean_osculating_round_trip_random_leo():
    mean = _random_leo_mean_elements(np.random.default_rng(1959), 400)
    osc = mean_to_osculating(mean, **KW)
    # the short-period terms are O(J2): km in a, 1e-3 in ex, ey
    assert 1e3 < np.max(np.abs(osc.a - mean.a)) < 3e4
    back = osculating_to_mean(osc, **KW)
    _assert_elements_close(back, mean, a_rtol=1e-12, atol=1e-11)
    # and the other way round: the inversion reproduces its target
    again = mean_to_osculating(osculating_to_mean(mean, **KW), **KW)
    _assert_elements_close(again, mean, a_rtol=1e-12, atol=1e-11)


def test_exact_circular_equatorial_mean_orbit():
    mean = NonsingularElements(a=R_E + 400e3, ex=0.0, ey=0.0, i=0.0, raan=0.0, u=1.0)
    osc = mean_to_osculating(mean, **KW)
    assert osc.i == 0.0
    back = osculating_to_mean(osc, **KW)
    _assert_elements_close(back, mean, a_rtol=1e-13, atol=1e-12)


def test_circular_limit_of_the_semi_major_axis_term():
    """For a circular mean orbit Brouwer's da reduces to 3/2 J2 R^2 / a sin^2 i cos 2u.

    (Its constant part (3 cos^2 i - 1)((a/r)^3 - eta^-3) vanishes at e = 0:
    the Brouwer mean a is the orbit average of the osculating one.)
    """
    u = np.linspace(0, 2 * np.pi, 13)
    a, i = R_E + 345e3, np.radians(51.6)
    mean = NonsingularElements(a=a, ex=0.0, ey=0.0, i=i, raan=0.3, u=u)
    osc = mean_to_osculating(mean, **KW)
    expected = 1.5 * J2 * R_E**2 / a * np.sin(i) ** 2 * np.cos(2 * u)
    np.testing.assert_allclose(osc.a - a, expected, rtol=1e-12, atol=1e-9)


def test_conversion_is_continuous_as_e_goes_to_zero():
    base = dict(a=R_E + 500e3, i=0.9, raan=1.0, u=np.linspace(0, 6, 7))
    at_zero = mean_to_osculating(NonsingularElements(ex=0.0, ey=0.0, **base), **KW)
    tiny = mean_to_osculating(NonsingularElements(ex=1e-12, ey=-1e-12, **base), **KW)
    # e = 1.4e-12 moves a by ~a J2 e ~ 1e-8 m: the change is physical, not a jump
    _assert_elements_close(tiny, at_zero, a_rtol=1e-14, atol=1e-11)


def test_zero_j2_is_the_identity():
    mean = _random_leo_mean_elements(np.random.default_rng(0), 50)
    osc = mean_to_osculating(mean, mu=MU, radius=R_E, j2=0.0)
    _assert_elements_close(osc, mean, a_rtol=1e-15, atol=1e-13)


def test_scalar_use_and_state_round_trip():
    mean = NonsingularElements(a=R_E + 420e3, ex=1e-4, ey=-2e-4, i=0.9, raan=0.5, u=3.0)
    r, v = mean_to_state(mean, **KW)
    assert r.shape == v.shape == (3,)
    back = state_to_mean(r, v, **KW)
    assert isinstance(back.a, float)
    _assert_elements_close(back, mean, a_rtol=1e-12, atol=1e-11)


def test_propagate_mean_is_linear_in_the_mean_angles():
    mean = NonsingularElements(a=R_E + 420e3, ex=0.01, ey=0.02, i=0.9, raan=0.5, u=3.0)
    dt = np.array([0.0, 1000.0, 5.0 * DAY])
    later = propagate_mean(mean, dt, **KW)
    e = np.hypot(0.01, 0.02)
    raan_dot, argp_dot, m_dot = secular_rates(mean.a, e, mean.i, **KW)
    np.testing.assert_allclose(later.a, mean.a)
    np.testing.assert_allclose(np.hypot(later.ex, later.ey), e, rtol=1e-14)
    assert np.max(_angle_diff(later.raan, 0.5 + raan_dot * dt)) < 1e-12
    argp0 = np.arctan2(0.02, 0.01)
    argp = np.arctan2(later.ey, later.ex)
    assert np.max(_angle_diff(argp, argp0 + argp_dot * dt)) < 1e-12
    mean_anomaly = true_to_mean_anomaly(later.u - argp, e)
    m0 = true_to_mean_anomaly(3.0 - argp0, e)
    assert np.max(_angle_diff(mean_anomaly, m0 + m_dot * dt)) < 1e-10


# --------------------------------------------------------------------------- #
# Second method: numerical integration of the J2 problem
# --------------------------------------------------------------------------- #
def _j2_equations_of_motion(_t, y):
    """Two-body + J2 in ECI (Curtis, Orbital Mechanics for Engineering Students, eq. 12.30)."""
    r = y[:3]
    r_norm = np.linalg.norm(r)
    z_sq = (r[2] / r_norm) ** 2
    scale = 1.5 * J2 * MU * R_E**2 / r_norm**5
    perturbation = -scale * r * np.array([1.0 - 5.0 * z_sq, 1.0 - 5.0 * z_sq, 3.0 - 5.0 * z_sq])
    return np.concatenate([y[3:], -MU * r / r_norm**3 + perturbation])


def _integrate(r0, v0, t):
    solution = solve_ivp(
        _j2_equations_of_motion,
        (t[0], t[-1]),
        np.concatenate([r0, v0]),
        method="DOP853",
        rtol=1e-12,
        atol=1e-6,
        t_eval=t,
    )
    assert solution.success
    return solution.y[:3].T, solution.y[3:].T


@pytest.fixture(scope="module", params=[28.5, 51.6], ids=["i28.5", "i51.6"])
def circular_345km_day(request):
    """One day of a 345 km circular orbit (osculating-circular at t = 0), seed 004's altitude."""
    a0 = R_E + 345e3
    r0, v0 = coe_to_rv(a0, 0.0, np.radians(request.param), 0.3, 0.0, 0.2, mu=MU)
    t = np.linspace(0.0, DAY, 4001)
    r, v = _integrate(r0, v0, t)
    return request.param, t, r0, v0, r, v


@pytest.mark.slow
def test_semi_major_axis_oscillation_matches_numerical_integration(circular_345km_day):
    inclination_deg, t, r0, v0, r, v = circular_345km_day
    numerical = rv_to_nonsingular(r, v, mu=MU)
    mean = propagate_mean(state_to_mean(r0, v0, **KW), t, **KW)
    analytic = mean_to_osculating(mean, **KW)
    window = t <= 3.0 * orbital_period(R_E + 345e3, mu=MU)
    amplitude_numerical = np.ptp(numerical.a[window])
    amplitude_analytic = np.ptp(analytic.a[window])
    # measured over 3 revolutions: 4502 m (28.5 deg) and 12090 m (51.6 deg)
    # peak to peak, analytic 4496 m and 12093 m (0.15 % and 0.03 %); the
    # circular-limit formula 3 J2 R^2/a sin^2 i gives 4474 m and 12070 m
    circular_limit = 3.0 * J2 * R_E**2 / (R_E + 345e3) * np.sin(np.radians(inclination_deg)) ** 2
    assert amplitude_numerical == pytest.approx(circular_limit, rel=0.02)
    assert amplitude_analytic == pytest.approx(amplitude_numerical, rel=0.02)
    # pointwise over the whole day the residual is second order, J2^2 a ~ 6 m
    assert np.max(np.abs(analytic.a - numerical.a)) < 15.0
    assert np.max(np.abs(analytic.ex - numerical.ex)) < 1e-5
    assert np.max(np.abs(analytic.ey - numerical.ey)) < 1e-5
    assert np.max(np.abs(analytic.i - numerical.i)) < 1e-6


# One-day position error, measured max over the day (u0 = 0.2 rad, raan 0.3 rad):
#   first-order rates:  28.5 deg 5.33 km, 51.6 deg 1.01 km  (after one orbit 340 m, 65 m)
#   with J2^2 rates:    28.5 deg 1.65 km, 51.6 deg 0.52 km  (after one orbit 115 m, 33 m)
#   two-body:           28.5 deg 1607 km, 51.6 deg 1063 km
# What is left is second order: the J2^2 secular drift (first-order rates) and
# the O(J2^2 a) ~ 5-20 m uncertainty of a first-order mean semi-major axis,
# i.e. an along-track drift of 3 pi x that per revolution. Bounds: +30 %.
ONE_DAY_BOUND_M = {
    (28.5, False): 7000.0,
    (51.6, False): 1400.0,
    (28.5, True): 2200.0,
    (51.6, True): 700.0,
}


@pytest.mark.slow
@pytest.mark.parametrize("second_order", [False, True], ids=["J2", "J2+J2^2"])
def test_mean_element_prediction_follows_numerical_trajectory(circular_345km_day, second_order):
    inclination_deg, t, r0, v0, r, v = circular_345km_day
    mean = propagate_mean(state_to_mean(r0, v0, **KW), t, **KW, second_order=second_order)
    r_pred, v_pred = mean_to_state(mean, **KW)
    error = np.linalg.norm(r_pred - r, axis=1)
    assert np.max(error) < ONE_DAY_BOUND_M[(inclination_deg, second_order)]
    first_orbit = t <= orbital_period(R_E + 345e3, mu=MU)
    assert np.max(error[first_orbit]) < 400.0
    assert np.max(np.linalg.norm(v_pred - v, axis=1)) < 8.0

    two_body = rv_to_coe(r0, v0, mu=MU)
    m0 = true_to_mean_anomaly(two_body.nu, two_body.e)
    nu = mean_to_true_anomaly(m0 + mean_motion(two_body.a, mu=MU) * t, two_body.e)
    r_kepler, _ = coe_to_rv(
        two_body.a, two_body.e, two_body.i, two_body.raan, two_body.argp, nu, mu=MU
    )
    kepler_error = np.max(np.linalg.norm(r_kepler - r, axis=1))
    assert kepler_error > 4.0e5
    assert np.max(error) < 1e-2 * kepler_error


@pytest.mark.slow
@pytest.mark.parametrize(
    ("altitude_km", "e", "inclination_deg"),
    [(345.0, 0.05, 28.5), (600.0, 0.1, 63.435), (345.0, 0.02, 97.0), (500.0, 0.03, 1e-3)],
)
def test_eccentric_orbits_follow_numerical_integration(altitude_km, e, inclination_deg):
    """The short-period terms are exact in e: check them on eccentric orbits over 3 revolutions."""
    a0 = R_E + altitude_km * 1e3
    r0, v0 = coe_to_rv(a0, e, np.radians(inclination_deg), 0.3, 0.5, 0.2, mu=MU)
    t = np.linspace(0.0, 3.0 * orbital_period(a0, mu=MU), 601)
    r, v = _integrate(r0, v0, t)
    numerical = rv_to_nonsingular(r, v, mu=MU)
    mean = propagate_mean(state_to_mean(r0, v0, **KW), t, **KW, second_order=True)
    analytic = mean_to_osculating(mean, **KW)
    # measured: |da| <= 32 m against peak-to-peak oscillations of 1-20 km,
    # |d(ex, ey)| <= 8e-6, position error after 3 revolutions <= 490 m
    assert np.max(np.abs(analytic.a - numerical.a)) < 60.0
    assert np.max(np.abs(analytic.ex - numerical.ex)) < 1e-5
    assert np.max(np.abs(analytic.ey - numerical.ey)) < 1e-5
    r_pred, _ = mean_to_state(mean, **KW)
    assert np.max(np.linalg.norm(r_pred - r, axis=1)) < 700.0
