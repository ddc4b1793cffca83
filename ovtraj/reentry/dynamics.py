"""3-DOF lifting entry over a rotating spherical Earth, compiled with numba.

States ``(r, lon, lat, V, gamma, psi)``: radius, geocentric longitude and latitude,
Earth-relative speed, flight-path angle and heading (from north, clockwise). With
``L``, ``D`` the lift and drag accelerations, ``g = mu / r^2`` and ``Omega`` the
Earth's rate (Vinh, Busemann & Culp, *Hypersonic and Planetary Entry Flight
Mechanics*, 1980, ch. 2; in this heading convention e.g. Lu, JGCD 37(4), 2014,
eqs. 1-6)::

    r'   = V sin(gamma)
    lon' = V cos(gamma) sin(psi) / (r cos(lat))
    lat' = V cos(gamma) cos(psi) / r
    V'   = -D - g sin(gamma)
           + Omega^2 r cos(lat) (sin(gamma) cos(lat) - cos(gamma) sin(lat) cos(psi))
    gamma' = [L cos(sigma) + (V^2/r - g) cos(gamma) + 2 Omega V cos(lat) sin(psi)
              + Omega^2 r cos(lat) (cos(gamma) cos(lat) + sin(gamma) cos(psi) sin(lat))] / V
    psi' = [L sin(sigma) / cos(gamma) + V^2/r cos(gamma) sin(psi) tan(lat)
            - 2 Omega V (tan(gamma) cos(psi) cos(lat) - sin(lat))
            + Omega^2 r sin(psi) sin(lat) cos(lat) / cos(gamma)] / V

Angle of attack from a Mach table, bank magnitude linear in speed between
``sigma_0`` and ``sigma_1``, bank sign reversed when the heading error to the
landing site leaves a corridor narrowing with range to go. Fixed-step RK4: the
bank magnitude is evaluated at every stage (it is a function of the speed, so
the scheme keeps its fourth order), the sign is held over the step; the terminal
speed is located by linear interpolation inside the last step. Path quantities
at every step and at the end point: heat rate ``k_Q sqrt(rho) V^n``, normal load
``|L cos(alpha) + D sin(alpha)| / g0``, dynamic pressure ``rho V^2 / 2``.

Compiled with numba's ``error_model="numpy"``: a division by zero gives inf or nan
(the step's finiteness check then ends the flight ``DIVERGED``) instead of a Python
exception, which spares a zero test on every division: 40 % of a flight's time
(benchmarks/mission.py). Inside the step loop no array crosses a call: the
state and the stages are scalars and the parameters and tables travel as one packed
array (:func:`pack`), because numba counts references (atomic operations) to every
array a compiled function receives; with the state, the stages and six tables as
arrays those counts were half of a flight's time (measured with perf). The history
row is written by a helper numba inlines (``inline="always"``), so the history array
does not cross a call either.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ovtraj.astro.angles import TWO_PI, wrap_to_pi

# Status codes of a trajectory.
TERMINAL, CRASHED, SKIPPED, TIME_LIMIT, DIVERGED = 0, 1, 2, 3, 4
STATUS_TEXT = {
    TERMINAL: "reached the terminal speed",
    CRASHED: "reached the ground before the terminal speed",
    SKIPPED: "skipped out of the atmosphere",
    TIME_LIMIT: "time limit reached before the terminal speed",
    DIVERGED: "the integration diverged",
}
# Columns of a recorded history.
HISTORY_COLUMNS = (
    "time_s",
    "radius_m",
    "longitude_rad",
    "latitude_rad",
    "speed_mps",
    "fpa_rad",
    "heading_rad",
    "alpha_rad",
    "bank_rad",
    "mach",
    "density_kg_m3",
    "heat_rate_w_m2",
    "load_g",
    "dynamic_pressure_pa",
    "range_to_go_m",
)
# The vehicle and atmosphere arrays every kernel needs, passed as one tuple: lift and
# drag coefficient matrices, the Mach and alpha nodes of the schedule, the log-density
# and speed-of-sound tables.
Tables = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
# Indices of the float parameter vector.
(
    P_MU,
    P_RADIUS,
    P_OMEGA,
    P_G0,
    P_MASS_AREA,  # m / S
    P_ALPHA_SCALE,  # alpha [rad] -> polynomial unit
    P_ATM_MODEL,  # 0 table, 1 exponential
    P_ATM_STEP,
    P_RHO0,
    P_SCALE_HEIGHT,
    P_SOUND,
    P_KQ,
    P_NQ,
    P_SIGMA0,
    P_SIGMA1,
    P_SIGMA_MAX,
    P_V_START,
    P_V_END,
    P_TARGET_LAT,
    P_TARGET_LON,
    P_CORRIDOR_MIN,
    P_CORRIDOR_MAX,
    P_CORRIDOR_RANGE,
    P_STEP,
    P_MAX_TIME,
    P_SKIP_RADIUS,
    P_GUIDED,  # 1: reversals by the corridor; 0: fixed bank sign
    P_BANK_SIGN,  # initial sign when unguided
    N_PARAMS,
) = range(29)


@njit(cache=True, error_model="numpy")
def range_and_bearing(lat1: float, lon1: float, lat2: float, lon2: float) -> tuple[float, float]:
    """Central angle [rad] and initial bearing from north [rad] from point 1 to point 2."""
    return _range_and_bearing(lat1, lon1, lat2, lon2, math.cos(lat2), math.sin(lat2))


@njit(cache=True, error_model="numpy")
def _range_and_bearing(
    lat1: float, lon1: float, lat2: float, lon2: float, cos_lat2: float, sin_lat2: float
) -> tuple[float, float]:
    """:func:`range_and_bearing` with point 2's latitude cosine and sine given (a fixed
    landing site: the flight's loop computes them once)."""
    return _range_and_bearing_trig(
        lat1, lon1, math.cos(lat1), math.sin(lat1), lat2, lon2, cos_lat2, sin_lat2
    )


@njit(cache=True, error_model="numpy")
def _range_and_bearing_trig(
    lat1: float,
    lon1: float,
    cos_lat1: float,
    sin_lat1: float,
    lat2: float,
    lon2: float,
    cos_lat2: float,
    sin_lat2: float,
) -> tuple[float, float]:
    """:func:`range_and_bearing` with both latitudes' cosines and sines given (haversine
    central angle, initial bearing of the great circle)."""
    dlon = lon2 - lon1
    s = math.sin(0.5 * (lat2 - lat1)) ** 2 + cos_lat1 * cos_lat2 * math.sin(0.5 * dlon) ** 2
    angle = 2.0 * math.asin(math.sqrt(min(max(s, 0.0), 1.0)))
    bearing = math.atan2(
        math.sin(dlon) * cos_lat2,
        cos_lat1 * sin_lat2 - sin_lat1 * cos_lat2 * math.cos(dlon),
    )
    return angle, bearing


# The flight loop's angle wrap: ovtraj.astro.angles.wrap_to_pi compiled (numba calls only
# compiled functions).
_wrap_to_pi = njit(cache=True, error_model="numpy")(wrap_to_pi)


@njit(cache=True, error_model="numpy")
def _wrap(angle: float) -> float:
    """:func:`ovtraj.astro.angles.wrap_to_pi` of ``angle`` [rad]: in [-pi, pi)."""
    shifted = angle + math.pi
    if 0.0 <= shifted < TWO_PI:
        # The modulo would return ``shifted`` itself (exact): skip its library call, a
        # few % of a flight. The same result as the kernel's, bit for bit.
        return shifted - math.pi
    return _wrap_to_pi(angle)


# The packed model (:func:`pack`): the float parameters (``P_*``), the table sizes
# (``H_*``), then the tables: lift and drag coefficient matrices row by row, the Mach and
# alpha nodes, the log-density and speed-of-sound tables. One array instead of a
# parameter vector and six tables: numba counts references to every array a function
# receives, and those atomic counts were half of a flight's time.
H_ROWS, H_COLS, H_MACH, H_ATM, N_HEADER = range(5)


@njit(cache=True, error_model="numpy")
def pack(p: np.ndarray, tables: Tables) -> np.ndarray:
    """The parameters ``p`` and the vehicle and atmosphere ``tables`` in one array."""
    cl, cd, mach_nodes, alpha_nodes, log_rho, sound = tables
    rows, cols = cl.shape
    n_mach, n_atm = mach_nodes.shape[0], log_rho.shape[0]
    m = np.empty(N_PARAMS + N_HEADER + 2 * rows * cols + 2 * n_mach + 2 * n_atm)
    m[:N_PARAMS] = p
    m[N_PARAMS + H_ROWS] = rows
    m[N_PARAMS + H_COLS] = cols
    m[N_PARAMS + H_MACH] = n_mach
    m[N_PARAMS + H_ATM] = n_atm
    k = N_PARAMS + N_HEADER
    for i in range(rows):
        for j in range(cols):
            m[k] = cl[i, j]
            m[k + rows * cols] = cd[i, j]
            k += 1
    k += rows * cols
    m[k : k + n_mach] = mach_nodes
    m[k + n_mach : k + 2 * n_mach] = alpha_nodes
    k += 2 * n_mach
    m[k : k + n_atm] = log_rho
    m[k + n_atm : k + 2 * n_atm] = sound
    return m


@njit(cache=True, error_model="numpy")
def _aero_packed(r: float, v: float, m: np.ndarray) -> tuple[float, float, float, float, float]:
    """Lift and drag accelerations [m/s^2], angle of attack [rad], Mach and density
    [kg/m^3] at radius r [m] and speed v [m/s]: the atmosphere (US76 table, log-linear,
    or exponential), the alpha schedule (piecewise linear in Mach, held outside its
    nodes) and the coefficient polynomials ``C = sum c[i][j] alpha^i Mach^j``."""
    rows, cols = int(m[N_PARAMS + H_ROWS]), int(m[N_PARAMS + H_COLS])
    n_mach, n_atm = int(m[N_PARAMS + H_MACH]), int(m[N_PARAMS + H_ATM])
    cl0 = N_PARAMS + N_HEADER
    cd0 = cl0 + rows * cols
    mach0 = cd0 + rows * cols
    alpha0 = mach0 + n_mach
    rho0 = alpha0 + n_mach
    sound0 = rho0 + n_atm
    h = r - m[P_RADIUS]
    if m[P_ATM_MODEL] > 0.5:
        rho, a = m[P_RHO0] * math.exp(-max(h, 0.0) / m[P_SCALE_HEIGHT]), m[P_SOUND]
    else:
        step = m[P_ATM_STEP]
        last = n_atm - 2
        x = min(max(h, 0.0), step * (last + 1)) / step
        k = min(int(x), last)
        f = x - k
        rho = math.exp(m[rho0 + k] + f * (m[rho0 + k + 1] - m[rho0 + k]))
        a = m[sound0 + k] + f * (m[sound0 + k + 1] - m[sound0 + k])
    mach = v / a
    if mach <= m[mach0]:
        alpha = m[alpha0]
    elif mach >= m[mach0 + n_mach - 1]:
        alpha = m[alpha0 + n_mach - 1]
    else:
        k = 0
        while m[mach0 + k + 1] < mach:
            k += 1
        alpha = m[alpha0 + k] + (m[alpha0 + k + 1] - m[alpha0 + k]) * (mach - m[mach0 + k]) / (
            m[mach0 + k + 1] - m[mach0 + k]
        )
    q = 0.5 * rho * v * v / m[P_MASS_AREA]
    a_unit = alpha * m[P_ALPHA_SCALE]
    c_lift = 0.0
    c_drag = 0.0
    ai = 1.0
    for i in range(rows):
        mj = 1.0
        for j in range(cols):
            term = ai * mj
            c_lift += m[cl0 + i * cols + j] * term
            c_drag += m[cd0 + i * cols + j] * term
            mj *= mach
        ai *= a_unit
    return q * c_lift, q * c_drag, alpha, mach, rho


@njit(cache=True, error_model="numpy")
def aero_accelerations(
    x: np.ndarray,
    p: np.ndarray,
    tables: Tables,
) -> tuple[float, float, float, float, float]:
    """Lift and drag accelerations [m/s^2], angle of attack [rad], Mach and density
    [kg/m^3] at state ``x`` (radius [m] first, speed [m/s] fourth) of the vehicle ``p``
    in the atmosphere and aerodynamic ``tables``: what an accelerometer on board measures
    (the Monte Carlo's guidance compares the truth's with its model's)."""
    return _aero_packed(x[0], x[3], pack(p, tables))


@njit(cache=True, error_model="numpy")
def _bank_magnitude(v: float, m: np.ndarray) -> float:
    span = m[P_V_START] - m[P_V_END]
    frac = 0.0 if span <= 0.0 else min(max((m[P_V_START] - v) / span, 0.0), 1.0)
    sigma = m[P_SIGMA0] + (m[P_SIGMA1] - m[P_SIGMA0]) * frac
    return min(max(sigma, 0.0), m[P_SIGMA_MAX])


# Cosines and sines of the angles at a step's start, and the angles: latitude,
# flight-path angle, heading, bank magnitude (:func:`_start_of_step`).
StepStart = tuple[
    float, float, float, float, float, float, float, float, float, float, float, float
]


@njit(cache=True, error_model="numpy")
def _start_of_step(lat: float, gamma: float, psi: float, bank: float) -> StepStart:
    return (
        lat,
        gamma,
        psi,
        bank,
        math.cos(lat),
        math.sin(lat),
        math.cos(gamma),
        math.sin(gamma),
        math.cos(psi),
        math.sin(psi),
        math.cos(bank),
        math.sin(bank),
    )


# Largest increment [rad] whose cosine and sine :func:`_shifted` takes from a series:
# the truncation is below 1e-19 there; a stage's increments are < 0.01 rad.
_SHIFT_MAX_RAD = 0.05


@njit(cache=True, error_model="numpy")
def _shifted(c: float, s: float, angle: float, start: float) -> tuple[float, float]:
    """cos and sin of ``angle`` from those of a nearby ``start`` (c, s): angle addition
    with the increment's Taylor series to the 9th power (truncation below 1e-19 for
    increments up to 0.05 rad, a stage's are < 0.01); a far angle is computed directly.
    Within an RK4 step this replaces 12 of 16 cosine-sine pairs."""
    d = angle - start
    if abs(d) > _SHIFT_MAX_RAD:
        return math.cos(angle), math.sin(angle)
    d2 = d * d
    cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0 - d2 * (1.0 / 40320.0))))
    sd = d * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0 - d2 / 362880.0))))
    return c * cd - s * sd, s * cd + c * sd


@njit(cache=True, error_model="numpy")
def _stage(
    state: tuple[float, float, float, float, float],
    aero: tuple[float, float, float, float, float],
    bank: float,
    sign: float,
    mu: float,
    omega: float,
    start: StepStart,
) -> tuple[float, float, float, float, float, float]:
    """The state derivatives at an RK4 stage: ``state`` (r, lat, V, gamma, psi), its
    aerodynamics (:func:`_aero_packed`) and bank magnitude, its angles' cosines and sines
    shifted from the step's ``start``. The magnitude follows the stage's speed (it is a
    function of the state); only the sign, a guidance decision, is held over the step.
    Scalars only: no array reference to count (see the module's notes)."""
    r, lat, v, gamma, psi = state
    cl_, sl = _shifted(start[4], start[5], lat, start[0])
    cg, sg = _shifted(start[6], start[7], gamma, start[1])
    cp, sp = _shifted(start[8], start[9], psi, start[2])
    cb, sb = _shifted(start[10], start[11], bank, start[3])
    return point_mass_rates_trig(
        r, v, cl_, sl, cg, sg, cp, sp, cb, sign * sb, aero[0], aero[1], mu / (r * r), omega
    )


@njit(cache=True, error_model="numpy")
def derivatives_packed(
    x: np.ndarray, sign: float, m: np.ndarray
) -> tuple[float, float, float, float, float, float]:
    """The state derivatives at x with the bank sign ``sign``, the model packed once
    (:func:`pack`; e.g. a replay's right-hand side, called thousands of times)."""
    r, v = x[0], x[3]
    lift, drag, _, _, _ = _aero_packed(r, v, m)
    sigma = sign * _bank_magnitude(v, m)
    return point_mass_rates_of(
        r, x[2], v, x[4], x[5], lift, drag, sigma, m[P_MU] / (r * r), m[P_OMEGA]
    )


@njit(cache=True, error_model="numpy")
def point_mass_rates_of(
    r: float,
    lat: float,
    v: float,
    gamma: float,
    psi: float,
    lift: float,
    drag: float,
    bank: float,
    g: float,
    omega: float,
) -> tuple[float, float, float, float, float, float]:
    """d/dt of (r or h, lon, lat, V, gamma, psi): the module equations (Vinh, Busemann &
    Culp 1980, ch. 2), radius r [m], speed [m/s], angles [rad], lift and drag
    accelerations and gravity g [m/s^2], Earth rate omega [rad/s]. The same primitive for
    the guided entry and the optimal entry's compiled re-flight."""
    return point_mass_rates_trig(
        r,
        v,
        math.cos(lat),
        math.sin(lat),
        math.cos(gamma),
        math.sin(gamma),
        math.cos(psi),
        math.sin(psi),
        math.cos(bank),
        math.sin(bank),
        lift,
        drag,
        g,
        omega,
    )


@njit(cache=True, error_model="numpy")
def point_mass_rates_trig(
    r: float,
    v: float,
    cl_: float,
    sl: float,
    cg: float,
    sg: float,
    cp: float,
    sp: float,
    cb: float,
    sb: float,
    lift: float,
    drag: float,
    g: float,
    omega: float,
) -> tuple[float, float, float, float, float, float]:
    """:func:`point_mass_rates_of` with the cosines and sines of the latitude, the
    flight-path angle, the heading and the bank angle given."""
    w = omega
    return (
        v * sg,
        v * cg * sp / (r * cl_),
        v * cg * cp / r,
        -drag - g * sg + w * w * r * cl_ * (sg * cl_ - cg * sl * cp),
        (
            lift * cb
            + (v * v / r - g) * cg
            + 2.0 * w * v * cl_ * sp
            + w * w * r * cl_ * (cg * cl_ + sg * cp * sl)
        )
        / v,
        (
            lift * sb / cg
            + v * v / r * cg * sp * sl / cl_
            - 2.0 * w * v * (sg / cg * cp * cl_ - sl)
            + w * w * r * sp * sl * cl_ / cg
        )
        / v,
    )


@njit(cache=True, error_model="numpy")
def _path_of(
    v: float, lift: float, drag: float, alpha: float, rho: float, m: np.ndarray
) -> tuple[float, float, float]:
    """Heat rate ``k_Q sqrt(rho) V^n`` [W/m^2], normal load [g], dynamic pressure [Pa]."""
    heat = m[P_KQ] * math.sqrt(rho) * v ** m[P_NQ]
    load = abs(lift * math.cos(alpha) + drag * math.sin(alpha)) / m[P_G0]
    return heat, load, 0.5 * rho * v * v


@njit(cache=True, error_model="numpy")
def _path(
    x: np.ndarray,
    p: np.ndarray,
    tables: Tables,
) -> tuple[float, float, float, float, float, float]:
    """Angle of attack, Mach, density, heat rate, normal load [g], dynamic pressure."""
    return path_packed(x, pack(p, tables))


@njit(cache=True, error_model="numpy")
def path_packed(x: np.ndarray, m: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """:func:`_path` with the model packed once (:func:`pack`)."""
    lift, drag, alpha, mach, rho = _aero_packed(x[0], x[3], m)
    heat, load, qdyn = _path_of(x[3], lift, drag, alpha, rho, m)
    return alpha, mach, rho, heat, load, qdyn


@njit(cache=True, error_model="numpy")
def _raised(
    maxima: tuple[float, float, float, float, float, float],
    t: float,
    heat: float,
    load: float,
    qdyn: float,
) -> tuple[float, float, float, float, float, float]:
    """(heat rate, its time, load, its time, dynamic pressure, its time) with the values
    at time t counted."""
    q_max, q_t, n_max, n_t, p_max, p_t = maxima
    if heat > q_max:
        q_max, q_t = heat, t
    if load > n_max:
        n_max, n_t = load, t
    if qdyn > p_max:
        p_max, p_t = qdyn, t
    return q_max, q_t, n_max, n_t, p_max, p_t


# A state of the flight loop: radius, longitude, latitude, speed, flight-path angle, heading.
State = tuple[float, float, float, float, float, float]


@njit(cache=True, error_model="numpy")
def _first_bank_sign(x: np.ndarray, m: np.ndarray) -> float:
    """The bank sign at the start: the configured one, or for a guided entry the one that
    turns the heading towards the landing site."""
    sign = m[P_BANK_SIGN]
    if m[P_GUIDED] > 0.5:
        _, bearing = range_and_bearing(x[2], x[1], m[P_TARGET_LAT], m[P_TARGET_LON])
        sign = -1.0 if _wrap(x[5] - bearing) > 0.0 else 1.0
    return sign


@njit(cache=True, error_model="numpy")
def _guided_bank_sign(
    sign: float, reversals: int, psi: float, bearing: float, togo: float, m: np.ndarray
) -> tuple[float, int]:
    """The bank sign and reversal count after the corridor test: the sign reverses when the
    heading error to the site leaves the corridor, which narrows with the range to go."""
    frac = min(togo / m[P_CORRIDOR_RANGE], 1.0)
    corridor = m[P_CORRIDOR_MIN] + (m[P_CORRIDOR_MAX] - m[P_CORRIDOR_MIN]) * frac
    error = _wrap(psi - bearing)
    if error > corridor and sign > 0.0:
        return -1.0, reversals + 1
    if error < -corridor and sign < 0.0:
        return 1.0, reversals + 1
    return sign, reversals


@njit(cache=True, error_model="numpy")
def _rk4_step(
    state: State, lift: float, drag: float, sign: float, start: StepStart, dt: float, m: np.ndarray
) -> State:
    """One RK4 step from ``state``, whose aerodynamics (``lift``, ``drag``) and angles'
    cosines and sines (``start``) are known; the bank sign is held over the step."""
    r, lon, lat, v, gamma, psi = state
    mu, omega = m[P_MU], m[P_OMEGA]
    k1 = point_mass_rates_trig(
        r, v, start[4], start[5], start[6], start[7], start[8], start[9],
        start[10], sign * start[11], lift, drag, mu / (r * r), omega,
    )  # fmt: skip
    h = 0.5 * dt
    s2 = (r + h * k1[0], lat + h * k1[2], v + h * k1[3], gamma + h * k1[4], psi + h * k1[5])
    a2 = _aero_packed(s2[0], s2[2], m)
    k2 = _stage(s2, a2, _bank_magnitude(s2[2], m), sign, mu, omega, start)
    s3 = (r + h * k2[0], lat + h * k2[2], v + h * k2[3], gamma + h * k2[4], psi + h * k2[5])
    a3 = _aero_packed(s3[0], s3[2], m)
    k3 = _stage(s3, a3, _bank_magnitude(s3[2], m), sign, mu, omega, start)
    s4 = (
        r + dt * k3[0], lat + dt * k3[2], v + dt * k3[3], gamma + dt * k3[4],
        psi + dt * k3[5],
    )  # fmt: skip
    a4 = _aero_packed(s4[0], s4[2], m)
    k4 = _stage(s4, a4, _bank_magnitude(s4[2], m), sign, mu, omega, start)
    w = dt / 6.0
    return (
        r + w * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
        lon + w * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        lat + w * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
        v + w * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
        gamma + w * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4]),
        psi + w * (k1[5] + 2.0 * k2[5] + 2.0 * k3[5] + k4[5]),
    )


# The status of a step after which the flight goes on (:func:`_advanced`).
_FLYING = -1


@njit(cache=True, error_model="numpy")
def _advanced(
    state: State, new: State, t: float, dt: float, m: np.ndarray
) -> tuple[int, State, float]:
    """The status, state and time [s] after the step from ``state`` at ``t`` to ``new``:
    ``DIVERGED`` (the step's start kept) on a non-finite value, ``TERMINAL`` at the
    terminal speed (interpolated within the step), ``CRASHED`` at the ground, ``SKIPPED``
    above the skip radius and climbing, else :data:`_FLYING`."""
    finite = True
    for value in new:
        finite = finite and math.isfinite(value)
    if not finite:
        return DIVERGED, state, t
    if new[3] <= m[P_V_END]:
        at_end, f = _at_terminal_speed(state, new, m[P_V_END])
        return TERMINAL, at_end, t + f * dt
    t += dt
    if new[0] <= m[P_RADIUS]:
        return CRASHED, new, t
    if new[0] > m[P_SKIP_RADIUS] and new[4] > 0.0:
        return SKIPPED, new, t
    return _FLYING, new, t


@njit(cache=True, error_model="numpy")
def _at_terminal_speed(state: State, new: State, v_end: float) -> tuple[State, float]:
    """The state where the speed crosses ``v_end`` within the step from ``state`` to
    ``new`` (linear interpolation), and the step's fraction there."""
    r, lon, lat, v, gamma, psi = state
    f = (v - v_end) / (v - new[3])
    return (
        r + f * (new[0] - r),
        lon + f * (new[1] - lon),
        lat + f * (new[2] - lat),
        v + f * (new[3] - v),
        gamma + f * (new[4] - gamma),
        psi + f * (new[5] - psi),
    ), f


@njit(cache=True, error_model="numpy", inline="always")
def _record_row(
    history: np.ndarray,
    n: int,
    t: float,
    state: State,
    path: tuple[float, float, float, float, float, float, float, float],
) -> None:
    """Row ``n`` of the history (:data:`HISTORY_COLUMNS`): the time, the state, then the
    angle of attack, bank, Mach, density, heat rate, load, dynamic pressure, range to go."""
    history[n, 0] = t
    history[n, 1], history[n, 2], history[n, 3] = state[0], state[1], state[2]
    history[n, 4], history[n, 5], history[n, 6] = state[3], state[4], state[5]
    for k in range(8):
        history[n, 7 + k] = path[k]


@njit(cache=True, error_model="numpy")
def _end_point(
    history: np.ndarray,
    n: int,
    record: bool,
    t: float,
    state: State,
    sign: float,
    maxima: tuple[float, float, float, float, float, float],
    m: np.ndarray,
) -> tuple[tuple[float, float, float, float, float, float], int]:
    """The end point (e.g. interpolated to the terminal speed) counted for the maxima
    too, and recorded: the maxima and the number of history rows."""
    r, lon, lat, v, _, _ = state
    lift, drag, alpha, mach, rho = _aero_packed(r, v, m)
    heat, load, qdyn = _path_of(v, lift, drag, alpha, rho, m)
    maxima = _raised(maxima, t, heat, load, qdyn)
    if record:
        angle, _ = range_and_bearing(lat, lon, m[P_TARGET_LAT], m[P_TARGET_LON])
        sigma = sign * _bank_magnitude(v, m)
        togo = angle * m[P_RADIUS]
        _record_row(history, n, t, state, (alpha, sigma, mach, rho, heat, load, qdyn, togo))
        n += 1
    return maxima, n


@njit(cache=True, nogil=True, error_model="numpy")
def fly(
    x0: np.ndarray,
    p: np.ndarray,
    tables: Tables,
    record: bool,
) -> tuple[int, float, np.ndarray, np.ndarray, int, np.ndarray, int]:
    """Integrate one entry; returns (status, t, final state, maxima, reversals, history, n).

    ``maxima``: heat rate [W/m^2], its time, load [g], its time, dynamic pressure
    [Pa], its time, largest |bank| [rad].
    """
    m = pack(p, tables)
    dt = m[P_STEP]
    history = np.zeros((int(m[P_MAX_TIME] / dt) + 2 if record else 1, 15))
    maxima = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    max_bank = 0.0
    x = x0.copy()
    t = 0.0
    sign = _first_bank_sign(x, m)
    guided = m[P_GUIDED] > 0.5
    site_lat, site_lon = m[P_TARGET_LAT], m[P_TARGET_LON]
    reversals, n, status = 0, 0, TIME_LIMIT
    cos_site, sin_site = math.cos(site_lat), math.sin(site_lat)
    # The state and the stages as scalars: no array crosses a call in the loop.
    state = (x[0], x[1], x[2], x[3], x[4], x[5])
    while t < m[P_MAX_TIME]:
        r, lon, lat, v, gamma, psi = state
        magnitude = _bank_magnitude(v, m)
        start = _start_of_step(lat, gamma, psi, magnitude)
        angle, bearing = _range_and_bearing_trig(
            lat, lon, start[4], start[5], site_lat, site_lon, cos_site, sin_site
        )
        togo = angle * m[P_RADIUS]
        if guided:
            sign, reversals = _guided_bank_sign(sign, reversals, psi, bearing, togo, m)
        sigma = sign * magnitude
        # One aerodynamic evaluation at x serves the path quantities and the first stage.
        lift, drag, alpha, mach, rho = _aero_packed(r, v, m)
        heat, load, qdyn = _path_of(v, lift, drag, alpha, rho, m)
        maxima = _raised(maxima, t, heat, load, qdyn)
        max_bank = max(max_bank, abs(sigma))
        if record:
            _record_row(history, n, t, state, (alpha, sigma, mach, rho, heat, load, qdyn, togo))
        n += 1
        new = _rk4_step(state, lift, drag, sign, start, dt, m)
        ended, state, t = _advanced(state, new, t, dt, m)
        if ended != _FLYING:
            status = ended
            break
    x[0], x[1], x[2], x[3], x[4], x[5] = state
    maxima, n = _end_point(history, n, record, t, state, sign, maxima, m)
    out = np.empty(7)
    out[:6] = maxima
    out[6] = max_bank
    return status, t, x, out, reversals, history, n
