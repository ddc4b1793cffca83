"""The public numeric kernels of ``ovtraj.astro`` against independent references.

Angle wraps against the IEEE remainder and numpy's complex argument, the eccentricity
vector and the perigee radius against states built from orbital elements with the
perifocal formulas (and astropy's rotation matrices), the great-circle distance against
the spherical law of cosines and a published city pair.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from astropy.coordinates.matrix_utilities import rotation_matrix

from ovtraj.astro.angles import TWO_PI, principal_angle, wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.elements import (
    eccentricity_vector,
    eccentricity_vector_from_dots,
    perigee_radius,
    perigee_radius_from_semi_latus_rectum,
)
from ovtraj.astro.frames import great_circle_distance

MU = 3.986004418e14  # m^3/s^2, EGM-96 / WGS-84

# Random angles over many turns, every multiple of pi up to 9 turns, and the floats next to
# the interval ends.
EDGES = [
    *(k * math.pi for k in range(-18, 19)),
    0.0,
    -0.0,
    1e-17,
    -1e-17,
    math.nextafter(math.pi, 0.0),
    math.nextafter(-math.pi, 0.0),
    math.nextafter(TWO_PI, 0.0),
    math.nextafter(TWO_PI, 10.0),
]
ANGLES = np.concatenate([np.random.default_rng(45).uniform(-60.0, 60.0, 5000), EDGES])


def _angular_difference(a: float, b: float) -> float:
    """|a - b| up to whole turns [rad]."""
    return abs(math.remainder(a - b, TWO_PI))


def test_two_pi_is_a_full_turn():
    assert TWO_PI == 2.0 * math.pi == math.tau


def test_wrap_to_pi_is_the_ieee_remainder_up_to_the_rounding_of_the_shift():
    """Its error is that of ``angle + pi`` (half an ulp of |angle| + pi) and of ``- pi``."""
    for angle in ANGLES.tolist():
        wrapped = wrap_to_pi(angle)
        assert -math.pi <= wrapped <= math.pi
        tolerance = math.ulp(abs(angle) + math.pi) + math.ulp(math.pi)
        assert _angular_difference(wrapped, math.remainder(angle, TWO_PI)) <= tolerance


def test_wrap_to_pi_interval_ends():
    """[-pi, pi): pi and -pi go to -pi; odd multiples of pi (rounded floats, so a hair
    off them) to within rounding of -pi or pi, whole turns to within rounding of 0."""
    for k in range(-9, 10):
        tolerance = math.ulp(abs(2 * k + 1) * math.pi + math.pi) + math.ulp(math.pi)
        assert _angular_difference(wrap_to_pi((2 * k + 1) * math.pi), math.pi) <= tolerance
        assert abs(wrap_to_pi(2 * k * math.pi)) <= tolerance
    assert wrap_to_pi(math.pi) == wrap_to_pi(-math.pi) == -math.pi
    assert wrap_to_pi(0.0) == 0.0
    # The documented rounding at the ends (``angle + pi`` rounds to 2 pi or to -0): the
    # float below pi comes out as -pi, the float below -pi as pi itself.
    assert wrap_to_pi(math.nextafter(math.pi, 0.0)) == -math.pi
    assert wrap_to_pi(math.nextafter(-math.pi, -4.0)) == math.pi


def test_wrap_to_pi_keeps_the_type_of_its_argument():
    assert type(wrap_to_pi(7.0)) is float
    assert type(wrap_to_pi(np.float64(7.0))) is np.float64
    wrapped = wrap_to_pi(ANGLES)
    assert isinstance(wrapped, np.ndarray) and wrapped.shape == ANGLES.shape
    # Elementwise the same bits as the scalar evaluation (numpy's mod is Python's %).
    assert wrapped.tolist() == [wrap_to_pi(a) for a in ANGLES.tolist()]


def test_wrap_to_pi_compiled_by_numba_gives_the_same_bits():
    compiled = numba.njit(wrap_to_pi)
    assert [compiled(a) for a in ANGLES.tolist()] == [wrap_to_pi(a) for a in ANGLES.tolist()]


def test_principal_angle_is_numpys_complex_argument():
    """(-pi, pi], like ``numpy.angle(exp(1j x))``. That reference takes whole turns of the
    real 2 pi (cos and sin reduce exactly), the kernels turns of the float ``TWO_PI``,
    2 sin(pi_float) = 2.4e-16 rad short of it: the two part by that much per turn."""
    turn_shortfall = 2.0 * math.sin(math.pi)  # 2 (pi - math.pi) to first order
    reference = np.angle(np.exp(1j * ANGLES))
    for angle, expected in zip(ANGLES.tolist(), reference.tolist(), strict=True):
        wrapped = principal_angle(angle)
        assert -math.pi < wrapped <= math.pi
        turns = abs(round(angle / TWO_PI))
        tolerance = 4 * math.ulp(math.pi) + turns * turn_shortfall
        assert _angular_difference(wrapped, expected) <= tolerance


def test_principal_angle_interval_ends_and_exactness():
    assert principal_angle(math.pi) == principal_angle(-math.pi) == math.pi
    assert principal_angle(1e-17) == 1e-17  # exact: no shift by pi to round it away
    assert principal_angle(-1e-17) == -1e-17
    assert principal_angle(TWO_PI) == 0.0


def test_wrap_to_two_pi_against_the_ieee_remainder():
    wrapped = wrap_to_two_pi(ANGLES)
    assert np.all((wrapped >= 0.0) & (wrapped < TWO_PI))
    for angle, value in zip(ANGLES.tolist(), wrapped.tolist(), strict=True):
        assert _angular_difference(value, math.remainder(angle, TWO_PI)) <= math.ulp(TWO_PI)


def test_wrap_to_two_pi_interval_ends():
    """[0, 2 pi): 2 pi goes to 0, and so does a tiny negative angle that np.mod rounds up
    to 2 pi."""
    assert np.mod(-1e-17, TWO_PI) == TWO_PI  # the case the kernel exists for
    assert wrap_to_two_pi(-1e-17) == 0.0
    assert wrap_to_two_pi(TWO_PI) == 0.0
    assert wrap_to_two_pi(-math.pi / 2) == 1.5 * math.pi
    assert wrap_to_two_pi(math.nextafter(TWO_PI, 0.0)) == math.nextafter(TWO_PI, 0.0)
    assert math.copysign(1.0, wrap_to_two_pi(-0.0)) == 1.0
    assert math.isnan(wrap_to_two_pi(math.nan))
    assert math.isnan(wrap_to_two_pi(math.inf))


def test_wrap_to_two_pi_is_the_modulo_but_at_the_tiny_negative_angles():
    """The modulo's float for every angle but the negative ones within half an ulp of 0
    (-4.4e-16 < x < 0), where the modulo gives 2 pi and the kernel 0."""
    angles = np.concatenate([ANGLES, [-4e-16, -5e-16, math.nan, -math.inf]])
    with np.errstate(invalid="ignore"):
        wrapped, modulo = wrap_to_two_pi(angles), np.mod(angles, TWO_PI)
    differs = ~((wrapped == modulo) | (np.isnan(wrapped) & np.isnan(modulo)))
    assert angles[differs].tolist() == [-1e-17, -4e-16]
    assert [x % TWO_PI for x in angles[differs].tolist()] == [TWO_PI, TWO_PI]


def test_wrap_to_two_pi_keeps_the_type_of_its_argument():
    assert type(wrap_to_two_pi(7.0)) is float
    assert type(wrap_to_two_pi(np.float64(7.0))) is np.float64
    wrapped = wrap_to_two_pi(ANGLES)
    assert isinstance(wrapped, np.ndarray)
    assert wrapped.shape == ANGLES.shape
    assert wrapped.tolist() == [wrap_to_two_pi(a) for a in ANGLES.tolist()]


def test_wrap_to_two_pi_compiled_by_numba_gives_the_same_bits():
    compiled = numba.njit(wrap_to_two_pi)
    angles = [*ANGLES.tolist(), -4e-16]
    assert [compiled(a) for a in angles] == [wrap_to_two_pi(a) for a in angles]


# --------------------------------------------------------------------------------------------
# Eccentricity vector and perigee radius
# --------------------------------------------------------------------------------------------
def _state_from_elements(a, e, i, raan, argp, nu):
    """Position [m] and velocity [m/s] from classical elements: the perifocal state
    (Curtis, Orbital Mechanics for Engineering Students, 3rd ed., Algorithm 4.5) rotated
    to ECI with astropy's rotation matrices, R3(-raan) R1(-i) R3(-argp); with the
    periapsis direction P (perifocal x axis) in ECI."""
    p = a * (1.0 - e * e)
    r_pf = p / (1.0 + e * math.cos(nu)) * np.array([math.cos(nu), math.sin(nu), 0.0])
    v_pf = math.sqrt(MU / p) * np.array([-math.sin(nu), e + math.cos(nu), 0.0])
    # astropy's rotation_matrix(angle, axis) turns the axes by angle: its transpose turns
    # a vector by +angle, as Q = R3(-raan) R1(-i) R3(-argp) does.
    q = (
        rotation_matrix(math.degrees(raan), "z").T
        @ rotation_matrix(math.degrees(i), "x").T
        @ rotation_matrix(math.degrees(argp), "z").T
    )
    return q @ r_pf, q @ v_pf, q @ np.array([1.0, 0.0, 0.0])


ELEMENTS = [
    # a [m], e, i, raan, argp, nu [rad]
    (6_778_137.0, 0.0012, 0.9006, 1.2, 0.3, 2.0),
    (7_000_000.0, 0.1, 1.7, 5.9, 4.4, -1.0),
    (26_560_000.0, 0.74, 1.1, 0.5, 4.7, 0.01),
    (42_164_000.0, 0.0003, 0.001, 0.2, 1.0, 3.0),
    (-12_000_000.0, 1.6, 0.5, 3.0, 2.0, 0.4),  # hyperbola, nu inside the asymptotes
]


@pytest.mark.parametrize("a, e, i, raan, argp, nu", ELEMENTS)
def test_eccentricity_vector_points_to_periapsis_with_the_eccentricity(a, e, i, raan, argp, nu):
    r, v, periapsis_hat = _state_from_elements(a, e, i, raan, argp, nu)
    ecc = eccentricity_vector(r, v, MU)
    # The terms are of order (|r| v^2 / mu) ~ 1: rounding leaves ~1e-15 absolute.
    np.testing.assert_allclose(ecc, e * periapsis_hat, rtol=0.0, atol=1e-13)


def test_eccentricity_vector_broadcasts_over_states_and_agrees_with_given_dots():
    states = [_state_from_elements(*el) for el in ELEMENTS]
    r = np.array([s[0] for s in states])
    v = np.array([s[1] for s in states])
    batch = eccentricity_vector(r, v, MU)
    assert batch.shape == (len(ELEMENTS), 3)
    for k in range(len(ELEMENTS)):
        assert np.array_equal(batch[k], eccentricity_vector(r[k], v[k], MU))
        # The same formula on BLAS dot products: equal up to the dots' rounding.
        blas = eccentricity_vector_from_dots(
            r[k], v[k], float(np.linalg.norm(r[k])), float(v[k] @ v[k]), float(r[k] @ v[k]), MU
        )
        np.testing.assert_allclose(blas, batch[k], rtol=0.0, atol=1e-14)


@pytest.mark.parametrize("a, e, i, raan, argp, nu", ELEMENTS)
def test_perigee_radius_two_ways_and_from_the_state(a, e, i, raan, argp, nu):
    """a (1 - e) = h^2 / mu / (1 + e), with h, e and a (vis-viva) taken from the state."""
    r, v, _ = _state_from_elements(a, e, i, raan, argp, nu)
    expected = a * (1.0 - e)  # the elements the state was built from
    assert perigee_radius(a, e) == expected
    h_sq = float(np.sum(np.cross(r, v) ** 2))
    e_state = float(np.linalg.norm(eccentricity_vector(r, v, MU)))
    a_state = 1.0 / (2.0 / float(np.linalg.norm(r)) - float(v @ v) / MU)
    rel = 1e-12 if e < 1.0 else 1e-11  # a hyperbola's a (1 - e) cancels a little
    assert perigee_radius(a_state, e_state) == pytest.approx(expected, rel=rel)
    assert perigee_radius_from_semi_latus_rectum(h_sq / MU, e_state) == pytest.approx(
        expected, rel=1e-12
    )


def test_perigee_radius_of_a_parabola_and_of_arrays():
    assert perigee_radius_from_semi_latus_rectum(8.0e6, 1.0) == 4.0e6  # p / 2
    a = np.array([7.0e6, 8.0e6])
    e = np.array([0.0, 0.5])
    np.testing.assert_array_equal(perigee_radius(a, e), [7.0e6, 4.0e6])
    np.testing.assert_array_equal(
        perigee_radius_from_semi_latus_rectum(a * (1.0 - e * e), e), [7.0e6, 4.0e6]
    )


# --------------------------------------------------------------------------------------------
# Great-circle distance
# --------------------------------------------------------------------------------------------
def test_great_circle_distance_of_a_published_city_pair():
    """LAX (33 deg 57' N, 118 deg 24' W) to JFK (40 deg 38' N, 73 deg 47' W): 0.623585 rad,
    2144 nmi (E. Williams, Aviation Formulary, the worked haversine example)."""
    lax = math.radians(33 + 57 / 60), math.radians(-(118 + 24 / 60))
    jfk = math.radians(40 + 38 / 60), math.radians(-(73 + 47 / 60))
    angle = great_circle_distance(*lax, *jfk, radius=1.0)
    assert angle == pytest.approx(0.623585, abs=1e-6)
    assert great_circle_distance(*lax, *jfk, radius=1852.0 * 180 * 60 / math.pi) == (
        pytest.approx(2144.0 * 1852.0, abs=0.5 * 1852.0)
    )


def test_great_circle_distance_against_the_spherical_law_of_cosines():
    rng = np.random.default_rng(4)
    lat1, lat2 = rng.uniform(-1.5, 1.5, (2, 2000))
    lon1, lon2 = rng.uniform(-math.pi, math.pi, (2, 2000))
    cos_angle = np.sin(lat1) * np.sin(lat2) + np.cos(lat1) * np.cos(lat2) * np.cos(lon2 - lon1)
    angle = np.arccos(np.clip(cos_angle, -1.0, 1.0))
    # acos loses digits near 0 and pi (where the haversine does not): compare elsewhere.
    keep = (angle > 1e-3) & (angle < math.pi - 1e-3)
    radius = 6_371_008.8
    distance = great_circle_distance(lat1, lon1, lat2, lon2, radius=radius)
    np.testing.assert_allclose(distance[keep], radius * angle[keep], rtol=1e-9)
    scalar = [
        great_circle_distance(*map(float, p), radius=radius)
        for p in zip(lat1[:200], lon1[:200], lat2[:200], lon2[:200], strict=True)
    ]
    np.testing.assert_allclose(scalar, distance[:200], rtol=1e-14)


def test_great_circle_distance_quarter_meridian_and_antipodes():
    assert great_circle_distance(0.0, 0.3, math.pi / 2, 2.0, radius=2.0) == pytest.approx(math.pi)
    assert great_circle_distance(0.4, 0.0, -0.4, math.pi, radius=1.0) == pytest.approx(math.pi)
    assert great_circle_distance(0.4, 1.0, 0.4, 1.0, radius=1.0) == 0.0
