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
(benchmarks/mission.py, issue 20).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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
def _poly(c: np.ndarray, a: float, m: float) -> float:
    total = 0.0
    ai = 1.0
    for i in range(c.shape[0]):
        mj = 1.0
        for j in range(c.shape[1]):
            total += c[i, j] * ai * mj
            mj *= m
        ai *= a
    return total


@njit(cache=True, error_model="numpy")
def _atmosphere(
    h: float, p: np.ndarray, log_rho: np.ndarray, sound: np.ndarray
) -> tuple[float, float]:
    if p[P_ATM_MODEL] > 0.5:
        return p[P_RHO0] * math.exp(-max(h, 0.0) / p[P_SCALE_HEIGHT]), p[P_SOUND]
    step = p[P_ATM_STEP]
    last = log_rho.shape[0] - 2
    x = min(max(h, 0.0), step * (last + 1)) / step
    k = min(int(x), last)
    f = x - k
    rho = math.exp(log_rho[k] + f * (log_rho[k + 1] - log_rho[k]))
    return rho, sound[k] + f * (sound[k + 1] - sound[k])


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
    dlon = lon2 - lon1
    cos_lat1 = math.cos(lat1)
    s = math.sin(0.5 * (lat2 - lat1)) ** 2 + cos_lat1 * cos_lat2 * math.sin(0.5 * dlon) ** 2
    angle = 2.0 * math.asin(math.sqrt(min(max(s, 0.0), 1.0)))
    bearing = math.atan2(
        math.sin(dlon) * cos_lat2,
        cos_lat1 * sin_lat2 - math.sin(lat1) * cos_lat2 * math.cos(dlon),
    )
    return angle, bearing


@njit(cache=True, error_model="numpy")
def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, error_model="numpy")
def _interp(x: float, xs: np.ndarray, ys: np.ndarray) -> float:
    """Piecewise-linear, held constant outside the nodes."""
    if x <= xs[0]:
        return ys[0]
    n = xs.shape[0]
    if x >= xs[n - 1]:
        return ys[n - 1]
    k = 0
    while xs[k + 1] < x:
        k += 1
    return ys[k] + (ys[k + 1] - ys[k]) * (x - xs[k]) / (xs[k + 1] - xs[k])


@njit(cache=True, error_model="numpy")
def _coefficients(cl: np.ndarray, cd: np.ndarray, a: float, m: float) -> tuple[float, float]:
    """Lift and drag coefficients: both polynomials in one pass over the powers."""
    c_lift = 0.0
    c_drag = 0.0
    ai = 1.0
    for i in range(cl.shape[0]):
        mj = 1.0
        for j in range(cl.shape[1]):
            term = ai * mj
            c_lift += cl[i, j] * term
            c_drag += cd[i, j] * term
            mj *= m
        ai *= a
    return c_lift, c_drag


@njit(cache=True, error_model="numpy")
def _aero(
    x: np.ndarray,
    p: np.ndarray,
    tables: Tables,
) -> tuple[float, float, float, float, float]:
    """Lift and drag accelerations, angle of attack, Mach and density at state x."""
    cl, cd, mach_nodes, alpha_nodes, log_rho, sound = tables
    h = x[0] - p[P_RADIUS]
    rho, a = _atmosphere(h, p, log_rho, sound)
    mach = x[3] / a
    alpha = _interp(mach, mach_nodes, alpha_nodes)
    q = 0.5 * rho * x[3] * x[3] / p[P_MASS_AREA]
    c_lift, c_drag = _coefficients(cl, cd, alpha * p[P_ALPHA_SCALE], mach)
    return q * c_lift, q * c_drag, alpha, mach, rho


@njit(cache=True, error_model="numpy")
def _bank_magnitude(v: float, p: np.ndarray) -> float:
    span = p[P_V_START] - p[P_V_END]
    frac = 0.0 if span <= 0.0 else min(max((p[P_V_START] - v) / span, 0.0), 1.0)
    sigma = p[P_SIGMA0] + (p[P_SIGMA1] - p[P_SIGMA0]) * frac
    return min(max(sigma, 0.0), p[P_SIGMA_MAX])


@njit(cache=True, error_model="numpy")
def _derivatives(
    x: np.ndarray,
    sign: float,
    p: np.ndarray,
    tables: Tables,
    out: np.ndarray,
) -> None:
    lift, drag, _, _, _ = _aero(x, p, tables)
    _rates(x, sign, lift, drag, p, out)


@njit(cache=True, error_model="numpy")
def _rates(
    x: np.ndarray, sign: float, lift: float, drag: float, p: np.ndarray, out: np.ndarray
) -> None:
    """The state derivatives (module equations) with the lift and drag at x given."""
    r, v = x[0], x[3]
    # The magnitude follows the stage's speed (it is a function of the state); only
    # the sign, a guidance decision, is held over the step.
    sigma = sign * _bank_magnitude(v, p)
    point_mass_rates(r, x[2], v, x[4], x[5], lift, drag, sigma, p[P_MU] / (r * r), p[P_OMEGA], out)


@njit(cache=True, error_model="numpy")
def point_mass_rates(
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
    out: np.ndarray,
) -> None:
    """d/dt of (r or h, lon, lat, V, gamma, psi): the module equations (Vinh, Busemann &
    Culp 1980, ch. 2), radius r [m], speed [m/s], angles [rad], lift and drag
    accelerations and gravity g [m/s^2], Earth rate omega [rad/s]. The same primitive for
    the guided entry and the optimal entry's compiled re-flight."""
    w = omega
    cg, sg = math.cos(gamma), math.sin(gamma)
    cl_, sl = math.cos(lat), math.sin(lat)
    cp, sp = math.cos(psi), math.sin(psi)
    out[0] = v * sg
    out[1] = v * cg * sp / (r * cl_)
    out[2] = v * cg * cp / r
    out[3] = -drag - g * sg + w * w * r * cl_ * (sg * cl_ - cg * sl * cp)
    out[4] = (
        lift * math.cos(bank)
        + (v * v / r - g) * cg
        + 2.0 * w * v * cl_ * sp
        + w * w * r * cl_ * (cg * cl_ + sg * cp * sl)
    ) / v
    out[5] = (
        lift * math.sin(bank) / cg
        + v * v / r * cg * sp * sl / cl_
        - 2.0 * w * v * (sg / cg * cp * cl_ - sl)
        + w * w * r * sp * sl * cl_ / cg
    ) / v


@njit(cache=True, error_model="numpy")
def _path(
    x: np.ndarray,
    p: np.ndarray,
    tables: Tables,
) -> tuple[float, float, float, float, float, float]:
    """Angle of attack, Mach, density, heat rate, normal load [g], dynamic pressure."""
    lift, drag, alpha, mach, rho = _aero(x, p, tables)
    return _path_from(x, p, lift, drag, alpha, mach, rho)


@njit(cache=True, error_model="numpy")
def _path_from(
    x: np.ndarray, p: np.ndarray, lift: float, drag: float, alpha: float, mach: float, rho: float
) -> tuple[float, float, float, float, float, float]:
    """:func:`_path` from the aerodynamics at x."""
    heat = p[P_KQ] * math.sqrt(rho) * x[3] ** p[P_NQ]
    load = abs(lift * math.cos(alpha) + drag * math.sin(alpha)) / p[P_G0]
    return alpha, mach, rho, heat, load, 0.5 * rho * x[3] * x[3]


@njit(cache=True, error_model="numpy")
def _update_maxima(maxima: np.ndarray, t: float, heat: float, load: float, qdyn: float) -> None:
    if heat > maxima[0]:
        maxima[0], maxima[1] = heat, t
    if load > maxima[2]:
        maxima[2], maxima[3] = load, t
    if qdyn > maxima[4]:
        maxima[4], maxima[5] = qdyn, t


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
    dt = p[P_STEP]
    n_max = int(p[P_MAX_TIME] / dt) + 2
    history = np.zeros((n_max if record else 1, 15))
    maxima = np.zeros(7)
    x = x0.copy()
    new, stage = np.empty(6), np.empty(6)
    k1, k2, k3, k4 = np.empty(6), np.empty(6), np.empty(6), np.empty(6)
    t = 0.0
    sign = p[P_BANK_SIGN]
    if p[P_GUIDED] > 0.5:
        _, bearing = range_and_bearing(x[2], x[1], p[P_TARGET_LAT], p[P_TARGET_LON])
        sign = -1.0 if _wrap(x[5] - bearing) > 0.0 else 1.0
    reversals = 0
    n = 0
    status = TIME_LIMIT
    cos_site, sin_site = math.cos(p[P_TARGET_LAT]), math.sin(p[P_TARGET_LAT])
    while t < p[P_MAX_TIME]:
        angle, bearing = _range_and_bearing(
            x[2], x[1], p[P_TARGET_LAT], p[P_TARGET_LON], cos_site, sin_site
        )
        togo = angle * p[P_RADIUS]
        if p[P_GUIDED] > 0.5:
            frac = min(togo / p[P_CORRIDOR_RANGE], 1.0)
            corridor = p[P_CORRIDOR_MIN] + (p[P_CORRIDOR_MAX] - p[P_CORRIDOR_MIN]) * frac
            error = _wrap(x[5] - bearing)
            if error > corridor and sign > 0.0:
                sign = -1.0
                reversals += 1
            elif error < -corridor and sign < 0.0:
                sign = 1.0
                reversals += 1
        sigma = sign * _bank_magnitude(x[3], p)
        # One aerodynamic evaluation at x serves the path quantities and the first stage.
        lift, drag, alpha, mach, rho = _aero(x, p, tables)
        alpha, mach, rho, heat, load, qdyn = _path_from(x, p, lift, drag, alpha, mach, rho)
        _update_maxima(maxima, t, heat, load, qdyn)
        maxima[6] = max(maxima[6], abs(sigma))
        if record:
            history[n, 0] = t
            history[n, 1:7] = x
            history[n, 7] = alpha
            history[n, 8] = sigma
            history[n, 9] = mach
            history[n, 10] = rho
            history[n, 11] = heat
            history[n, 12] = load
            history[n, 13] = qdyn
            history[n, 14] = togo
        n += 1
        _rates(x, sign, lift, drag, p, k1)
        for i in range(6):
            stage[i] = x[i] + 0.5 * dt * k1[i]
        _derivatives(stage, sign, p, tables, k2)
        for i in range(6):
            stage[i] = x[i] + 0.5 * dt * k2[i]
        _derivatives(stage, sign, p, tables, k3)
        for i in range(6):
            stage[i] = x[i] + dt * k3[i]
        _derivatives(stage, sign, p, tables, k4)
        finite = True
        for i in range(6):
            new[i] = x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            finite = finite and math.isfinite(new[i])
        if not finite:
            status = DIVERGED
            break
        if new[3] <= p[P_V_END]:
            f = (x[3] - p[P_V_END]) / (x[3] - new[3])
            for i in range(6):
                x[i] += f * (new[i] - x[i])
            t += f * dt
            status = TERMINAL
            break
        x[:] = new
        t += dt
        if x[0] <= p[P_RADIUS]:
            status = CRASHED
            break
        if x[0] > p[P_SKIP_RADIUS] and x[4] > 0.0:
            status = SKIPPED
            break
    # The end point (e.g. interpolated to the terminal speed) counts for the maxima too.
    alpha, mach, rho, heat, load, qdyn = _path(x, p, tables)
    _update_maxima(maxima, t, heat, load, qdyn)
    if record:
        history[n, 0] = t
        history[n, 1:7] = x
        angle, _ = range_and_bearing(x[2], x[1], p[P_TARGET_LAT], p[P_TARGET_LON])
        history[n, 7] = alpha
        history[n, 8] = sign * _bank_magnitude(x[3], p)
        history[n, 9] = mach
        history[n, 10] = rho
        history[n, 11] = heat
        history[n, 12] = load
        history[n, 13] = qdyn
        history[n, 14] = angle * p[P_RADIUS]
        n += 1
    return status, t, x, maxima, reversals, history, n
