"""Two-body deorbit burn estimate (patent step 103) against independent references."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from ovtraj.astro.elements import rv_to_coe
from ovtraj.deorbit.estimate import TangentialDeorbit, tangential_deorbit

MU = 3.986004418e14  # m^3/s^2
R_EARTH = 6378137.0  # m
KM = 1e3
R0 = R_EARTH + 345 * KM  # preparation orbit
RE = R_EARTH + 120 * KM  # entry interface
GAMMA = math.radians(-1.1)


def _v1_by_root_finding(r0, re, gamma, mu):
    """Post-burn speed from h = r0 v1 = re ve cos(gamma) and the energy equation.

    Solves cos(gamma) = r0 v1 / (re ve(v1)) for v1 with ve from the energy
    integral: negative at v1 = 0, >= 1 - cos(gamma) at the circular speed.
    """

    def residual(v1):
        ve = math.sqrt(v1 * v1 + 2.0 * mu * (1.0 / re - 1.0 / r0))
        return r0 * v1 / (re * ve) - math.cos(gamma)

    return brentq(residual, 0.0, math.sqrt(mu / r0), xtol=1e-12, rtol=1e-15)


# --- 1. the published figure ------------------------------------------------------------------


def test_published_345_to_120_km_at_minus_1_1_deg():
    est = tangential_deorbit(R0, RE, GAMMA, MU)
    assert isinstance(est, TangentialDeorbit)
    assert est.dv_mps == pytest.approx(87.0, abs=1.5)

    v0 = math.sqrt(MU / R0)
    v1 = _v1_by_root_finding(R0, RE, GAMMA, MU)
    assert est.speed_before_mps == pytest.approx(v0, rel=1e-15)
    assert est.speed_after_mps == pytest.approx(v1, rel=1e-12)
    assert est.dv_mps == pytest.approx(v0 - v1, rel=1e-6)
    assert est.dv_mps == pytest.approx(est.speed_before_mps - est.speed_after_mps, rel=1e-15)


def test_speed_before_is_used_for_the_impulse():
    circ = tangential_deorbit(R0, RE, GAMMA, MU)
    faster = tangential_deorbit(R0, RE, GAMMA, MU, speed_before_mps=circ.speed_before_mps + 10.0)
    # Same descent ellipse, the impulse grows by the extra speed.
    assert faster.speed_after_mps == circ.speed_after_mps
    assert faster.time_of_flight_s == circ.time_of_flight_s
    assert faster.dv_mps == pytest.approx(circ.dv_mps + 10.0, rel=1e-12)


# --- 2. conservation and the ellipse -------------------------------------------------------------


@pytest.mark.parametrize("fpa_deg", [-0.3, -1.1, -2.5, -8.0])
def test_energy_and_angular_momentum_are_conserved(fpa_deg):
    gamma = math.radians(fpa_deg)
    est = tangential_deorbit(R0, RE, gamma, MU)
    v1, ve = est.speed_after_mps, est.entry_speed_mps

    energy_burn = 0.5 * v1**2 - MU / R0
    energy_entry = 0.5 * ve**2 - MU / RE
    assert energy_entry == pytest.approx(energy_burn, rel=1e-12)
    assert -MU / (2.0 * est.semi_major_axis_m) == pytest.approx(energy_burn, rel=1e-12)
    # vis-viva at the entry radius
    assert ve == pytest.approx(math.sqrt(MU * (2.0 / RE - 1.0 / est.semi_major_axis_m)), rel=1e-12)
    # h = r0 v1 (horizontal at the burn) = re ve cos(gamma)
    assert R0 * v1 / (RE * ve) == pytest.approx(math.cos(gamma), rel=1e-12)

    # The burn point is the apoapsis of the ellipse; elements from the Cartesian state.
    coe = rv_to_coe([R0, 0.0, 0.0], [0.0, v1, 0.0], mu=MU)
    assert est.semi_major_axis_m == pytest.approx(coe.a, rel=1e-12)
    assert est.eccentricity == pytest.approx(coe.e, rel=1e-10)
    assert float(coe.nu) == pytest.approx(math.pi, abs=1e-12)
    assert est.semi_major_axis_m * (1.0 + est.eccentricity) == pytest.approx(R0, rel=1e-12)
    assert est.semi_major_axis_m * (1.0 - est.eccentricity) < RE


# --- 3. numerical propagation -----------------------------------------------------------------


def _two_body(_t, y):
    r3 = math.hypot(y[0], y[1]) ** 3
    return [y[2], y[3], -MU * y[0] / r3, -MU * y[1] / r3]


@pytest.mark.parametrize(
    ("r0", "re", "fpa_deg"),
    [
        (R0, RE, -1.1),
        (R0, RE, -0.2),
        (R0, RE, -4.0),
        (R_EARTH + 500 * KM, R_EARTH + 100 * KM, -15.0),
    ],
)
def test_against_numerical_propagation(r0, re, fpa_deg):
    gamma = math.radians(fpa_deg)
    est = tangential_deorbit(r0, re, gamma, MU)

    def reach_entry(_t, y):
        return math.hypot(y[0], y[1]) - re

    reach_entry.terminal = True
    reach_entry.direction = -1.0

    period_circular = 2.0 * math.pi * math.sqrt(r0**3 / MU)
    sol = solve_ivp(
        _two_body,
        (0.0, period_circular),
        [r0, 0.0, 0.0, est.speed_after_mps],
        method="DOP853",
        rtol=1e-12,
        atol=1e-6,
        events=reach_entry,
    )
    assert sol.status == 1, "the entry radius was not reached"
    t_entry = sol.t_events[0][0]
    x, y, vx, vy = sol.y_events[0][0]
    r = np.array([x, y])
    v = np.array([vx, vy])

    assert est.time_of_flight_s == pytest.approx(t_entry, abs=1e-3)
    assert est.central_angle_rad == pytest.approx(math.atan2(y, x), abs=1e-8)
    fpa = math.atan2(float(r @ v), x * vy - y * vx)  # radial over horizontal speed
    assert fpa == pytest.approx(gamma, abs=1e-8)
    assert est.entry_speed_mps == pytest.approx(float(np.hypot(vx, vy)), rel=1e-9)
    assert 0.0 < est.central_angle_rad < math.pi


# --- 4. limits and monotonicity ---------------------------------------------------------------


def test_shallow_entry_tends_to_the_hohmann_like_ellipse():
    dv_hohmann = math.sqrt(MU / R0) - math.sqrt(2.0 * MU * RE / (R0 * (R0 + RE)))
    half_period = math.pi * math.sqrt((0.5 * (R0 + RE)) ** 3 / MU)
    errors = []
    for fpa in (-1e-2, -1e-3, -1e-4):
        est = tangential_deorbit(R0, RE, fpa, MU)
        errors.append(est.dv_mps - dv_hohmann)
    # dv - dv_H = O(gamma^2): positive, and shrinks ~100x per decade of gamma.
    assert all(err > 0.0 for err in errors)
    for coarse, fine in itertools.pairwise(errors):
        assert fine / coarse == pytest.approx(1e-2, rel=0.05)

    est = tangential_deorbit(R0, RE, -1e-7, MU)
    assert est.dv_mps == pytest.approx(dv_hohmann, abs=1e-6)
    assert est.semi_major_axis_m == pytest.approx(0.5 * (R0 + RE), rel=1e-9)
    assert est.eccentricity == pytest.approx((R0 - RE) / (R0 + RE), rel=1e-9)
    assert est.time_of_flight_s == pytest.approx(half_period, rel=1e-5)
    assert est.central_angle_rad == pytest.approx(math.pi, abs=1e-4)


def test_steeper_entry_needs_more_dv():
    fpas = [-0.5, -1.0, -1.1, -2.0, -3.0, -5.0, -10.0]
    results = [tangential_deorbit(R0, RE, math.radians(f), MU) for f in fpas]
    dvs = [res.dv_mps for res in results]
    angles = [res.central_angle_rad for res in results]
    tofs = [res.time_of_flight_s for res in results]
    assert all(b > a for a, b in itertools.pairwise(dvs))
    assert all(b < a for a, b in itertools.pairwise(angles))
    assert all(b < a for a, b in itertools.pairwise(tofs))


# --- 5. bad input -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"entry_radius_m": R0}, "entry_radius_m"),
        ({"entry_radius_m": R0 + 1.0}, "entry_radius_m"),
        ({"entry_radius_m": -1.0}, "entry_radius_m"),
        ({"entry_radius_m": math.nan}, "entry_radius_m"),
        ({"burn_radius_m": 0.0}, "burn_radius_m"),
        ({"burn_radius_m": -R0}, "burn_radius_m"),
        ({"entry_fpa_rad": 0.0}, "entry_fpa_rad"),
        ({"entry_fpa_rad": 0.01}, "entry_fpa_rad"),
        ({"entry_fpa_rad": -math.pi / 2}, "entry_fpa_rad"),
        ({"entry_fpa_rad": -2.0}, "entry_fpa_rad"),
        ({"entry_fpa_rad": math.nan}, "entry_fpa_rad"),
        ({"mu": 0.0}, "mu"),
        ({"speed_before_mps": 0.0}, "speed_before_mps"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {"burn_radius_m": R0, "entry_radius_m": RE, "entry_fpa_rad": GAMMA, "mu": MU}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        tangential_deorbit(**args)


def test_prograde_burn_is_reported():
    v1 = tangential_deorbit(R0, RE, GAMMA, MU).speed_after_mps
    with pytest.raises(ValueError, match=r"speed_before_mps.*prograde"):
        tangential_deorbit(R0, RE, GAMMA, MU, speed_before_mps=v1 - 1.0)
    # exactly the post-burn speed: no impulse needed, still valid
    assert tangential_deorbit(R0, RE, GAMMA, MU, speed_before_mps=v1).dv_mps == 0.0


def test_the_central_angle_alone_is_the_whole_estimates_to_the_bit():
    """The pass forecast's shortcut (:func:`descent_central_angle_rad`) runs the same
    operations as the whole estimate, and its caller keeps the estimate's checks."""
    from ovtraj.config.physical import default_earth
    from ovtraj.deorbit.estimate import descent_central_angle_rad
    from ovtraj.deorbit.inputs import EntryRegion
    from ovtraj.deorbit.pass_estimate import descent_angle_rad

    for r0, gamma in itertools.product(
        R_EARTH + np.linspace(121, 2000, 200) * KM, np.radians([-0.01, -0.9, -1.1, -5, -60])
    ):
        whole = tangential_deorbit(r0, RE, gamma, MU).central_angle_rad
        assert descent_central_angle_rad(r0, RE, gamma, MU) == whole
    earth = default_earth()
    entry_radius = earth.radius + 120 * KM
    entry = EntryRegion(0.0, 0.0, 0.1, 0.1, 120 * KM, -0.03, -0.01, GAMMA)
    burn = earth.radius + 345 * KM
    angles = descent_angle_rad(np.array([burn, earth.radius + 300 * KM, burn]), entry, earth)
    whole = tangential_deorbit(burn, entry_radius, GAMMA, earth.mu).central_angle_rad
    assert angles[0] == angles[2] == whole
    for bad in (entry_radius - 1.0, np.nan):
        with pytest.raises(ValueError, match=r"burn_radius_m|entry_radius_m"):
            descent_angle_rad(np.array([burn, bad]), entry, earth)
