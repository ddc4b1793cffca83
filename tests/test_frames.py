"""Frame transformations and local geometry against closed forms and published values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ovtraj.astro.frames import (
    ecef_to_eci,
    ecef_to_eci_state,
    ecef_to_geocentric,
    eci_to_ecef,
    eci_to_ecef_state,
    eci_to_rsw,
    flight_path_angle,
    geocentric_to_ecef,
    great_circle_distance,
    heading,
    local_north_east_up,
    relative_velocity_state,
    rsw_basis,
    rsw_to_eci,
)
from ovtraj.config.physical import default_earth

EARTH = default_earth()
RNG = np.random.default_rng(20260301)


def _random_states(n: int) -> tuple[np.ndarray, np.ndarray]:
    r = RNG.normal(size=(n, 3)) * 7.0e6
    v = RNG.normal(size=(n, 3)) * 7.5e3
    return r, v


def _rot3(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def _perifocal_state(
    a: float, e: float, nu: np.ndarray, mu: float
) -> tuple[np.ndarray, np.ndarray]:
    """Keplerian state in perifocal axes (Curtis eqs. 4.45-4.46), tilted to be generic."""
    p = a * (1.0 - e**2)
    radius = p / (1.0 + e * np.cos(nu))
    r = np.stack([radius * np.cos(nu), radius * np.sin(nu), np.zeros_like(nu)], axis=-1)
    speed_scale = math.sqrt(mu / p)
    v = np.stack([-speed_scale * np.sin(nu), speed_scale * (e + np.cos(nu)), np.zeros_like(nu)], -1)
    tilt = _rot3(0.7) @ np.array(
        [[1, 0, 0], [0, math.cos(0.9), math.sin(0.9)], [0, -math.sin(0.9), math.cos(0.9)]]
    )
    return r @ tilt, v @ tilt


# ------------------------------------------------------------------ ECI/ECEF


def test_eci_ecef_round_trip_with_array_of_angles() -> None:
    r, _ = _random_states(50)
    theta = RNG.uniform(-10.0, 10.0, size=50)
    np.testing.assert_allclose(ecef_to_eci(eci_to_ecef(r, theta), theta), r, rtol=0, atol=1e-8)
    # Scalar angle and single vector; rotation by +90 deg takes ECI x onto ECEF -y.
    np.testing.assert_allclose(
        eci_to_ecef([1.0, 0.0, 0.0], math.pi / 2), [0.0, -1.0, 0.0], atol=1e-15
    )


def test_eci_to_ecef_matches_rot3_matrix_and_broadcasts() -> None:
    vec = np.array([1.0, 2.0, 3.0])
    thetas = np.array([0.1, 1.2, -2.5])
    out = eci_to_ecef(vec, thetas)
    assert out.shape == (3, 3)
    for row, theta in zip(out, thetas, strict=True):
        np.testing.assert_allclose(row, _rot3(theta) @ vec, atol=1e-15)


def test_state_round_trip() -> None:
    r, v = _random_states(20)
    theta = RNG.uniform(0, 2 * np.pi, size=20)
    r_f, v_f = eci_to_ecef_state(r, v, theta, omega=EARTH.omega)
    r_back, v_back = ecef_to_eci_state(r_f, v_f, theta, omega=EARTH.omega)
    np.testing.assert_allclose(r_back, r, rtol=0, atol=1e-8)
    np.testing.assert_allclose(v_back, v, rtol=0, atol=1e-11)


def test_ecef_velocity_is_derivative_of_rotated_position() -> None:
    # Straight-line inertial motion seen from the rotating Earth; central difference.
    omega, theta0 = EARTH.omega, 1.3
    r0 = np.array([6.9e6, -1.2e6, 2.1e6])
    v = np.array([-1.5e3, 7.1e3, 1.9e3])

    def r_ecef(t: float) -> np.ndarray:
        return eci_to_ecef(r0 + v * t, theta0 + omega * t)

    dt = 0.05  # truncation ~ omega^2 v dt^2 ~ 1e-7 m/s, round-off ~ 1e-8 m/s
    finite_difference = (r_ecef(dt) - r_ecef(-dt)) / (2 * dt)
    _, v_ecef = eci_to_ecef_state(r0, v, theta0, omega=omega)
    np.testing.assert_allclose(v_ecef, finite_difference, rtol=0, atol=1e-6)


def test_point_fixed_on_earth_has_zero_ecef_velocity() -> None:
    omega = EARTH.omega
    r_ecef = geocentric_to_ecef(math.radians(28.6), math.radians(-80.7), 3.0, radius=EARTH.radius)
    theta = 4.2
    r_eci, v_eci = ecef_to_eci_state(r_ecef, np.zeros(3), theta, omega=omega)
    # The inertial velocity of a ground point is omega x r: eastward, omega * rho.
    rho = math.hypot(r_ecef[0], r_ecef[1])
    assert np.linalg.norm(v_eci) == pytest.approx(omega * rho, rel=1e-12)
    assert heading(r_eci, v_eci) == pytest.approx(math.pi / 2, abs=1e-12)
    _, v_back = eci_to_ecef_state(r_eci, v_eci, theta, omega=omega)
    np.testing.assert_allclose(v_back, 0.0, atol=1e-12)
    np.testing.assert_allclose(relative_velocity_state(r_eci, v_eci, omega=omega), 0.0, atol=1e-12)


# ---------------------------------------------------------------- geocentric


def test_geocentric_round_trip_and_conventions() -> None:
    lat = RNG.uniform(-np.pi / 2, np.pi / 2, size=100)
    lon = RNG.uniform(-np.pi, np.pi, size=100)
    alt = RNG.uniform(-1e3, 1e6, size=100)
    r = geocentric_to_ecef(lat, lon, alt, radius=EARTH.radius)
    assert r.shape == (100, 3)
    lat_b, lon_b, alt_b = ecef_to_geocentric(r, radius=EARTH.radius)
    np.testing.assert_allclose(lat_b, lat, atol=1e-12)
    np.testing.assert_allclose(lon_b, lon, atol=1e-12)
    np.testing.assert_allclose(alt_b, alt, atol=1e-6)
    # Spherical Earth: altitude is |r| - R and latitude is asin(z / |r|).
    np.testing.assert_allclose(alt_b, np.linalg.norm(r, axis=-1) - EARTH.radius, atol=1e-6)
    np.testing.assert_allclose(lat_b, np.arcsin(r[:, 2] / np.linalg.norm(r, axis=-1)), atol=1e-8)


def test_longitude_is_in_half_open_interval() -> None:
    _, lon, _ = ecef_to_geocentric([-7e6, -0.0, 0.0], radius=EARTH.radius)
    assert lon == math.pi
    lat, _, alt = ecef_to_geocentric([0.0, 0.0, 7e6], radius=EARTH.radius)
    assert lat == pytest.approx(math.pi / 2) and alt == pytest.approx(7e6 - EARTH.radius)


# --------------------------------------------------------------------- RSW


def test_rsw_basis_is_orthonormal_and_right_handed() -> None:
    r, v = _random_states(30)
    basis = rsw_basis(r, v)
    assert basis.shape == (30, 3, 3)
    np.testing.assert_allclose(
        basis @ np.swapaxes(basis, -1, -2), np.broadcast_to(np.eye(3), (30, 3, 3)), atol=1e-14
    )
    np.testing.assert_allclose(np.linalg.det(basis), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", basis, r)[:, 1:], 0.0, atol=1e-7)
    # W is along the angular momentum; the velocity has no W component.
    np.testing.assert_allclose(eci_to_rsw(v, r, v)[:, 2], 0.0, atol=1e-10)


def test_circular_orbit_velocity_is_purely_along_track() -> None:
    nu = np.linspace(0, 2 * np.pi, 13)
    r, v = _perifocal_state(EARTH.radius + 420e3, 0.0, nu, EARTH.mu)
    speed = math.sqrt(EARTH.mu / (EARTH.radius + 420e3))
    v_rsw = eci_to_rsw(v, r, v)
    np.testing.assert_allclose(v_rsw[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(v_rsw[:, 1], speed, rtol=1e-13)
    np.testing.assert_allclose(v_rsw[:, 2], 0.0, atol=1e-9)


def test_rsw_round_trip_and_degenerate_case() -> None:
    r, v = _random_states(10)
    vec = RNG.normal(size=(10, 3))
    np.testing.assert_allclose(rsw_to_eci(eci_to_rsw(vec, r, v), r, v), vec, atol=1e-14)
    with pytest.raises(ValueError, match="r x v"):
        rsw_basis([7e6, 0, 0], [100.0, 0, 0])


def test_rsw_basis_of_one_state_equals_the_broadcast_path() -> None:
    # One state takes a scalar path (the deorbit's shots); a batch the array one.
    r, v = _random_states(20)
    batch = rsw_basis(r, v)
    for k in range(20):
        np.testing.assert_allclose(rsw_basis(r[k], v[k]), batch[k], rtol=0.0, atol=1e-15)


# ------------------------------------------------------- flight-path angle


def test_flight_path_angle_of_circular_orbit_is_zero() -> None:
    r, v = _perifocal_state(7.0e6, 0.0, np.linspace(0, 2 * np.pi, 9), EARTH.mu)
    np.testing.assert_allclose(flight_path_angle(r, v), 0.0, atol=1e-15)


def test_flight_path_angle_of_ellipse_matches_closed_form() -> None:
    # tan(gamma) = e sin(nu) / (1 + e cos(nu)) (Vallado eq. 2-98; Curtis sec. 2.5).
    e = 0.3
    nu = np.linspace(-np.pi, np.pi, 37)
    r, v = _perifocal_state(9.0e6, e, nu, EARTH.mu)
    gamma = flight_path_angle(r, v)
    np.testing.assert_allclose(gamma, np.arctan(e * np.sin(nu) / (1 + e * np.cos(nu))), atol=1e-14)
    apsides = flight_path_angle(*_perifocal_state(9.0e6, e, np.array([0.0, np.pi]), EARTH.mu))
    np.testing.assert_allclose(apsides, 0.0, atol=1e-15)
    assert np.all(gamma[(nu > 0) & (nu < np.pi)] > 0)  # climbing from perigee to apogee


def test_flight_path_angle_scalar_input() -> None:
    assert flight_path_angle([7e6, 0, 0], [1e3, 1e3, 0]) == pytest.approx(math.pi / 4)
    e, nu = 0.3, np.linspace(-np.pi, np.pi, 37)
    r, v = _perifocal_state(9.0e6, e, nu, EARTH.mu)
    one_by_one = [flight_path_angle(r[k], v[k]) for k in range(len(nu))]
    assert all(isinstance(gamma, float) for gamma in one_by_one)
    np.testing.assert_allclose(one_by_one, flight_path_angle(r, v), rtol=0.0, atol=1e-15)


# ---------------------------------------------------------------- heading


def test_heading_cardinal_directions_at_equator() -> None:
    r = [EARTH.radius, 0.0, 0.0]
    assert heading(r, [0.0, 7e3, 0.0]) == pytest.approx(math.pi / 2)  # due east
    assert heading(r, [0.0, 0.0, 7e3]) == 0.0  # due north
    assert heading(r, [0.0, 0.0, -7e3]) == pytest.approx(math.pi)  # due south
    assert heading(r, [0.0, -7e3, 0.0]) == pytest.approx(3 * math.pi / 2)  # due west
    # A vertical component does not change the heading.
    assert heading(r, [500.0, 7e3, 0.0]) == pytest.approx(math.pi / 2)


def test_heading_recovers_azimuth_anywhere() -> None:
    lat = RNG.uniform(-1.4, 1.4, size=40)
    lon = RNG.uniform(-np.pi, np.pi, size=40)
    psi = RNG.uniform(0, 2 * np.pi, size=40)
    north, east, up = np.moveaxis(local_north_east_up(lat, lon), -2, 0)
    r = geocentric_to_ecef(lat, lon, 120e3, radius=EARTH.radius)
    v = 7e3 * (np.cos(psi)[:, None] * north + np.sin(psi)[:, None] * east) + 50.0 * up
    result = heading(r, v)
    assert np.all((result >= 0) & (result < 2 * np.pi))
    np.testing.assert_allclose(np.angle(np.exp(1j * (result - psi))), 0.0, atol=1e-12)


def test_heading_of_a_prograde_orbit_equals_launch_azimuth_relation() -> None:
    # Spherical trigonometry: cos(i) = cos(lat) sin(psi); at the ascending node psi = 90 deg - i.
    incl = math.radians(51.6)
    r = np.array([EARTH.radius + 420e3, 0.0, 0.0])
    v = 7.66e3 * np.array([0.0, math.cos(incl), math.sin(incl)])
    assert heading(r, v) == pytest.approx(math.pi / 2 - incl)


# ------------------------------------------------------ north / east / up


def test_local_north_east_up_basis() -> None:
    basis = local_north_east_up(np.array([0.0, 0.5]), np.array([0.0, -2.0]))
    assert basis.shape == (2, 3, 3)
    np.testing.assert_allclose(
        basis @ np.swapaxes(basis, -1, -2), np.broadcast_to(np.eye(3), (2, 3, 3)), atol=1e-15
    )
    np.testing.assert_allclose(np.linalg.det(basis), -1.0, atol=1e-15)  # (N, E, U) is left-handed
    np.testing.assert_allclose(basis[0], [[0, 0, 1], [0, 1, 0], [1, 0, 0]], atol=1e-15)
    up = geocentric_to_ecef(0.5, -2.0, 0.0, radius=1.0)
    np.testing.assert_allclose(basis[1, 2], up, atol=1e-15)


# -------------------------------------------------------- great circles


def test_quarter_meridian_is_quarter_circumference() -> None:
    d = great_circle_distance(0.0, 0.3, math.pi / 2, 0.3, radius=EARTH.radius)
    assert d == pytest.approx(math.pi / 2 * EARTH.radius, rel=1e-14)
    antipode = great_circle_distance(0.2, 0.1, -0.2, 0.1 + math.pi, radius=EARTH.radius)
    assert antipode == pytest.approx(math.pi * EARTH.radius, rel=1e-12)
    assert great_circle_distance(0.4, 1.0, 0.4, 1.0, radius=EARTH.radius) == 0.0


def test_published_city_pairs() -> None:
    # Ed Williams, Aviation Formulary: LAX (33d57'N, 118d24'W) to JFK (40d38'N, 73d47'W)
    # is 0.623585 rad on the sphere, i.e. 2144 nm with 1 nm = 1 arc minute.
    lax = (math.radians(33 + 57 / 60), math.radians(-(118 + 24 / 60)))
    jfk = (math.radians(40 + 38 / 60), math.radians(-(73 + 47 / 60)))
    assert great_circle_distance(*lax, *jfk, radius=1.0) == pytest.approx(0.623585, abs=1e-6)
    nm_radius = 180 * 60 / math.pi
    assert round(great_circle_distance(*lax, *jfk, radius=nm_radius)) == 2144
    # Wikipedia "Haversine formula": Nashville BNA (36.12 N, 86.67 W) to LAX (33.94 N,
    # 118.40 W) is about 2886.44 km on a sphere of radius 6371 km.
    bna_lax = great_circle_distance(
        math.radians(36.12),
        math.radians(-86.67),
        math.radians(33.94),
        math.radians(-118.40),
        radius=6371e3,
    )
    assert bna_lax == pytest.approx(2886.44e3, abs=10.0)


def test_great_circle_distance_is_vectorised_and_symmetric() -> None:
    lat1, lon1, lat2, lon2 = RNG.uniform(-1.5, 1.5, size=(4, 25))
    d12 = great_circle_distance(lat1, lon1, lat2, lon2, radius=EARTH.radius)
    d21 = great_circle_distance(lat2, lon2, lat1, lon1, radius=EARTH.radius)
    assert d12.shape == (25,)
    np.testing.assert_allclose(d12, d21, rtol=1e-13)
    # Cross-check with the angle between the position vectors.
    u1 = geocentric_to_ecef(lat1, lon1, 0.0, radius=1.0)
    u2 = geocentric_to_ecef(lat2, lon2, 0.0, radius=1.0)
    chord_angle = np.arctan2(np.linalg.norm(np.cross(u1, u2), axis=-1), np.sum(u1 * u2, axis=-1))
    np.testing.assert_allclose(d12, EARTH.radius * chord_angle, rtol=1e-10)


def test_fast_cross_matches_numpy_cross_with_broadcasting():
    from ovtraj.astro.vectors import cross

    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(4, 3)), rng.normal(size=3)
    np.testing.assert_allclose(cross(a, b), np.cross(a, b), rtol=0, atol=1e-15)
    np.testing.assert_allclose(cross(a[0], b), np.cross(a[0], b), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(cross([1, 0, 0], [0, 1, 0]), [0.0, 0.0, 1.0])


def test_single_vector_paths_equal_the_broadcasting_paths() -> None:
    """One vector or four numbers take a scalar path; it must give the array path's values."""
    vectors = RNG.normal(size=(50, 3)) * 7.0e6
    angles = RNG.uniform(-10.0, 10.0, size=50)
    rotated = eci_to_ecef(vectors, angles)
    lat, lon, alt = ecef_to_geocentric(vectors, radius=EARTH.radius)
    for k in range(50):
        np.testing.assert_allclose(eci_to_ecef(vectors[k], angles[k]), rotated[k], rtol=1e-15)
        one = ecef_to_geocentric(vectors[k], radius=EARTH.radius)
        assert all(isinstance(value, float) for value in one)
        np.testing.assert_allclose(one, (lat[k], lon[k], alt[k]), rtol=1e-14, atol=1e-7)
    # The half-open longitude convention holds on both paths (atan2(-0.0, -1) = -pi).
    assert ecef_to_geocentric(np.array([-1.0, -0.0, 0.0]), radius=1.0)[1] == math.pi
    points = RNG.uniform(-1.5, 1.5, size=(50, 4))
    distances = great_circle_distance(*points.T, radius=EARTH.radius)
    for k in range(50):
        one = great_circle_distance(*(float(v) for v in points[k]), radius=EARTH.radius)
        assert one == pytest.approx(distances[k], rel=1e-13, abs=1e-6)
    # Antipodes: the haversine clipped at 1 on the scalar path too.
    assert great_circle_distance(0.0, 0.0, 0.0, math.pi, radius=1.0) == pytest.approx(math.pi)
