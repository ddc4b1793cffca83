"""Reentry stage (patent step 104) against independent references.

The references are written here, not taken from the library:

* Allen & Eggers (NACA TR-1381, 1958): ballistic entry in an exponential
  atmosphere, peak deceleration ``V_E^2 sin|gamma_E| / (2 e H)`` at the altitude
  ``H ln(rho0 H / (beta sin|gamma_E|))``.
* The equilibrium glide ``L cos(sigma) = g - V^2 / r`` and its flight-path angle
  ``gamma_eq = -2 H g / (V^2 (L/D) cos(sigma))`` (Vinh, Busemann & Culp,
  *Hypersonic and Planetary Entry Flight Mechanics*, 1980, ch. 2; derived below).
* A Cartesian Earth-fixed integration (scipy DOP853) of gravity, Coriolis,
  centrifugal, lift and drag accelerations: an independent check of the
  spherical 3-DOF equations with and without Earth rotation.
* Great-circle geometry (haversine) for the ground range and the landing-site miss.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

from ovtraj.config import ConfigError
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry import reentry_input, solve_reentry
from ovtraj.reentry.model import EntryModel
from tests.conftest import DEFAULT_SCENARIO, build_scenario
from tests.conftest import REENTRY_KEYS as ROW_KEYS

COL = {name: i for i, name in enumerate(dyn.HISTORY_COLUMNS)}
RHO0, SCALE_HEIGHT = 1.225, 7200.0  # exponential atmosphere of the analytic references
EXPONENTIAL = {
    "model": "exponential",
    "density0_kg_m3": RHO0,
    "scale_height_km": SCALE_HEIGHT / 1e3,
    "speed_of_sound_mps": 300.0,
}
# The default vehicle's polynomials written out (a in deg, no Mach terms): CL, CD of a.
DEFAULT_AERO = {
    "alpha_unit": "deg",
    "cl": [[-0.05, 0.0], [0.025, 0.0], [-0.0001, 0.0]],
    "cd": [[0.10, 0.0], [0.0, 0.0], [0.0005, 0.0]],
}


def default_cl(a_deg: float) -> float:
    return -0.05 + 0.025 * a_deg - 1e-4 * a_deg**2


def default_cd(a_deg: float) -> float:
    return 0.10 + 5e-4 * a_deg**2


def flat_alpha(alpha_deg: float) -> dict:
    return {"mach": [0.5, 60.0], "alpha_deg": [alpha_deg, alpha_deg]}


def setup(mutate=None):
    """(input, model) of the default scenario with ``mutate(reentry_section)`` applied."""
    with open(DEFAULT_SCENARIO, encoding="utf-8") as fh:
        data = yaml.safe_load(fh)
    if mutate is not None:
        mutate(data["reentry"])
    inp = reentry_input(build_scenario(data))
    return inp, EntryModel(inp)


def central_angle(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Haversine central angle [rad] between two points on the sphere."""
    s = (
        math.sin(0.5 * (lat2 - lat1)) ** 2
        + math.cos(lat1) * math.cos(lat2) * math.sin(0.5 * (lon2 - lon1)) ** 2
    )
    return 2.0 * math.asin(math.sqrt(min(s, 1.0)))


def destination(lat: float, lon: float, bearing: float, angle: float) -> tuple[float, float]:
    """End point of a great-circle arc of ``angle`` [rad] from (lat, lon) along ``bearing``."""
    lat2 = math.asin(
        math.sin(lat) * math.cos(angle) + math.cos(lat) * math.sin(angle) * math.cos(bearing)
    )
    lon2 = lon + math.atan2(
        math.sin(bearing) * math.sin(angle) * math.cos(lat),
        math.cos(angle) - math.sin(lat) * math.sin(lat2),
    )
    return lat2, lon2


def parabolic_peak(t: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Peak value and time of sampled y(t) (uniform steps) from the parabola through 3 points."""
    k = int(np.argmax(y))
    y0, y1, y2 = y[k - 1], y[k], y[k + 1]
    d = 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2)
    return y1 - 0.25 * (y0 - y2) * d, t[k] + d * 0.5 * (t[k + 1] - t[k - 1])


# --- 1. ballistic entry vs Allen & Eggers --------------------------------------------------------

# Allen & Eggers neglect gravity against drag. From the 120 km entry down to the
# deceleration peak (~25-30 km) gravity still adds speed: with V_E taken at 120 km
# the simulated peak is 4.3-5.3 % above the closed form (measured). The reference
# therefore uses the speed the vehicle would have at the peak altitude without drag,
# V_E^2 + 2 mu (1/r* - 1/r_E) (energy conservation), still a closed form: the
# simulated peak is then 0.7-1.5 % above it (measured; the residue is gravity and
# the flight-path curvature during the deceleration itself). Altitude of the peak:
# 0.3-0.6 % below H ln(rho0 H / (beta sin|gamma_E|)) (measured).
BALLISTIC_SPEED = 7000.0
BALLISTIC_ALTITUDE = 120e3


@pytest.fixture(scope="module", params=[(-30.0, 200.0), (-45.0, 500.0)], ids=["g30b200", "g45b500"])
def ballistic(request):
    fpa_deg, beta = request.param

    def mutate(r):
        r["vehicle"].update(mass_kg=beta, reference_area_m2=1.0)  # CD 1: m/(CD S) = beta
        r["vehicle"]["aero"] = {"alpha_unit": "deg", "cl": [[0.0]], "cd": [[1.0]]}
        r["vehicle"]["alpha_schedule"] = flat_alpha(90.0)  # load = |D sin(90 deg)| = D
        r["atmosphere"] = EXPONENTIAL
        r["integration"].update(earth_rotation=False, step_s=0.1)
        r["entry"].update(
            fpa_deg=fpa_deg, speed_mps=BALLISTIC_SPEED, altitude_km=BALLISTIC_ALTITUDE / 1e3
        )
        r["terminal"]["speed_mps"] = 1000.0  # well below V_E / sqrt(e) = 4246 m/s

    inp, model = setup(mutate)
    flight = model.fly(0.0, 0.0, record=True, guided=False)
    return fpa_deg, beta, inp, flight


def test_ballistic_peak_deceleration_matches_allen_eggers(ballistic):
    fpa_deg, beta, inp, flight = ballistic
    assert flight.status == dyn.TERMINAL
    h = flight.history
    earth = inp.earth
    drag = h[:, COL["dynamic_pressure_pa"]] * 1.0 / beta  # q CD S / m
    np.testing.assert_allclose(h[:, COL["load_g"]] * earth.g0_m_s2, drag, rtol=1e-9)
    a_peak, t_peak = parabolic_peak(h[:, COL["time_s"]], drag)
    h_peak = np.interp(t_peak, h[:, COL["time_s"]], h[:, COL["radius_m"]]) - earth.radius

    s = math.sin(math.radians(-fpa_deg))
    h_star = SCALE_HEIGHT * math.log(RHO0 * SCALE_HEIGHT / (beta * s))
    a_plain = BALLISTIC_SPEED**2 * s / (2.0 * math.e * SCALE_HEIGHT)
    r_star, r_entry = earth.radius + h_star, earth.radius + BALLISTIC_ALTITUDE
    v_e2 = BALLISTIC_SPEED**2 + 2.0 * earth.mu * (1.0 / r_star - 1.0 / r_entry)
    a_max = v_e2 * s / (2.0 * math.e * SCALE_HEIGHT)

    assert a_peak == pytest.approx(a_max, rel=0.03)
    assert h_peak == pytest.approx(h_star, rel=0.03)
    # Without the gravity correction: above the closed form by the gravity gain (4-6 %).
    assert 0.0 < a_peak / a_plain - 1.0 < 0.07
    # Allen & Eggers: the peak occurs at V = V_E / sqrt(e).
    v_peak = np.interp(t_peak, h[:, COL["time_s"]], h[:, COL["speed_mps"]])
    assert v_peak == pytest.approx(math.sqrt(v_e2 / math.e), rel=0.03)
    # The recorded maximum load is the drag peak (sampled: no more than the refined one).
    assert flight.max_load_g * earth.g0_m_s2 == pytest.approx(a_peak, rel=2e-3)


# --- 2. equilibrium glide ------------------------------------------------------------------------

# Equilibrium glide: L cos(sigma) = g - V^2/r with L = rho V^2 / (2 beta_L),
# beta_L = m / (CL S). Differentiate in time with rho' = -rho V sin(gamma) / H,
# V' = -D = -L / (L/D), r and g frozen:
#   -rho V^3 sin(gamma) / H = 2 rho V D + 4 beta_L V D / (r cos(sigma))
# and, with 2 beta_L / (rho cos(sigma)) = V^2 / (g - V^2/r) from the glide condition,
#   sin(gamma_eq) = -2 H g / (V^2 (L/D) cos(sigma))   (Vinh et al. 1980, ch. 2).
# The altitude follows from rho_eq = 2 beta_L (g - V^2/r) / (V^2 cos(sigma)).
GLIDE_ALPHA_DEG = 20.0  # L/D = 0.41 / 0.30 = 1.367
GLIDE_WINDOW = (3500.0, 6500.0)  # m/s


def glide_setup(step_s: float = 2.0):
    def mutate(r):
        r["vehicle"]["aero"] = DEFAULT_AERO
        r["vehicle"]["alpha_schedule"] = flat_alpha(GLIDE_ALPHA_DEG)
        r["atmosphere"] = EXPONENTIAL
        r["integration"].update(earth_rotation=False, step_s=step_s)

    inp, model = setup(mutate)
    cl, cd = default_cl(GLIDE_ALPHA_DEG), default_cd(GLIDE_ALPHA_DEG)
    beta_l = inp.settings.vehicle.mass_kg / (cl * inp.settings.vehicle.reference_area_m2)
    return inp, model, cl / cd, beta_l


def equilibrium_altitude(v: np.ndarray, sigma: float, beta_l: float, mu: float, radius: float):
    """Altitude [m] of L cos(sigma) = g - V^2/r in the exponential atmosphere (fixed point)."""
    h = np.full_like(v, 50e3, dtype=float)
    for _ in range(60):
        r = radius + h
        rho = 2.0 * beta_l * (mu / r**2 - v**2 / r) / (v**2 * math.cos(sigma))
        h = SCALE_HEIGHT * np.log(RHO0 / rho)
    return h


def gamma_equilibrium(v, r, sigma: float, lift_drag: float, mu: float):
    return -2.0 * SCALE_HEIGHT * (mu / r**2) / (v**2 * lift_drag * math.cos(sigma))


@pytest.mark.parametrize("bank_deg", [0.0, 40.0, 60.0])
def test_glide_from_equilibrium_state_stays_on_equilibrium(bank_deg):
    """Started on the equilibrium glide at 7200 m/s, the flight stays on it.

    Measured over 6500 -> 3500 m/s: gamma 1.6 / 2.2 / 3.5 % shallower than gamma_eq
    on average (max 3.0 / 4.3 / 8.1 %) at 0 / 40 / 60 deg of bank; altitude within
    83 / 138 / 292 m of the equilibrium altitude. (A missing cos(sigma) would be a
    30 % / 100 % error at 40 / 60 deg.)
    """
    inp, model, lift_drag, beta_l = glide_setup()
    earth = inp.earth
    sigma = math.radians(bank_deg)
    v0 = 7200.0
    h0 = float(equilibrium_altitude(np.array([v0]), sigma, beta_l, earth.mu, earth.radius)[0])
    x0 = model.x0.copy()
    x0[0], x0[3] = earth.radius + h0, v0
    x0[4] = math.asin(gamma_equilibrium(v0, earth.radius + h0, sigma, lift_drag, earth.mu))
    flight = model.fly(sigma, sigma, record=True, guided=False, x0=x0)
    assert flight.status == dyn.TERMINAL
    h = flight.history
    v, r, gamma = h[:, COL["speed_mps"]], h[:, COL["radius_m"]], h[:, COL["fpa_rad"]]
    window = (v > GLIDE_WINDOW[0]) & (v < GLIDE_WINDOW[1])
    assert window.sum() > 100
    g_eq = np.arcsin(gamma_equilibrium(v, r, sigma, lift_drag, earth.mu))
    rel = gamma[window] / g_eq[window] - 1.0
    assert abs(rel.mean()) < 0.10
    assert np.max(np.abs(rel)) < 0.15
    h_eq = equilibrium_altitude(v, sigma, beta_l, earth.mu, earth.radius)
    assert np.max(np.abs(r[window] - earth.radius - h_eq[window])) < 1000.0


def test_glide_from_default_entry_settles_near_equilibrium_altitude():
    """From the 120 km default entry the phugoid is not damped out by 6500 m/s.

    gamma oscillates about gamma_eq (window mean -44 % off at 40 deg of bank, so no
    gamma check here); the altitude stays close to the equilibrium altitude: measured
    mean |dh| 2.2 km, max 5.6 km over 6500 -> 3500 m/s.
    """
    inp, model, _, beta_l = glide_setup()
    earth = inp.earth
    sigma = math.radians(40.0)
    flight = model.fly(sigma, sigma, record=True, guided=False)
    assert flight.status == dyn.TERMINAL
    h = flight.history
    v, r = h[:, COL["speed_mps"]], h[:, COL["radius_m"]]
    window = (v > GLIDE_WINDOW[0]) & (v < GLIDE_WINDOW[1])
    dh = (
        r[window]
        - earth.radius
        - equilibrium_altitude(v[window], sigma, beta_l, earth.mu, earth.radius)
    )
    assert np.mean(np.abs(dh)) < 3000.0
    assert np.max(np.abs(dh)) < 8000.0


# --- 3. Earth rotation ---------------------------------------------------------------------------


def cartesian_reference(model: EntryModel, sigma: float, cl: float, cd: float, rotation: bool):
    """Earth-fixed Cartesian integration to the terminal speed: (t, altitude, lat, lon).

    a = -mu r/|r|^3 - 2 Omega x v - Omega x (Omega x r) + L + D, drag along -v, lift
    normal to v in the plane of v and the local vertical rotated by the bank about v
    (positive bank toward v x up_perp, i.e. to the right, heading increasing).
    """
    earth = model.earth
    mu, radius = earth.mu, earth.radius
    omega = np.array([0.0, 0.0, earth.omega if rotation else 0.0])
    mass_area = model.params[dyn.P_MASS_AREA]
    v_end = model.params[dyn.P_V_END]
    r0, lon, lat, v0, gamma, psi = model.x0
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    north = np.cross(up, east)
    vel = v0 * (
        math.cos(gamma) * (math.sin(psi) * east + math.cos(psi) * north) + math.sin(gamma) * up
    )

    def rhs(_t, s):
        p, v = s[:3], s[3:]
        rn = np.linalg.norm(p)
        speed = np.linalg.norm(v)
        u, vh = p / rn, v / speed
        normal = u - (u @ vh) * vh
        normal /= np.linalg.norm(normal)
        side = np.cross(vh, normal)
        q = 0.5 * RHO0 * math.exp(-(rn - radius) / SCALE_HEIGHT) * speed**2 / mass_area
        acc = -mu * p / rn**3 - 2.0 * np.cross(omega, v) - np.cross(omega, np.cross(omega, p))
        acc += q * cl * (math.cos(sigma) * normal + math.sin(sigma) * side) - q * cd * vh
        return np.r_[v, acc]

    def slow(_t, s):
        return np.linalg.norm(s[3:]) - v_end

    slow.terminal = True
    sol = solve_ivp(
        rhs,
        (0.0, 4000.0),
        np.r_[r0 * up, vel],
        method="DOP853",
        rtol=1e-10,
        atol=1e-6,
        events=slow,
    )
    p = sol.y_events[0][0][:3]
    rn = float(np.linalg.norm(p))
    return sol.t_events[0][0], rn - radius, math.asin(p[2] / rn), math.atan2(p[1], p[0])


@pytest.mark.parametrize(
    ("rotation", "bank_deg"), [(True, 40.0), (True, -40.0), (False, 40.0)], ids=str
)
def test_spherical_equations_match_cartesian_integration(rotation, bank_deg):
    """The 3-DOF spherical equations (rotating Earth) against an Earth-fixed Cartesian RK.

    Default entry, exponential atmosphere, constant alpha and bank, 2 s step: measured
    terminal-position differences of 1-4 m after 1700-3700 s of flight.
    """

    def mutate(r):
        r["vehicle"]["aero"] = DEFAULT_AERO
        r["vehicle"]["alpha_schedule"] = flat_alpha(GLIDE_ALPHA_DEG)
        r["atmosphere"] = EXPONENTIAL
        r["integration"]["earth_rotation"] = rotation

    inp, model = setup(mutate)
    sigma = math.radians(abs(bank_deg))
    sign = math.copysign(1.0, bank_deg)
    flight = model.fly(sigma, sigma, guided=False, bank_sign=sign)
    assert flight.status == dyn.TERMINAL
    t, alt, lat, lon = cartesian_reference(
        model, sign * sigma, default_cl(GLIDE_ALPHA_DEG), default_cd(GLIDE_ALPHA_DEG), rotation
    )
    x = flight.state
    assert flight.time_s == pytest.approx(t, abs=0.5)
    assert x[0] - inp.earth.radius == pytest.approx(alt, abs=50.0)
    assert central_angle(x[2], x[1], lat, lon) * inp.earth.radius < 200.0


def test_earth_rotation_effect_of_expected_order():
    """Rotation on vs off, same Earth-relative entry, 40 deg fixed bank, US76.

    Estimate: the Coriolis acceleration 2 Omega V acting over the flight time T
    displaces the vehicle by about (1/2)(2 Omega V) T^2 = Omega V T^2 (V the mean
    speed, T the rotating flight's duration). Measured: 9220 km against an estimate of
    3620 km (ratio 2.5); the bracket [0.2, 5] x estimate is the order-of-magnitude
    test. The entry heads north-east: rotation adds ~280 m/s of inertial speed
    (Omega R cos(lat) sin(psi)), i.e. nearly circular speed, and the Coriolis lift
    2 Omega V cos(lat) sin(psi) ~ 0.7 m/s^2 is as large as g - V^2/r: the rotating
    flight goes much farther (16510 km against 7400 km, measured).
    """
    sigma = math.radians(40.0)
    flights = {}
    for rotation in (True, False):
        inp, model = setup(lambda r, rot=rotation: r["integration"].update(earth_rotation=rot))
        flights[rotation] = model.fly(sigma, sigma, record=True, guided=False)
        assert flights[rotation].reached
    on, off = flights[True], flights[False]
    radius = inp.earth.radius
    diff = central_angle(on.state[2], on.state[1], off.state[2], off.state[1]) * radius
    h = on.history
    mean_speed = np.trapezoid(h[:, COL["speed_mps"]], h[:, COL["time_s"]]) / on.time_s
    estimate = inp.earth.omega * mean_speed * on.time_s**2
    assert 0.2 * estimate < diff < 5.0 * estimate
    x0 = model.x0
    range_on = central_angle(x0[2], x0[1], on.state[2], on.state[1]) * radius
    range_off = central_angle(x0[2], x0[1], off.state[2], off.state[1]) * radius
    assert range_on > 1.5 * range_off


def test_zero_bank_without_rotation_flies_a_great_circle():
    """Measured: great-circle distance = integrated ground range to 8e-8; cross-track 2 cm."""
    inp, model = setup(lambda r: r["integration"].update(earth_rotation=False))
    flight = model.fly(0.0, 0.0, record=True, guided=False)
    assert flight.reached
    h = flight.history
    radius = inp.earth.radius
    ground = np.trapezoid(
        h[:, COL["speed_mps"]] * np.cos(h[:, COL["fpa_rad"]]) * radius / h[:, COL["radius_m"]],
        h[:, COL["time_s"]],
    )
    lat1, lon1, psi = model.x0[2], model.x0[1], model.x0[5]
    lat2, lon2 = flight.state[2], flight.state[1]
    angle = central_angle(lat1, lon1, lat2, lon2)
    assert angle * radius == pytest.approx(ground, rel=1e-4)
    assert ground > 5000e3
    # On the great circle of the initial heading: its end point at that distance.
    lat_gc, lon_gc = destination(lat1, lon1, psi, angle)
    assert central_angle(lat_gc, lon_gc, lat2, lon2) * radius < 10.0
    # The heading does change along the great circle (not a rhumb line).
    assert abs(flight.state[5] - psi) > math.radians(5.0)


# --- 4. RK4 step study ---------------------------------------------------------------------------


def terminal_shift(sigma0_deg: float, sigma1_deg: float, steps=(2.0, 0.25)) -> float:
    ends = []
    for step in steps:
        inp, model = setup(lambda r, s=step: r["integration"].update(step_s=s))
        flight = model.fly(math.radians(sigma0_deg), math.radians(sigma1_deg), guided=False)
        assert flight.reached
        ends.append(flight.state)
    a, b = ends
    return central_angle(a[2], a[1], b[2], b[1]) * inp.earth.radius


def test_rk4_step_constant_bank():
    """Default flight, 40 deg fixed bank: 2 s vs 0.25 s steps end 1 m apart (measured)."""
    assert terminal_shift(40.0, 40.0) < 50.0


def test_rk4_step_bank_ramp_keeps_fourth_order():
    """The default guided profile (sigma_0 64.2 -> sigma_1 30.6 deg, docs) flown unguided.

    The bank magnitude is a function of speed evaluated at every RK4 stage, so the
    scheme keeps its order: 2 s vs 0.25 s steps end ~3 m apart (measured; 2.8 km
    when the magnitude was held over each step, a first-order error).
    """
    assert terminal_shift(64.2, 30.6) < 50.0


# --- 5./6. guided entries ------------------------------------------------------------------------


def dispersed_entries(entry, radius: float) -> dict:
    def moved(distance_m: float, bearing: float):
        lat, lon = destination(
            entry.latitude_rad, entry.longitude_rad, bearing, distance_m / radius
        )
        return replace(entry, latitude_rad=lat, longitude_rad=lon)

    psi = entry.heading_rad
    return {
        "nominal": entry,
        "fpa+0.1": replace(entry, fpa_rad=entry.fpa_rad + math.radians(0.1)),
        "fpa-0.1": replace(entry, fpa_rad=entry.fpa_rad - math.radians(0.1)),
        "speed+20": replace(entry, speed_mps=entry.speed_mps + 20.0),
        "speed-20": replace(entry, speed_mps=entry.speed_mps - 20.0),
        "heading+1": replace(entry, heading_rad=psi + math.radians(1.0)),
        "heading-1": replace(entry, heading_rad=psi - math.radians(1.0)),
        "downrange+50km": moved(50e3, psi),
        "uprange-50km": moved(50e3, psi + math.pi),
        "crossrange+50km": moved(50e3, psi + 0.5 * math.pi),
        "crossrange-50km": moved(50e3, psi - 0.5 * math.pi),
    }


CASES = [
    "nominal",
    "fpa+0.1",
    "fpa-0.1",
    "speed+20",
    "speed-20",
    "heading+1",
    "heading-1",
    "downrange+50km",
    "uprange-50km",
    "crossrange+50km",
    "crossrange-50km",
]


@pytest.fixture(scope="module")
def guided():
    inp, _ = setup()
    entries = dispersed_entries(inp.entry, inp.earth.radius)
    assert list(entries) == CASES
    return inp, {name: solve_reentry(replace(inp, entry=e)) for name, e in entries.items()}


@pytest.mark.parametrize("case", CASES)
def test_guided_dispersed_entry_reaches_the_site(guided, case):
    """Measured misses 0.02-0.11 km; smallest margins: heat 0.17, load 0.57, q 0.54, bank 0.08."""
    inp, results = guided
    res = results[case]
    s = inp.settings
    assert res.feasible, res.reason
    assert res.flags == ()
    assert res.reason is None
    row = res.to_row()
    assert row["miss_distance_km"] <= s.terminal.miss_tolerance_km
    # Independent miss: haversine from the trajectory's last point to the site.
    last = res.trajectory.iloc[-1]
    site = s.landing_site
    miss = central_angle(
        math.radians(last["latitude_deg"]),
        math.radians(last["longitude_deg"]),
        math.radians(site.latitude_deg),
        math.radians(site.longitude_deg),
    )
    assert miss * inp.earth.radius / 1e3 == pytest.approx(row["miss_distance_km"], abs=1e-6)
    assert last["time_s"] == pytest.approx(row["flight_time_s"])
    assert row["terminal_speed_mps"] == pytest.approx(s.terminal.speed_mps, abs=1e-6)
    assert abs(row["terminal_altitude_km"] - s.terminal.altitude_km) <= (
        s.terminal.altitude_tolerance_km
    )
    assert last["altitude_km"] == pytest.approx(row["terminal_altitude_km"])
    # Margins: recomputed from the limits, all respected.
    lim = s.limits
    expected = {
        "heat_rate_margin": 1.0 - row["max_heat_rate_kw_m2"] / lim.max_heat_rate_kw_m2,
        "load_margin": 1.0 - row["max_load_g"] / lim.max_load_g,
        "dynamic_pressure_margin": 1.0
        - row["max_dynamic_pressure_kpa"] / lim.max_dynamic_pressure_kpa,
        "bank_margin": 1.0 - row["max_bank_deg"] / lim.max_bank_deg,
    }
    for key, value in expected.items():
        assert row[key] == pytest.approx(value, abs=1e-12), key
        assert row[key] >= 0.0, key


@pytest.mark.parametrize("case", CASES)
def test_guided_reported_maxima_match_trajectory_table(guided, case):
    """The table is sampled (10 s): its maxima may fall below the reported ones.

    Measured table/reported ratios 0.9996-1.0 (heat, load) and 1.0001-1.0006 for the
    dynamic pressure: its maximum is at the terminal point, which the reported
    maxima leave out (see the report); hence the 1e-3 allowance above.
    """
    _, results = guided
    res = results[case]
    row = res.to_row()
    table = res.trajectory
    assert len(table) > 50
    for column, key in (
        ("heat_rate_kw_m2", "max_heat_rate_kw_m2"),
        ("load_g", "max_load_g"),
        ("dynamic_pressure_kpa", "max_dynamic_pressure_kpa"),
    ):
        top = table[column].max()
        assert top <= row[key] * (1.0 + 1e-3), column
        assert top >= row[key] * 0.98, column
    assert np.abs(table["bank_deg"]).max() <= row["max_bank_deg"] + 1e-9
    assert np.abs(table["bank_deg"]).max() >= row["max_bank_deg"] - 1.0


@pytest.mark.parametrize("case", ["nominal", "speed-20"])
def test_row_keys_present_and_finite(guided, case):
    _, results = guided
    row = results[case].to_row()
    assert ROW_KEYS <= set(row)
    for key in ROW_KEYS - {"feasible"}:
        assert isinstance(row[key], float) and math.isfinite(row[key]), key
    for key, value in row.items():
        if isinstance(value, float):
            assert math.isfinite(value), key
    assert row["feasible"] is True


@pytest.fixture(scope="module")
def unreachable():
    """Sites and entries the vehicle cannot make: each must come back flagged, not raise."""
    out = {}
    # KSC moved 50 deg east (4850 km): 14735 km to go, ~900 km beyond the footprint.
    far, _ = setup(lambda r: r["landing_site"].update(longitude_deg=-30.7))
    out["site_4850km_east"] = (far, solve_reentry(far))
    # Entry climbing at +3 deg: skips out of the atmosphere.
    skip, _ = setup(lambda r: r["entry"].update(fpa_deg=3.0))
    out["skip_out"] = (skip, solve_reentry(skip))
    return out


def test_site_outside_footprint_is_flagged(unreachable):
    _, res = unreachable["site_4850km_east"]
    assert res.feasible is False
    assert "outside_footprint" in res.flags
    assert "outside the footprint" in res.reason
    assert "km from it" in res.reason
    assert res.miss_distance_m > 100e3
    row = res.to_row()
    assert ROW_KEYS <= set(row)
    assert row["feasible"] is False
    assert all(math.isfinite(v) for v in row.values() if isinstance(v, float))


def test_skip_out_is_flagged(unreachable):
    _, res = unreachable["skip_out"]
    assert res.feasible is False
    assert "terminal_not_reached" in res.flags
    assert "skipped" in res.reason


# --- 7. bad configs ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        (("vehicle", "reference_area_m2"), -1.0, "reentry.vehicle.reference_area_m2"),
        (("vehicle", "alpha_schedule", "mach"), [12.0, 3.0], "reentry.vehicle.alpha_schedule"),
        (("vehicle", "alpha_schedule", "mach"), [3.0, 3.0], "reentry.vehicle.alpha_schedule"),
        (("limits", "max_load_g"), 0.0, "reentry.limits.max_load_g"),
        (("limits", "max_heat_rate_kw_m2"), -1.0, "reentry.limits.max_heat_rate_kw_m2"),
        (("limits", "max_dynamic_pressure_kpa"), 0.0, "reentry.limits.max_dynamic_pressure_kpa"),
    ],
)
def test_bad_config_refused(scenario_data, path, value, field):
    node = scenario_data["reentry"]
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ConfigError) as info:
        build_scenario(scenario_data)
    assert field in str(info.value)
    if path[-1] == "mach":
        assert "increasing" in str(info.value)


# --- 8. seed-001 aerodynamics --------------------------------------------------------------------

SEED_CL = [[0.0042806, -0.010935], [0.022956, 0.0], [0.000181, 0.0]]
SEED_CD = [[0.074615, -0.0018487], [-0.0059261, 0.0], [0.000689, 0.0]]


def test_seed_001_aero_expressible():
    """alpha 10 deg at Mach 5 (1500 m/s, 300 m/s speed of sound), coefficients by hand."""

    def mutate(r):
        r["vehicle"]["aero"] = {"alpha_unit": "deg", "cl": SEED_CL, "cd": SEED_CD}
        r["vehicle"]["alpha_schedule"] = flat_alpha(10.0)
        r["atmosphere"] = EXPONENTIAL
        r["entry"].update(speed_mps=1500.0, altitude_km=40.0)

    inp, model = setup(mutate)
    a, mach = 10.0, 5.0
    cl = 0.000181 * a**2 + 0.022956 * a - 0.010935 * mach + 0.0042806  # 0.1972656
    cd = 0.074615 - 0.0018487 * mach - 0.0059261 * a + 0.000689 * a**2  # 0.0750105
    assert cl == pytest.approx(0.1972656, abs=1e-12)
    assert cd == pytest.approx(0.0750105, abs=1e-12)

    x = model.x0
    lift, drag, alpha, mach_model, rho = dyn.aero_accelerations(
        x,
        model.params,
        model.tables,
    )
    assert math.degrees(alpha) == pytest.approx(a)
    assert mach_model == pytest.approx(mach)
    q_over = (
        0.5
        * rho
        * x[3] ** 2
        * inp.settings.vehicle.reference_area_m2
        / (inp.settings.vehicle.mass_kg)
    )
    assert lift / q_over == pytest.approx(cl, rel=1e-12)
    assert drag / q_over == pytest.approx(cd, rel=1e-12)

    # The same through a recorded flight: first row's load |L cos a + D sin a| / g0.
    flight = model.fly(0.3, 0.3, record=True, guided=False)
    row = flight.history[0]
    assert row[COL["mach"]] == pytest.approx(mach)
    q = row[COL["dynamic_pressure_pa"]]
    ar = math.radians(a)
    load = (
        q
        * inp.settings.vehicle.reference_area_m2
        / inp.settings.vehicle.mass_kg
        * abs(cl * math.cos(ar) + cd * math.sin(ar))
        / inp.earth.g0_m_s2
    )
    assert row[COL["load_g"]] == pytest.approx(load, rel=1e-12)


# --- 9. the flight kernel's shortcuts (for speed) ----------------------------------------------


def test_angle_addition_gives_the_cosine_and_sine_within_two_ulp():
    """cos and sin of a stage's angle from the step's start (angle addition, the
    increment's Taylor series) against the library's, over every increment a stage
    takes; a far increment is the library's value itself."""
    rng = np.random.default_rng(20)
    worst = 0.0
    for start in rng.uniform(-math.pi, math.pi, 400):
        for d in rng.uniform(-0.05, 0.05, 25):
            c, s = dyn._shifted(math.cos(start), math.sin(start), start + d, start)
            angle = start + d
            worst = max(worst, abs(c - math.cos(angle)), abs(s - math.sin(angle)))
    assert worst <= 2 * np.finfo(float).eps
    far = 1.0 + 0.06
    assert dyn._shifted(math.cos(1.0), math.sin(1.0), far, 1.0) == (math.cos(far), math.sin(far))


def test_stage_rates_by_angle_addition_match_the_module_equations():
    """The RK4 stages' rates (angles shifted from the step's start) against
    :func:`point_mass_rates_of` (the library's cosines and sines) at the same state."""
    rng = np.random.default_rng(5)
    mu, omega = 3.986004418e14, 7.2921159e-5
    for _ in range(200):
        r = 6.371e6 + rng.uniform(25e3, 120e3)
        lat0, gamma0, psi0, bank0 = rng.uniform(-1.2, 1.2), -0.02, rng.uniform(-3, 3), 0.7
        start = dyn._start_of_step(lat0, gamma0, psi0, bank0)
        d = rng.uniform(-0.01, 0.01, 4)
        state = (r, lat0 + d[0], rng.uniform(800.0, 7600.0), gamma0 + d[1], psi0 + d[2])
        aero = (rng.uniform(0.0, 30.0), rng.uniform(0.0, 30.0), 0.0, 0.0, 0.0)
        sign = rng.choice([-1.0, 1.0])
        shifted = dyn._stage(state, aero, bank0 + d[3], sign, mu, omega, start)
        g = mu / (r * r)
        direct = dyn.point_mass_rates_of(
            r, state[1], state[2], state[3], state[4], aero[0], aero[1],
            sign * (bank0 + d[3]), g, omega,
        )  # fmt: skip
        assert np.allclose(shifted, direct, rtol=1e-13, atol=1e-18)


@pytest.mark.parametrize("angle", [-10.0, -math.pi - 1e-12, -math.pi, -1.0, 0.0, 3.0, math.pi, 7.5])
def test_heading_wrap_equals_the_modulo(angle):
    expected = (angle + math.pi) % (2.0 * math.pi) - math.pi
    assert dyn._wrap(angle) == expected
    assert -math.pi <= dyn._wrap(angle) < math.pi


def test_packed_model_holds_the_parameters_and_tables_in_order():
    """:func:`~ovtraj.reentry.dynamics.pack`: parameters, sizes, then the tables row by row."""
    _, model = setup()
    m = dyn.pack(model.params, model.tables)
    n = dyn.N_PARAMS
    assert np.array_equal(m[:n], model.params)
    rows, cols = model.cl.shape
    sizes = m[n : n + dyn.N_HEADER]
    assert list(sizes) == [rows, cols, len(model.mach_nodes), len(model.log_rho)]
    k = n + dyn.N_HEADER
    pieces = (model.cl, model.cd, model.mach_nodes, model.alpha_nodes, model.log_rho, model.sound)
    tables = np.concatenate([np.ravel(piece) for piece in pieces])
    assert np.array_equal(m[k:], tables)
