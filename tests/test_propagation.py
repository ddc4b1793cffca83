"""The compiled propagator against independent references.

Closed forms (Kepler, conic geometry, uniform circular motion), conservation
laws, the analytic J2 secular rates, a second integrator (DOP853) on a J2 field written
apart (the potential's gradient in spherical coordinates, checked here against the
Cartesian formula the propagator flies), and brute-force scans for the events (the scans
live here, not in the library).
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from ovtraj.astro.elements import (
    coe_to_rv,
    mean_motion,
    mean_to_true_anomaly,
    rv_to_coe,
    true_to_mean_anomaly,
)
from ovtraj.astro.j2_elements import secular_rates, state_to_mean
from ovtraj.astro.propagation import (
    AltitudeCrossing,
    ArgumentOfLatitudeCrossing,
    LatitudeCrossing,
    LongitudeCrossing,
    OrbitPropagator,
)
from ovtraj.astro.propagation.gravity import two_body_j2_acceleration
from ovtraj.astro.propagation.reference import propagate_dop853, zonal_j2_acceleration
from ovtraj.astro.propagation.taylor import _event_integrator

DAY = 86400.0
TOL = 1e-12  # the default scenario's integrator tolerance
# The two J2 formulas differ by rounding alone: a few ulp (2.2e-16 each) of the size of
# their terms; measured 7.5e-16 (Earth's J2) and 7.7e-16 (J2 = 0.5), poles included.
ACCELERATION_AGREEMENT = 1.5e-15


def _state(earth, a, e, i_deg, raan_deg=40.0, argp_deg=30.0, nu_deg=10.0):
    r, v = coe_to_rv(
        a,
        e,
        math.radians(i_deg),
        math.radians(raan_deg),
        math.radians(argp_deg),
        math.radians(nu_deg),
        mu=earth.mu,
    )
    return np.r_[r, v]


@pytest.fixture(scope="module")
def two_body(earth):
    return OrbitPropagator(earth, tol=TOL, j2=False)


@pytest.fixture(scope="module")
def j2(earth):
    return OrbitPropagator(earth, tol=TOL)


def test_two_body_conserves_energy_and_angular_momentum_over_10_days(earth, two_body):
    s0 = _state(earth, 7000e3, 0.05, 51.6)
    result = two_body.propagate(s0, 0.0, 10 * DAY, dense=True)
    states = result.dense(np.linspace(0.0, 10 * DAY, 2001))
    r = np.linalg.norm(states[:, :3], axis=1)
    energy = 0.5 * np.sum(states[:, 3:] ** 2, axis=1) - earth.mu / r
    h = np.cross(states[:, :3], states[:, 3:])
    assert np.max(np.abs(energy / energy[0] - 1.0)) < 1e-10
    assert np.max(np.linalg.norm(h - h[0], axis=1)) / np.linalg.norm(h[0]) < 1e-10


def test_two_body_matches_kepler_closed_form(earth, two_body):
    a, e = 7200e3, 0.1
    s0 = _state(earth, a, e, 28.5, nu_deg=0.0)
    n = mean_motion(a, mu=earth.mu)
    t = 10 * DAY
    nu = mean_to_true_anomaly(math.fmod(n * t, 2 * math.pi), e)
    expected = _state(earth, a, e, 28.5, nu_deg=math.degrees(nu))
    final = two_body.propagate(s0, 0.0, t).state
    # ~140 revolutions at tolerance 1e-12: 9 cm measured, 7e-8 of the radius allowed.
    assert np.linalg.norm(final[:3] - expected[:3]) < 0.5


def _random_positions(rng, n: int, earth) -> np.ndarray:
    """Positions [m] from 100 km altitude to beyond GEO, in every direction, a tenth of
    them within 1e-3..1e-12 rad of a pole (where the latitude is ill conditioned)."""
    directions = rng.normal(size=(n, 3))
    polar = rng.random(n) < 0.1
    tilt = 10.0 ** rng.uniform(-12.0, -3.0, size=(polar.sum(), 1))
    directions[polar, :2] = tilt * rng.normal(size=(polar.sum(), 2))
    directions[polar, 2] = rng.choice([-1.0, 1.0], size=polar.sum())
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return directions * rng.uniform(earth.radius + 100e3, 50_000e3, size=(n, 1))


@pytest.mark.parametrize("j2_value", ["earth", 0.5])
def test_reference_j2_field_is_the_propagators_to_rounding(earth, j2_value):
    """The DOP853 reference's acceleration (the potential's gradient in spherical
    coordinates) equals the propagator's Cartesian formula (Vallado eq. 8-30) to rounding,
    relative to the size of the terms. With J2 = 0.5 the zonal term is as large as the
    central one near the surface, so the zonal term too is held to rounding (with the
    Earth's J2 it is 1e-3 of the total)."""
    rng = np.random.default_rng(84)
    j2_coefficient = earth.j2 if j2_value == "earth" else j2_value
    worst = 0.0
    for position in _random_positions(rng, 2000, earth):
        ours = np.array(two_body_j2_acceleration(*position, earth.mu, earth.radius, j2_coefficient))
        ref = zonal_j2_acceleration(position, mu=earth.mu, radius=earth.radius, j2=j2_coefficient)
        r = float(np.linalg.norm(position))
        # The size of the terms: with a large J2 the two can cancel in the sum.
        scale = earth.mu / r**2 * (1.0 + 3.0 * j2_coefficient * (earth.radius / r) ** 2)
        worst = max(worst, float(np.linalg.norm(ref - ours)) / scale)
    print(f"J2 {j2_coefficient:g}: worst relative difference {worst:.2e}")
    assert worst < ACCELERATION_AGREEMENT
    # The check has power: J2 off by one part in 1e9 is seen.
    position = np.array([earth.radius + 400e3, 0.0, 3000e3])
    ours = np.array(two_body_j2_acceleration(*position, earth.mu, earth.radius, earth.j2))
    off = zonal_j2_acceleration(
        position, mu=earth.mu, radius=earth.radius, j2=earth.j2 * 1.000000001
    )
    assert np.linalg.norm(off - ours) / np.linalg.norm(ours) > 100 * ACCELERATION_AGREEMENT


def test_j2_agrees_with_dop853_over_a_day(earth, j2):
    s0 = _state(earth, earth.radius + 400e3, 0.001, 51.6)
    ours = j2.propagate(s0, 0.0, DAY).state
    ref = propagate_dop853(
        s0, 0.0, DAY, mu=earth.mu, radius=earth.radius, j2=earth.j2, rtol=1e-13, atol=1e-7
    )
    assert np.linalg.norm(ours[:3] - ref[:3]) < 0.01


@pytest.mark.parametrize(("a_km", "e", "i_deg"), [(7000.0, 0.05, 28.5), (6900.0, 0.02, 51.6)])
def test_j2_secular_rates_over_10_days(earth, j2, a_km, e, i_deg):
    s0 = _state(earth, a_km * 1e3, e, i_deg)
    times = np.linspace(0.0, 10 * DAY, 4001)
    states = j2.propagate_grid(s0, 0.0, times)
    coe = rv_to_coe(states[:, :3], states[:, 3:], mu=earth.mu)
    raan = np.unwrap(np.asarray(coe.raan))
    argp = np.unwrap(np.asarray(coe.argp))
    mean = state_to_mean(s0[:3], s0[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
    e_mean = math.hypot(float(mean.ex), float(mean.ey))
    raan_dot, argp_dot, _ = secular_rates(
        float(mean.a), e_mean, float(mean.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    fitted_raan_dot = np.polyfit(times, raan, 1)[0]
    fitted_argp_dot = np.polyfit(times, argp, 1)[0]
    assert fitted_raan_dot == pytest.approx(raan_dot, rel=0.01)
    assert fitted_argp_dot == pytest.approx(argp_dot, rel=0.01)


def test_altitude_event_matches_conic_geometry(earth, two_body):
    a, e = 7000e3, 0.05
    s0 = _state(earth, a, e, 40.0, nu_deg=0.0)
    h = 600e3
    result = two_body.propagate(s0, 0.0, DAY, events=[AltitudeCrossing(h, crossing="ascending")])
    # r = p / (1 + e cos nu), rising branch nu in (0, pi); time from Kepler's equation.
    p = a * (1 - e * e)
    nu = math.acos((p / (earth.radius + h) - 1.0) / e)
    t_expected = true_to_mean_anomaly(nu, e) / mean_motion(a, mu=earth.mu)
    assert result.status == "terminal_event" and result.terminal_event == 0
    assert result.t == pytest.approx(t_expected, abs=1e-6)
    assert np.linalg.norm(result.state[:3]) - earth.radius == pytest.approx(h, abs=1e-5)


def test_descending_altitude_event(earth, two_body):
    a, e = 7000e3, 0.05
    s0 = _state(earth, a, e, 40.0, nu_deg=0.0)
    h = 600e3
    result = two_body.propagate(s0, 0.0, DAY, events=[AltitudeCrossing(h)])
    p = a * (1 - e * e)
    nu = 2 * math.pi - math.acos((p / (earth.radius + h) - 1.0) / e)
    t_expected = true_to_mean_anomaly(nu, e) / mean_motion(a, mu=earth.mu)
    assert result.t == pytest.approx(t_expected, abs=1e-6)


def test_argument_of_latitude_event_on_circular_orbit(earth, two_body):
    a = earth.radius + 500e3
    s0 = _state(earth, a, 0.0, 63.0, argp_deg=0.0, nu_deg=20.0)
    n = mean_motion(a, mu=earth.mu)
    for u_target_deg in (90.0, 200.0, 15.0):
        result = two_body.propagate(
            s0, 0.0, DAY, events=[ArgumentOfLatitudeCrossing(math.radians(u_target_deg))]
        )
        du = math.radians((u_target_deg - 20.0) % 360.0)
        assert result.t == pytest.approx(du / n, abs=1e-6)


def test_event_at_the_start_point_is_not_a_crossing(earth, two_body):
    a = earth.radius + 500e3
    s0 = _state(earth, a, 0.0, 63.0, argp_deg=0.0, nu_deg=20.0)
    result = two_body.propagate(
        s0, 0.0, DAY, events=[ArgumentOfLatitudeCrossing(math.radians(20.0))]
    )
    period = 2 * math.pi / mean_motion(a, mu=earth.mu)
    assert result.t == pytest.approx(period, abs=1e-6)


def _scan_crossings(times, values):
    """Brute-force: linear interpolation of sign changes on a fine grid."""
    s = np.sign(values)
    idx = np.nonzero(s[:-1] * s[1:] < 0)[0]
    return times[idx] - values[idx] * (times[idx + 1] - times[idx]) / (
        values[idx + 1] - values[idx]
    )


def test_ground_track_events_agree_with_a_fine_scan(earth):
    theta0 = 1.234  # Earth rotation angle at t = 0
    prop = OrbitPropagator(earth, tol=TOL, earth_angle0_rad=theta0)
    s0 = _state(earth, earth.radius + 420e3, 0.0005, 51.64)
    lat0, lon0 = math.radians(28.6), math.radians(-80.7)
    events = [LatitudeCrossing(lat0), LongitudeCrossing(lon0)]
    result = prop.propagate(s0, 0.0, DAY, events=events, dense=True)
    times = np.arange(0.0, DAY, 1.0)
    states = result.dense(times)
    r = np.linalg.norm(states[:, :3], axis=1)
    lat = np.arcsin(states[:, 2] / r)
    lon = np.arctan2(states[:, 1], states[:, 0]) - (theta0 + earth.omega * times)
    dlon = np.angle(np.exp(1j * (lon - lon0)))
    lat_scan = _scan_crossings(times, lat - lat0)
    # Longitude crossings: where the wrapped difference changes sign near zero (not at +-pi).
    cos_dlon = np.cos(lon - lon0)
    lon_scan = [t for t in _scan_crossings(times, dlon) if np.interp(t, times, cos_dlon) > 0]
    lat_hits = [h.t for h in result.hits if h.event_index == 0]
    lon_hits = [h.t for h in result.hits if h.event_index == 1]
    assert len(lat_hits) == len(lat_scan) > 20
    assert len(lon_hits) == len(lon_scan) > 10
    assert np.max(np.abs(np.array(lat_hits) - lat_scan)) < 0.05
    assert np.max(np.abs(np.array(lon_hits) - lon_scan)) < 0.05
    for hit in result.hits:
        st = hit.state
        if hit.event_index == 0:
            assert math.asin(st[2] / np.linalg.norm(st[:3])) == pytest.approx(lat0, abs=1e-9)
        else:
            lon_hit = math.atan2(st[1], st[0]) - (theta0 + earth.omega * hit.t)
            assert math.remainder(lon_hit - lon0, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_dense_output_matches_a_direct_propagation(earth, j2):
    s0 = _state(earth, earth.radius + 400e3, 0.001, 51.6)
    result = j2.propagate(s0, 0.0, 20000.0, dense=True)
    for t in (1234.5, 9876.0, 20000.0):
        direct = j2.propagate(s0, 0.0, t).state
        assert np.linalg.norm(result.dense(t)[:3] - direct[:3]) < 1e-4
    # Two lookups must not share memory (heyoka reuses an internal buffer).
    a, b = result.state_at(100.0), result.state_at(5000.0)
    assert np.linalg.norm(a[:3] - b[:3]) > 1e5
    # Several lookups in one call: each equals its own lookup, clipped the same way.
    times = np.array([-50.0, 0.0, 1234.5, 9876.0, 20000.0, 20050.0])
    np.testing.assert_array_equal(
        result.states_at(times), np.array([result.state_at(t) for t in times])
    )


def test_batch_propagation_equals_single_propagations(earth, j2):
    rng = np.random.default_rng(7)
    states = np.array(
        [
            _state(earth, earth.radius + alt, 0.001, inc, raan, 0.0, nu)
            for alt, inc, raan, nu in zip(
                rng.uniform(250e3, 900e3, 7),
                rng.uniform(0.0, 98.0, 7),
                rng.uniform(0.0, 360.0, 7),
                rng.uniform(0.0, 360.0, 7),
                strict=True,
            )
        ]
    )
    t1 = rng.uniform(1000.0, DAY, 7)
    batch = j2.propagate_batch(states, 0.0, t1)
    for k in range(7):
        single = j2.propagate(states[k], 0.0, t1[k]).state
        assert np.linalg.norm(batch[k, :3] - single[:3]) < 1e-3


def test_state_transition_matrix_against_central_differences(earth, j2):
    s0 = _state(earth, earth.radius + 300e3, 0.001, 51.6)
    t1 = 2700.0
    _, stm = j2.propagate_with_stm(s0, 0.0, t1)
    steps = np.array([1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3])
    fd = np.empty((6, 6))
    for k in range(6):
        dp, dm = s0.copy(), s0.copy()
        dp[k] += steps[k]
        dm[k] -= steps[k]
        fd[:, k] = (j2.propagate(dp, 0.0, t1).state - j2.propagate(dm, 0.0, t1).state) / (
            2 * steps[k]
        )
    assert np.max(np.abs(stm - fd) / (np.abs(fd) + 1.0)) < 1e-6


def test_batch_state_transition_matrices_equal_the_scalar_ones(earth, j2):
    """More states than SIMD lanes (chunks and a padded last one), each with its times.

    The batch integrator is compiled without compact mode (for speed) and the scalar one
    with it: the same Taylor method, other operation order, so they agree to the
    integration's tolerance (up to 2.4e-8 m on ~7e6 m here), not to the bit."""
    rng = np.random.default_rng(7)
    base = _state(earth, earth.radius + 300e3, 0.001, 51.6)
    states = base + rng.normal(size=(11, 6)) * np.r_[np.full(3, 1e3), np.full(3, 1.0)]
    t0 = rng.uniform(-500.0, 500.0, 11)
    t1 = t0 + rng.uniform(1000.0, 6000.0, 11)
    finals, stms = j2.propagate_with_stm_batch(states, t0, t1)
    for k in range(11):
        final, stm = j2.propagate_with_stm(states[k], t0[k], t1[k])
        np.testing.assert_allclose(finals[k], final, rtol=TOL, atol=1e6 * TOL)
        np.testing.assert_allclose(stms[k], stm, rtol=1e-11, atol=1e-12)
    with pytest.raises(FloatingPointError, match="variational propagation failed"):
        j2.propagate_with_stm_batch(np.vstack([states[:2], np.zeros(6)]), 0.0, 100.0)


def test_non_finite_state_is_reported_not_raised(earth, j2):
    result = j2.propagate(np.zeros(6), 0.0, 100.0)
    assert result.status == "error" and not result.ok
    assert "integration stopped" in result.message


def test_integrators_are_built_once_per_thread(earth):
    events = [AltitudeCrossing(100e3)]
    first = _event_integrator(TOL, events)
    assert _event_integrator(TOL, [AltitudeCrossing(250e3)]) is first  # value is a parameter
    other: list = []
    worker = threading.Thread(target=lambda: other.append(_event_integrator(TOL, events)))
    worker.start()
    worker.join()
    assert other[0] is not first  # heyoka integrators are stateful: one per thread


def test_invalid_tolerance_is_refused(earth):
    with pytest.raises(ValueError, match="tol must be in"):
        OrbitPropagator(earth, tol=0.0)


def test_grid_output_equals_dense_output_and_a_later_start(earth, j2):
    """heyoka's grid output (no continuous-output object) gives the dense output's states;
    a grid that starts after t0 is reached first, forward and backward."""
    s0 = _state(earth, earth.radius + 400e3, 0.001, 51.6)
    times = np.r_[np.arange(0.0, 5000.0, 60.0), 5000.0]
    dense = j2.propagate(s0, 0.0, 5000.0, dense=True).dense(times)
    np.testing.assert_array_equal(j2.propagate_grid(s0, 0.0, times), dense)
    later = j2.propagate_grid(s0, 0.0, times[10:])
    np.testing.assert_allclose(later[:, :3], dense[10:, :3], rtol=0.0, atol=1e-4)
    backward = j2.propagate_grid(dense[-1], 5000.0, times[::-1][5:])
    np.testing.assert_allclose(backward[:, :3], dense[::-1][5:, :3], rtol=0.0, atol=1e-4)


def test_zero_length_dense_propagation_is_the_state_itself(earth, j2):
    s0 = _state(earth, earth.radius + 400e3, 0.001, 51.6)
    result = j2.propagate(s0, 100.0, 100.0, dense=True)
    assert result.ok and result.t == 100.0
    np.testing.assert_array_equal(result.state_at(100.0), s0)
    np.testing.assert_array_equal(result.dense(np.array([100.0, 100.0])), [s0, s0])
    np.testing.assert_array_equal(result.dense(100.0), s0)
    np.testing.assert_array_equal(result.states_at(np.array([99.0, 100.0, 101.0])), [s0] * 3)
    with pytest.raises(ValueError, match="must lie in"):
        result.dense(101.0)
