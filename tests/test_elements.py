"""Orbital elements <-> Cartesian state: published examples, conventions, round trips."""

from __future__ import annotations

import numpy as np
import pytest

from ovtraj.astro.elements import (
    ClassicalElements,
    EquinoctialElements,
    NonsingularElements,
    argument_of_latitude,
    classical_to_equinoctial,
    classical_to_nonsingular,
    coe_to_rv,
    eccentric_to_mean_anomaly,
    eccentric_to_true_anomaly,
    equinoctial_to_classical,
    equinoctial_to_rv,
    mean_motion,
    mean_to_eccentric_anomaly,
    mean_to_true_anomaly,
    mean_to_true_argument_of_latitude,
    nonsingular_to_classical,
    nonsingular_to_rv,
    orbital_period,
    rv_to_coe,
    rv_to_equinoctial,
    rv_to_nonsingular,
    true_to_eccentric_anomaly,
    true_to_mean_anomaly,
    true_to_mean_argument_of_latitude,
)
from ovtraj.config.physical import default_earth

EARTH = default_earth()
MU = EARTH.mu
KM = 1.0e3
# Vallado's examples use mu = 398600.4418 km^3/s^2, the same figure as the project's.
MU_VALLADO = 398600.4418 * KM**3


def _angle_diff(x, y):
    return np.abs(np.mod(np.asarray(x) - np.asarray(y) + np.pi, 2.0 * np.pi) - np.pi)


def _assert_same_state(r1, v1, r2, v2, rtol):
    r_scale = np.linalg.norm(r1, axis=-1)
    v_scale = np.linalg.norm(v1, axis=-1)
    assert np.all(np.linalg.norm(r1 - r2, axis=-1) <= rtol * r_scale)
    assert np.all(np.linalg.norm(v1 - v2, axis=-1) <= rtol * v_scale)


# --------------------------------------------------------------------------- #
# Published examples
# --------------------------------------------------------------------------- #
def test_vallado_example_2_5_rv2coe():
    """Vallado (2013), Example 2-5: RV2COE."""
    r = np.array([6524.834, 6862.875, 6448.296]) * KM
    v = np.array([4.901327, 5.533756, -1.976341]) * KM
    coe = rv_to_coe(r, v, mu=MU_VALLADO)
    p = coe.a * (1.0 - coe.e**2)
    # Vallado prints p = 11067.790 km and a = 36127.343 km; his hand-carried
    # rounding of intermediate values leaves a few metres (7e-7 relative).
    assert p / KM == pytest.approx(11067.790, abs=1e-2)
    assert coe.a / KM == pytest.approx(36127.343, abs=1e-2)
    assert coe.e == pytest.approx(0.832853, abs=1e-6)
    assert np.degrees(coe.i) == pytest.approx(87.870, abs=1e-3)
    assert np.degrees(coe.raan) == pytest.approx(227.89, abs=1e-2)
    assert np.degrees(coe.argp) == pytest.approx(53.38, abs=1e-2)
    assert np.degrees(coe.nu) == pytest.approx(92.335, abs=1e-3)
    assert argument_of_latitude(r, v) == pytest.approx(coe.argp + coe.nu, abs=1e-12)


def test_vallado_example_2_6_coe2rv():
    """Vallado (2013), Example 2-6: COE2RV, the reverse of Example 2-5."""
    p, e = 11067.790 * KM, 0.83285
    angles = np.radians([87.87, 227.89, 53.38, 92.335])
    r, v = coe_to_rv(p / (1.0 - e * e), e, *angles, mu=MU_VALLADO)
    # printed to 1 m and 1 mm/s
    np.testing.assert_allclose(r / KM, [6525.368, 6861.532, 6449.119], atol=1e-3)
    np.testing.assert_allclose(v / KM, [4.902279, 5.533140, -1.975710], atol=1e-6)


def test_vallado_example_2_1_kepler_equation():
    """Vallado (2013), Example 2-1: M = 235.4 deg, e = 0.4 -> E = 220.512074767522 deg."""
    E = mean_to_eccentric_anomaly(np.radians(235.4), 0.4)
    assert np.degrees(E) == pytest.approx(220.512074767522, abs=1e-9)


def test_period_of_geostationary_radius_is_a_sidereal_day():
    # The geostationary radius 42164.17 km is defined by the sidereal day 86164.09 s.
    assert orbital_period(42164.17 * KM, mu=MU) == pytest.approx(86164.09, abs=0.1)
    assert mean_motion(42164.17 * KM, mu=MU) == pytest.approx(EARTH.omega, rel=1e-6)


# --------------------------------------------------------------------------- #
# Kepler's equation and anomalies
# --------------------------------------------------------------------------- #
def test_kepler_solution_satisfies_equation():
    rng = np.random.default_rng(7)
    e = np.concatenate([[0.0, 0.5, 0.9, 0.99], rng.uniform(0.0, 0.99, 2000)])
    M = rng.uniform(-6.0 * np.pi, 6.0 * np.pi, e.size)
    E = mean_to_eccentric_anomaly(M, e)
    assert np.max(np.abs(E - e * np.sin(E) - M)) < 1e-13


def test_kepler_near_singular_corner():
    # e -> 1, M -> 0 is the hardest corner for Newton's method.
    M = np.array([1e-12, 1e-6, 1e-3, -1e-3, np.pi, -np.pi])
    E = mean_to_eccentric_anomaly(M, 0.99)
    assert np.max(np.abs(E - 0.99 * np.sin(E) - M)) < 1e-13


def test_kepler_one_angle_equals_the_vectorised_solution():
    # One angle takes a float path (the J2 mean-element inversion); arrays the vector one.
    rng = np.random.default_rng(8)
    e = np.concatenate([[0.0, 0.99], rng.uniform(0.0, 0.99, 200)])
    M = np.concatenate([[1e-12, -np.pi], rng.uniform(-6.0 * np.pi, 6.0 * np.pi, 200)])
    one_by_one = np.array([mean_to_eccentric_anomaly(m, x) for m, x in zip(M, e, strict=True)])
    np.testing.assert_allclose(one_by_one, mean_to_eccentric_anomaly(M, e), rtol=0, atol=1e-14)
    assert np.max(np.abs(one_by_one - e * np.sin(one_by_one) - M)) < 1e-13


def test_kepler_rejects_non_elliptic():
    with pytest.raises(ValueError):
        mean_to_eccentric_anomaly(1.0, 1.0)


def test_anomaly_conversions_round_trip_and_keep_revolutions():
    rng = np.random.default_rng(11)
    e = rng.uniform(0.0, 0.99, 500)
    nu = rng.uniform(-10.0, 10.0, 500)
    M = true_to_mean_anomaly(nu, e)
    np.testing.assert_allclose(mean_to_true_anomaly(M, e), nu, atol=1e-11)
    E = true_to_eccentric_anomaly(nu, e)
    np.testing.assert_allclose(eccentric_to_true_anomaly(E, e), nu, atol=1e-12)
    np.testing.assert_allclose(eccentric_to_mean_anomaly(E, e), M, atol=1e-12)
    # half-angle relation tan(nu/2) = sqrt((1+e)/(1-e)) tan(E/2)
    np.testing.assert_allclose(
        np.sin(0.5 * nu) * np.cos(0.5 * E) * np.sqrt(1.0 - e),
        np.cos(0.5 * nu) * np.sin(0.5 * E) * np.sqrt(1.0 + e),
        atol=1e-12,
    )


def test_mean_and_true_argument_of_latitude_round_trip_down_to_zero_eccentricity():
    rng = np.random.default_rng(5)
    e = np.concatenate([[0.0], 10.0 ** rng.uniform(-12, -1, 299)])
    argp = rng.uniform(0, 2 * np.pi, 300)
    u = rng.uniform(0, 2 * np.pi, 300)
    ex, ey = e * np.cos(argp), e * np.sin(argp)
    lam = true_to_mean_argument_of_latitude(u, ex, ey)
    np.testing.assert_allclose(mean_to_true_argument_of_latitude(lam, ex, ey), u, atol=1e-12)
    # equation of the centre: |lambda - u| = |M - nu| <= ~2e
    assert np.all(np.abs(lam - u) <= 2.0 * e * (1.0 + e) + 1e-15)


# --------------------------------------------------------------------------- #
# Random round trips
# --------------------------------------------------------------------------- #
def _random_elliptic_elements(rng, n):
    """A mix of generic, near-circular, near-equatorial and highly eccentric orbits."""
    quarter = n // 4
    a = rng.uniform(6.6e6, 4.5e7, n)
    e = np.concatenate(
        [
            rng.uniform(0.0, 0.7, quarter),
            10.0 ** rng.uniform(-8, -4, quarter),
            rng.uniform(0.0, 0.3, quarter),
            rng.uniform(0.9, 0.99, n - 3 * quarter),
        ]
    )
    i = rng.uniform(0.0, np.pi, n)
    small_i = 10.0 ** rng.uniform(-7, -3, quarter)
    i[2 * quarter : 3 * quarter] = np.where(rng.random(quarter) < 0.7, small_i, np.pi - small_i)
    raan, argp, nu = (rng.uniform(0.0, 2.0 * np.pi, n) for _ in range(3))
    return a, e, i, raan, argp, nu


def test_classical_round_trip_random_orbits():
    rng = np.random.default_rng(2024)
    a, e, i, raan, argp, nu = _random_elliptic_elements(rng, 400)
    r, v = coe_to_rv(a, e, i, raan, argp, nu, mu=MU)
    coe = rv_to_coe(r, v, mu=MU)
    np.testing.assert_allclose(coe.a, a, rtol=1e-10)
    np.testing.assert_allclose(coe.e, e, atol=1e-12)
    np.testing.assert_allclose(coe.i, i, atol=1e-12)
    well_defined = (e > 1e-3) & (np.sin(i) > 1e-3)
    for got, want in ((coe.raan, raan), (coe.argp, argp), (coe.nu, nu)):
        assert np.max(_angle_diff(got, want)[well_defined]) < 1e-9
    r2, v2 = coe_to_rv(coe.a, coe.e, coe.i, coe.raan, coe.argp, coe.nu, mu=MU)
    _assert_same_state(r, v, r2, v2, rtol=1e-10)


def test_hyperbolic_round_trip():
    rng = np.random.default_rng(3)
    n = 100
    e = rng.uniform(1.05, 3.0, n)
    a = -rng.uniform(7e6, 5e7, n)
    nu_max = np.arccos(-1.0 / e)  # asymptote
    nu = rng.uniform(-0.9, 0.9, n) * nu_max
    i, raan, argp = rng.uniform(0.1, 3.0, n), *rng.uniform(0, 2 * np.pi, (2, n))
    r, v = coe_to_rv(a, e, i, raan, argp, nu, mu=MU)
    coe = rv_to_coe(r, v, mu=MU)
    np.testing.assert_allclose(coe.a, a, rtol=1e-10)
    np.testing.assert_allclose(coe.e, e, rtol=1e-10)
    assert np.max(_angle_diff(coe.nu, nu)) < 1e-9
    r2, v2 = coe_to_rv(coe.a, coe.e, coe.i, coe.raan, coe.argp, coe.nu, mu=MU)
    _assert_same_state(r, v, r2, v2, rtol=1e-10)


def test_nonsingular_round_trip_random_orbits():
    rng = np.random.default_rng(99)
    a, e, i, raan, argp, nu = _random_elliptic_elements(rng, 400)
    e[:20] = 0.0
    r, v = coe_to_rv(a, e, i, raan, argp, nu, mu=MU)
    el = rv_to_nonsingular(r, v, mu=MU)
    inclined = np.sin(i) > 1e-3
    np.testing.assert_allclose(el.a, a, rtol=1e-10)
    np.testing.assert_allclose(np.hypot(el.ex, el.ey), e, atol=1e-12)
    # ex, ey and u are well defined for any e as long as the node is
    np.testing.assert_allclose(el.ex[inclined], (e * np.cos(argp))[inclined], atol=1e-11)
    np.testing.assert_allclose(el.ey[inclined], (e * np.sin(argp))[inclined], atol=1e-11)
    assert np.max(_angle_diff(el.u, argp + nu)[inclined]) < 1e-10
    r2, v2 = nonsingular_to_rv(el, mu=MU)
    _assert_same_state(r, v, r2, v2, rtol=1e-10)
    coe = nonsingular_to_classical(el)
    r3, v3 = coe_to_rv(coe.a, coe.e, coe.i, coe.raan, coe.argp, coe.nu, mu=MU)
    _assert_same_state(r, v, r3, v3, rtol=1e-10)


def test_equinoctial_round_trip_random_orbits():
    rng = np.random.default_rng(1985)
    a, e, i, raan, argp, nu = _random_elliptic_elements(rng, 400)
    i = np.minimum(i, np.pi - 0.1)  # the direct set is singular at i = pi only
    i[:10] = 0.0
    e[10:20] = 0.0
    r, v = coe_to_rv(a, e, i, raan, argp, nu, mu=MU)
    eq = rv_to_equinoctial(r, v, mu=MU)
    expected = classical_to_equinoctial(ClassicalElements(a, e, i, raan, argp, nu))
    for name in ("h", "k", "p", "q"):
        np.testing.assert_allclose(getattr(eq, name), getattr(expected, name), atol=1e-11)
    assert np.max(_angle_diff(eq.L, expected.L)) < 1e-10
    r2, v2 = equinoctial_to_rv(eq, mu=MU)
    _assert_same_state(r, v, r2, v2, rtol=1e-10)
    coe = equinoctial_to_classical(eq)
    r3, v3 = coe_to_rv(coe.a, coe.e, coe.i, coe.raan, coe.argp, coe.nu, mu=MU)
    _assert_same_state(r, v, r3, v3, rtol=1e-10)


def test_state_to_elements_to_state_random_states():
    """Start from states (not elements): each set must give the state back."""
    rng = np.random.default_rng(8)
    n = 300
    r = rng.normal(size=(n, 3))
    r *= (rng.uniform(6.6e6, 4e7, n) / np.linalg.norm(r, axis=1))[:, None]
    v = rng.normal(size=(n, 3))
    v_circ = np.sqrt(MU / np.linalg.norm(r, axis=1))
    v *= (rng.uniform(0.5, 1.3, n) * v_circ / np.linalg.norm(v, axis=1))[:, None]
    coe = rv_to_coe(r, v, mu=MU)
    _assert_same_state(r, v, *coe_to_rv(*vars(coe).values(), mu=MU), rtol=1e-10)
    _assert_same_state(r, v, *nonsingular_to_rv(rv_to_nonsingular(r, v, mu=MU), mu=MU), 1e-10)
    _assert_same_state(r, v, *equinoctial_to_rv(rv_to_equinoctial(r, v, mu=MU), mu=MU), 1e-10)


# --------------------------------------------------------------------------- #
# Conventions for the degenerate orbits
# --------------------------------------------------------------------------- #
def test_circular_inclined_orbit_has_zero_argp_and_nu_from_node():
    a, i, raan, u = 7.0e6, 0.9, 1.2, 2.5
    r, v = coe_to_rv(a, 0.0, i, raan, 0.0, u, mu=MU)
    coe = rv_to_coe(r, v, mu=MU)
    assert coe.e < 1e-14
    assert coe.argp == 0.0
    assert coe.nu == pytest.approx(u, abs=1e-12)
    assert coe.raan == pytest.approx(raan, abs=1e-12)


def test_equatorial_elliptic_orbit_has_zero_raan_and_argp_from_x_axis():
    a, e, varpi, nu = 8.0e6, 0.1, 0.7, 1.9
    r, v = coe_to_rv(a, e, 0.0, 0.0, varpi, nu, mu=MU)
    coe = rv_to_coe(r, v, mu=MU)
    assert coe.i == 0.0
    assert coe.raan == 0.0
    assert coe.argp == pytest.approx(varpi, abs=1e-12)
    assert coe.nu == pytest.approx(nu, abs=1e-12)


def test_retrograde_equatorial_orbit_round_trips():
    a, e, argp, nu = 8.0e6, 0.2, 0.7, 1.9
    r, v = coe_to_rv(a, e, np.pi, 0.0, argp, nu, mu=MU)
    coe = rv_to_coe(r, v, mu=MU)
    assert coe.i == pytest.approx(np.pi, abs=1e-15)
    assert coe.raan == 0.0
    assert coe.argp == pytest.approx(argp, abs=1e-12)
    _assert_same_state(r, v, *coe_to_rv(*vars(coe).values(), mu=MU), rtol=1e-12)


def test_circular_equatorial_orbit_gives_true_longitude():
    true_longitude = 4.0
    r = 7.0e6 * np.array([np.cos(true_longitude), np.sin(true_longitude), 0.0])
    v = np.sqrt(MU / 7.0e6) * np.array([-np.sin(true_longitude), np.cos(true_longitude), 0.0])
    coe = rv_to_coe(r, v, mu=MU)
    assert (coe.i, coe.raan, coe.argp) == (0.0, 0.0, 0.0)
    assert coe.nu == pytest.approx(true_longitude, abs=1e-12)
    eq = rv_to_equinoctial(r, v, mu=MU)
    assert eq.L == pytest.approx(true_longitude, abs=1e-12)
    assert abs(eq.h) < 1e-15 and abs(eq.k) < 1e-15 and eq.p == 0.0 and eq.q == 0.0


def test_nonsingular_elements_are_continuous_as_e_goes_to_zero():
    base = dict(a=7.0e6, i=0.9, raan=1.0, u=2.0)
    r0, v0 = nonsingular_to_rv(NonsingularElements(ex=0.0, ey=0.0, **base), mu=MU)
    r1, v1 = nonsingular_to_rv(NonsingularElements(ex=1e-10, ey=-1e-10, **base), mu=MU)
    _assert_same_state(r0, v0, r1, v1, rtol=1e-9)
    el = rv_to_nonsingular(r1, v1, mu=MU)
    assert el.ex == pytest.approx(1e-10, abs=1e-15)
    assert el.ey == pytest.approx(-1e-10, abs=1e-15)
    assert el.u == pytest.approx(2.0, abs=1e-13)


def test_classical_and_nonsingular_containers_agree():
    coe = ClassicalElements(a=7.2e6, e=0.01, i=1.0, raan=0.3, argp=2.0, nu=5.0)
    el = classical_to_nonsingular(coe)
    assert el.ex == pytest.approx(0.01 * np.cos(2.0))
    assert el.u == pytest.approx(np.mod(7.0, 2 * np.pi))
    back = nonsingular_to_classical(el)
    for name in ("a", "e", "i", "raan", "argp", "nu"):
        assert getattr(back, name) == pytest.approx(getattr(coe, name), abs=1e-12)
    eq = classical_to_equinoctial(coe)
    assert isinstance(eq, EquinoctialElements)
    back = equinoctial_to_classical(eq)
    for name in ("a", "e", "i", "raan", "argp", "nu"):
        assert getattr(back, name) == pytest.approx(getattr(coe, name), abs=1e-12)


def test_argument_of_latitude_matches_argp_plus_nu():
    a, e, i, raan, argp, nu = 7.5e6, 0.05, 0.6, 1.0, 2.0, 3.0
    r, v = coe_to_rv(a, e, i, raan, argp, nu, mu=MU)
    assert argument_of_latitude(r, v) == pytest.approx(argp + nu, abs=1e-12)


# --------------------------------------------------------------------------- #
# Shapes
# --------------------------------------------------------------------------- #
def test_vectorised_over_leading_axes_and_scalar_use():
    rng = np.random.default_rng(0)
    shape = (4, 5)
    a = rng.uniform(7e6, 8e6, shape)
    e = rng.uniform(0, 0.1, shape)
    i, raan, argp, nu = rng.uniform(0.1, 3.0, (4, *shape))
    r, v = coe_to_rv(a, e, i, raan, argp, nu, mu=MU)
    assert r.shape == v.shape == (*shape, 3)
    coe = rv_to_coe(r, v, mu=MU)
    assert coe.a.shape == shape
    assert rv_to_nonsingular(r, v, mu=MU).u.shape == shape
    assert rv_to_equinoctial(r, v, mu=MU).L.shape == shape
    scalar = rv_to_coe(r[1, 2], v[1, 2], mu=MU)
    assert isinstance(scalar.a, float) and isinstance(scalar.nu, float)
    assert scalar.a == pytest.approx(a[1, 2], rel=1e-12)
    assert isinstance(mean_to_true_anomaly(1.0, 0.1), float)
    # broadcasting of one orbit against many anomalies
    r_many, _ = coe_to_rv(7e6, 0.01, 1.0, 0.0, 0.0, np.linspace(0, 1, 7), mu=MU)
    assert r_many.shape == (7, 3)
