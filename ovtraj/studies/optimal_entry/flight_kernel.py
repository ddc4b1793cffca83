"""The numpy flight model of :mod:`.flight`, compiled with numba (the feasibility check
and the mesh refinement fly the controls again many times a solve).

The same equations as :class:`~ovtraj.studies.optimal_entry.flight.PointMass` (3-DOF
point mass over a spherical, optionally rotating Earth; Vinh, Busemann & Culp 1980,
ch. 2), the same atmosphere formulas as :mod:`ovtraj.astro.atmosphere` (US76 closed form
below 86 km, NOAA-S/T 76-1562 eqs. 18, 23, 33a/b, 42, 50; its log-linear density nodes
and temperature segments above; or the exponential model), and the same integrator as
scipy's ``solve_ivp(method="DOP853")`` (Dormand-Prince 8(5,3), Hairer, Norsett & Wanner,
*Solving ODEs I*, 1993, sec. II.10, with scipy's step-size control and its
coefficients), in one compiled loop: a 2000 s re-flight in milliseconds instead of
~0.1 s of Python right-hand sides. Controls are piecewise polynomials in time
(:class:`ControlTable`: a cubic spline's or linear interpolation's pieces), held at the
ends and clipped to their bounds. A terminal event (the ground, a terminal energy) ends
the flight at its root, found by bisection on the last step's length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.integrate._ivp import dop853_coefficients as _dop853

from ovtraj.astro.atmosphere import ExponentialAtmosphere, US76Atmosphere
from ovtraj.reentry.dynamics import point_mass_rates_of
from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["ControlTable", "KernelFlight", "fly_compiled", "model_arrays"]

Array = np.ndarray
Arrays = tuple  # the controls' and the model's arrays, passed whole to the kernels

# Status codes of a compiled flight.
COMPLETED, GROUND, TERMINAL_ENERGY, FAILED = 0, 1, 2, 3
STATUS_TEXT = {
    COMPLETED: "completed",
    GROUND: "ground",
    TERMINAL_ENERGY: "terminal energy",
    FAILED: "integration failed: step size below its minimum",
}

# Indices of the float parameter vector.
(
    P_MU,
    P_RADIUS,
    P_OMEGA,
    P_G0,
    P_MASS,
    P_AREA,
    P_ALPHA_SCALE,
    P_CONSTANT_GRAVITY,
    P_EXPONENTIAL,
    P_RHO0,
    P_SCALE_HEIGHT,
    P_SOUND,
    P_HEAT_K,
    P_HEAT_M,
    P_HEAT_N,
    P_HAS_HEAT,
    P_NORMAL_LOAD,
    P_TOP,
    N_PARAMS,
) = range(19)

# Indices of the US76 scalar vector.
(
    U_EARTH_RADIUS,
    U_HYDROSTATIC,
    U_GAS,
    U_WEIGHT,
    U_GAMMA,
    U_Z7,
    U_Z8,
    U_Z9,
    U_Z10,
    U_T86,
    U_A86,
    U_ELLIPSE_CENTRE,
    U_ELLIPSE_AMPLITUDE,
    U_ELLIPSE_SEMI_AXIS,
    U_T9,
    U_LINEAR_GRADIENT,
    U_T10,
    U_EXOSPHERIC,
    U_EXPONENTIAL_RATE,
    N_US76,
) = range(20)

_A = np.ascontiguousarray(_dop853.A[: _dop853.N_STAGES, : _dop853.N_STAGES])
_B = np.ascontiguousarray(_dop853.B)
_C = np.ascontiguousarray(_dop853.C[: _dop853.N_STAGES])
_E3 = np.ascontiguousarray(_dop853.E3)
_E5 = np.ascontiguousarray(_dop853.E5)
# scipy's RungeKutta step-size control (scipy/integrate/_ivp/rk.py) for order 7 errors.
_SAFETY, _MIN_FACTOR, _MAX_FACTOR, _ERROR_EXPONENT = 0.9, 0.2, 10.0, -1.0 / 8.0
_ORDER = 7


@dataclass(frozen=True)
class ControlTable:
    """Angle of attack and bank [rad] as piecewise polynomials of time.

    ``x``: (n,) increasing breakpoints [s]; ``c``: (k + 1, n - 1) coefficients, highest
    power first, of ``t - x[i]`` on ``[x[i], x[i + 1]]`` (scipy's ``PPoly`` layout);
    values are held beyond the ends and clipped to ``[lower, upper]``.
    """

    alpha_x: NDArray[np.float64]
    alpha_c: NDArray[np.float64]
    bank_x: NDArray[np.float64]
    bank_c: NDArray[np.float64]
    lower: NDArray[np.float64]  # (alpha, bank)
    upper: NDArray[np.float64]

    @classmethod
    def constant(cls, alpha: float, bank: float) -> ControlTable:
        x = np.array([0.0, 1.0])
        return cls(
            x,
            np.array([[alpha]]),
            x,
            np.array([[bank]]),
            np.array([-math.inf, -math.inf]),
            np.array([math.inf, math.inf]),
        )

    def __call__(self, t: float) -> tuple[float, float]:
        return (
            _piecewise(t, self.alpha_x, self.alpha_c, self.lower[0], self.upper[0]),
            _piecewise(t, self.bank_x, self.bank_c, self.lower[1], self.upper[1]),
        )


@dataclass(frozen=True)
class KernelFlight:
    t: NDArray[np.float64]
    y: NDArray[np.float64]  # rows of (h, lon, lat, V, gamma, psi), SI
    path: NDArray[np.float64]  # rows of (heat rate [W/m^2], load [g], dynamic pressure [Pa])
    status: str


def model_arrays(problem: EntryProblem) -> tuple[NDArray, ...]:
    """(parameters, CL, CD, heat-rate alpha polynomial, US76 scalars, US76 arrays...)."""
    p = np.zeros(N_PARAMS)
    p[P_MU], p[P_RADIUS], p[P_OMEGA], p[P_G0] = (
        problem.mu,
        problem.radius,
        problem.omega,
        problem.g0,
    )
    p[P_MASS], p[P_AREA], p[P_ALPHA_SCALE] = problem.mass, problem.area, problem.alpha_scale
    p[P_CONSTANT_GRAVITY] = 1.0 if problem.gravity == "constant" else 0.0
    atm = problem.atmosphere
    p[P_TOP] = problem.atmosphere_top_m
    if isinstance(atm, ExponentialAtmosphere):
        p[P_EXPONENTIAL] = 1.0
        p[P_RHO0], p[P_SCALE_HEIGHT], p[P_SOUND] = (
            atm.rho0_kg_m3,
            atm.scale_height_m,
            atm.speed_of_sound_m_s,
        )
    if problem.heat_coefficient is not None:
        p[P_HAS_HEAT] = 1.0
        p[P_HEAT_K] = problem.heat_coefficient
    p[P_HEAT_M], p[P_HEAT_N] = problem.heat_density_exponent, problem.heat_speed_exponent
    p[P_NORMAL_LOAD] = 1.0 if problem.load_definition == "normal" else 0.0
    us76, arrays = _us76_arrays(atm)
    return (
        p,
        _owned(problem.cl),
        _owned(problem.cd),
        _owned(problem.heat_alpha_polynomial),
        us76,
        *arrays,
    )


def _owned(values: NDArray) -> NDArray:
    """A writable C-contiguous float copy: numba compiles once per array layout and
    writability, so every kernel argument has the same kind (the US76 arrays are
    read-only)."""
    return np.array(values, dtype=float, order="C", copy=True)


def _us76_arrays(atm: object) -> tuple[NDArray, tuple[NDArray, ...]]:
    u = np.zeros(N_US76)
    if not isinstance(atm, US76Atmosphere):
        empty = np.zeros(2)
        return u, (empty, empty, empty, empty, empty, empty, empty)
    # The model's own constants and layer arrays (ovtraj/astro/atmosphere.py).
    u[U_EARTH_RADIUS] = atm._earth_radius
    u[U_HYDROSTATIC] = atm._hydrostatic_constant
    u[U_GAS] = atm._gas_constant
    u[U_WEIGHT] = atm._molecular_weight
    u[U_GAMMA] = atm._gamma
    u[U_Z7] = atm.lower_region_top_altitude_m
    u[U_Z8], u[U_Z9], u[U_Z10] = atm._z8, atm._z9, atm._z10
    u[U_T86], u[U_A86] = atm.temperature_86km_K, atm.speed_of_sound_86km_m_s
    u[U_ELLIPSE_CENTRE] = atm._ellipse_centre
    u[U_ELLIPSE_AMPLITUDE] = atm._ellipse_amplitude
    u[U_ELLIPSE_SEMI_AXIS] = atm._ellipse_semi_axis
    u[U_T9], u[U_LINEAR_GRADIENT], u[U_T10] = atm._t9, atm._linear_gradient, atm._t10
    u[U_EXOSPHERIC], u[U_EXPONENTIAL_RATE] = atm._exospheric_temperature, atm._exponential_rate
    arrays = tuple(
        _owned(a)
        for a in (
            atm.layer_base_geopotential_height_m,
            atm.layer_lapse_rate_K_per_m,
            atm.layer_base_temperature_K,
            atm.layer_base_pressure_Pa,
            atm.node_altitude_m,
            atm.node_log_density,
            atm._node_slope,
        )
    )
    return u, arrays


# -- compiled model ------------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _piecewise(t: float, x: Array, c: Array, lower: float, upper: float) -> float:
    n = x.shape[0]
    if t <= x[0]:
        k, dt = 0, 0.0
    elif t >= x[n - 1]:
        k, dt = n - 2, x[n - 1] - x[n - 2]
    else:
        k = np.searchsorted(x, t, side="right") - 1
        dt = t - x[k]
    value = 0.0
    for j in range(c.shape[0]):
        value = value * dt + c[j, k]
    return min(max(value, lower), upper)


@njit(cache=True, error_model="numpy")
def _us76(
    z: float,
    u: Array,
    base_h: Array,
    lapse: Array,
    base_t: Array,
    base_p: Array,
    node_z: Array,
    node_logrho: Array,
    slope: Array,
) -> tuple[float, float]:
    """US76 density [kg/m^3] and speed of sound [m/s] at geometric altitude z [m]."""
    if z < u[U_Z7]:
        h = u[U_EARTH_RADIUS] * z / (u[U_EARTH_RADIUS] + z)
        layer = np.searchsorted(base_h, h, side="right") - 1
        above = h - base_h[layer]
        t_m = base_t[layer] + lapse[layer] * above
        if lapse[layer] == 0.0:
            pressure = base_p[layer] * math.exp(-u[U_HYDROSTATIC] * above / base_t[layer])
        else:
            pressure = base_p[layer] * (base_t[layer] / t_m) ** (u[U_HYDROSTATIC] / lapse[layer])
        rho = pressure * u[U_WEIGHT] / (u[U_GAS] * t_m)
        return rho, math.sqrt(u[U_GAMMA] * u[U_GAS] * t_m / u[U_WEIGHT])
    node = min(np.searchsorted(node_z, z, side="right") - 1, slope.shape[0] - 1)
    rho = math.exp(node_logrho[node] + slope[node] * (z - node_z[node]))
    if z <= u[U_Z8]:
        temperature = u[U_T86]
    elif z <= u[U_Z9]:
        x = (z - u[U_Z8]) / u[U_ELLIPSE_SEMI_AXIS]
        temperature = u[U_ELLIPSE_CENTRE] + u[U_ELLIPSE_AMPLITUDE] * math.sqrt(1.0 - x * x)
    elif z <= u[U_Z10]:
        temperature = u[U_T9] + u[U_LINEAR_GRADIENT] * (z - u[U_Z9])
    else:
        r0, z10 = u[U_EARTH_RADIUS], u[U_Z10]
        xi = (z - z10) * (r0 + z10) / (r0 + z)
        temperature = u[U_EXOSPHERIC] - (u[U_EXOSPHERIC] - u[U_T10]) * math.exp(
            -u[U_EXPONENTIAL_RATE] * xi
        )
    return rho, u[U_A86] * math.sqrt(temperature / u[U_T86])


@njit(cache=True, error_model="numpy")
def _poly2(c: Array, a: float, m: float) -> float:
    total = 0.0
    for i in range(c.shape[0] - 1, -1, -1):
        row = 0.0
        for j in range(c.shape[1] - 1, -1, -1):
            row = row * m + c[i, j]
        total = total * a + row
    return total


@njit(cache=True, error_model="numpy")
def _path(
    h: float, v: float, alpha: float, model: Arrays
) -> tuple[float, float, float, float, float]:
    """Lift and drag accelerations, heat rate, load [g] and dynamic pressure."""
    p, cl, cd, heat_poly, u, a0, a1, a2, a3, a4, a5, a6 = model
    z = min(max(h, 0.0), p[P_TOP])
    if p[P_EXPONENTIAL] > 0.5:
        rho = p[P_RHO0] * math.exp(-z / p[P_SCALE_HEIGHT])
        sound = p[P_SOUND]
    else:
        rho, sound = _us76(z, u, a0, a1, a2, a3, a4, a5, a6)
    a = alpha * p[P_ALPHA_SCALE]
    mach = v / sound
    q = 0.5 * rho * v * v
    lift = q * p[P_AREA] * _poly2(cl, a, mach) / p[P_MASS]
    drag = q * p[P_AREA] * _poly2(cd, a, mach) / p[P_MASS]
    heat = 0.0
    if p[P_HAS_HEAT] > 0.5:
        shape = 0.0
        for k in range(heat_poly.shape[0] - 1, -1, -1):
            shape = shape * a + heat_poly[k]
        heat = p[P_HEAT_K] * rho ** p[P_HEAT_M] * v ** p[P_HEAT_N] * shape
    if p[P_NORMAL_LOAD] > 0.5:
        load = (lift * math.cos(alpha) + drag * math.sin(alpha)) / p[P_G0]
    else:
        load = math.hypot(lift, drag) / p[P_G0]
    return lift, drag, heat, load, q


@njit(cache=True, error_model="numpy")
def _rates(y: Array, alpha: float, bank: float, out: Array, model: Arrays) -> None:
    """d/dt of (h, lon, lat, V, gamma, psi): PointMass.rates."""
    p = model[0]
    h, v = y[0], y[3]
    r = p[P_RADIUS] + h
    g = p[P_G0] if p[P_CONSTANT_GRAVITY] > 0.5 else p[P_MU] / (r * r)
    lift, drag, _, _, _ = _path(h, v, alpha, model)
    out[:] = point_mass_rates_of(r, y[2], v, y[4], y[5], lift, drag, bank, g, p[P_OMEGA])


@njit(cache=True, error_model="numpy")
def _rhs(t: float, z: Array, scale: Array, out: Array, controls: Arrays, model: Arrays) -> None:
    ax, ac, bx, bc, lower, upper = controls
    alpha = _piecewise(t, ax, ac, lower[0], upper[0])
    bank = _piecewise(t, bx, bc, lower[1], upper[1])
    _rates(z * scale, alpha, bank, out, model)
    for i in range(6):
        out[i] /= scale[i]


@njit(cache=True, error_model="numpy")
def _event(
    z: Array, scale: Array, model: Arrays, stop_energy: float, use_energy: bool
) -> tuple[float, float]:
    """(ground value, energy value): the flight ends where either reaches zero."""
    p = model[0]
    h = z[0] * scale[0]
    v = z[3] * scale[3]
    if p[P_CONSTANT_GRAVITY] > 0.5:
        potential = p[P_G0] * h
    else:
        potential = p[P_MU] / p[P_RADIUS] - p[P_MU] / (p[P_RADIUS] + h)
    energy = 0.5 * v * v + potential - stop_energy if use_energy else 1.0
    return h, energy


@njit(cache=True, error_model="numpy")
def _step(
    t: float,
    z: Array,
    f: Array,
    h: float,
    scale: Array,
    controls: Arrays,
    model: Arrays,
    k: Array,
    z_new: Array,
    work: Array,
) -> None:
    """One DOP853 step (scipy's rk_step); stages in ``k``, the new state in ``z_new``."""
    k[0, :] = f
    for s in range(1, _A.shape[0]):
        for i in range(6):
            acc = 0.0
            for j in range(s):
                acc += _A[s, j] * k[j, i]
            work[i] = z[i] + h * acc
        _rhs(t + _C[s] * h, work, scale, k[s], controls, model)
    for i in range(6):
        acc = 0.0
        for j in range(_B.shape[0]):
            acc += _B[j] * k[j, i]
        z_new[i] = z[i] + h * acc
    _rhs(t + h, z_new, scale, k[_B.shape[0]], controls, model)


@njit(cache=True, error_model="numpy")
def _error_norm(k: Array, h: float, weights: Array) -> float:
    err5, err3 = 0.0, 0.0
    for i in range(6):
        e5, e3 = 0.0, 0.0
        for j in range(k.shape[0]):
            e5 += k[j, i] * _E5[j]
            e3 += k[j, i] * _E3[j]
        err5 += (e5 / weights[i]) ** 2
        err3 += (e3 / weights[i]) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    return abs(h) * err5 / math.sqrt((err5 + 0.01 * err3) * 6.0)


@njit(cache=True, error_model="numpy")
def _initial_step(
    t0: float,
    z0: Array,
    f0: Array,
    t_bound: float,
    scale: Array,
    controls: Arrays,
    model: Arrays,
    rtol: float,
    atol: float,
) -> float:
    """scipy's select_initial_step (Hairer et al. 1993, sec. II.4)."""
    d0, d1 = 0.0, 0.0
    for i in range(6):
        w = atol + abs(z0[i]) * rtol
        d0 += (z0[i] / w) ** 2
        d1 += (f0[i] / w) ** 2
    d0, d1 = math.sqrt(d0 / 6.0), math.sqrt(d1 / 6.0)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_bound - t0)
    z1 = z0 + h0 * f0
    f1 = np.empty(6)
    _rhs(t0 + h0, z1, scale, f1, controls, model)
    d2 = 0.0
    for i in range(6):
        w = atol + abs(z0[i]) * rtol
        d2 += ((f1[i] - f0[i]) / w) ** 2
    d2 = math.sqrt(d2 / 6.0) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (_ORDER + 1))
    return min(100.0 * h0, h1, t_bound - t0)


@njit(cache=True, error_model="numpy")
def _integrate(
    t0: float,
    z0: Array,
    edges: Array,
    scale: Array,
    controls: Arrays,
    model: Arrays,
    rtol: float,
    atol: float,
    stop_energy: float,
    use_energy: bool,
    cap: int,
) -> tuple[Array, Array, int]:
    """DOP853 from ``edges[0]`` through each edge, restarting there; terminal events."""
    ts = np.empty(cap)
    zs = np.empty((cap, 6))
    ts[0] = t0
    zs[0, :] = z0
    n = 1
    z = z0.copy()
    t = t0
    f = np.empty(6)
    k = np.empty((_A.shape[0] + 1, 6))
    z_new = np.empty(6)
    work = np.empty(6)
    weights = np.empty(6)
    buffers = (k, z_new, work, weights)  # a step's stages, new state and work arrays
    status = COMPLETED
    for e in range(1, edges.shape[0]):
        t_bound = edges[e]
        if t_bound <= t:
            continue
        _rhs(t, z, scale, f, controls, model)
        h_abs = _initial_step(t, z, f, t_bound, scale, controls, model, rtol, atol)
        while t < t_bound:
            ok, t_new, h, h_abs = _accepted_step(
                t, z, f, h_abs, t_bound, scale, controls, model, rtol, atol, buffers
            )
            if not ok:
                return ts[:n], zs[:n], FAILED
            ground0, energy0 = _event(z, scale, model, stop_energy, use_energy)
            ground1, energy1 = _event(z_new, scale, model, stop_energy, use_energy)
            crossed = ground0 > 0.0 and ground1 <= 0.0
            ended = use_energy and energy0 > 0.0 and energy1 <= 0.0
            if crossed or ended:
                hi = _event_root(
                    t, z, f, h, crossed, scale, controls, model, stop_energy, use_energy, buffers
                )
                if n >= cap:
                    return ts[:n], zs[:n], FAILED
                ts[n] = t + hi
                zs[n, :] = z_new
                n += 1
                return ts[:n], zs[:n], GROUND if crossed else TERMINAL_ENERGY
            t = t_new
            z[:] = z_new
            f[:] = k[_B.shape[0]]
            if n >= cap:
                return ts[:n], zs[:n], FAILED
            ts[n] = t
            zs[n, :] = z
            n += 1
    return ts[:n], zs[:n], status


@njit(cache=True, error_model="numpy")
def _accepted_step(
    t: float,
    z: Array,
    f: Array,
    h_abs: float,
    t_bound: float,
    scale: Array,
    controls: Arrays,
    model: Arrays,
    rtol: float,
    atol: float,
    buffers: Arrays,
) -> tuple[bool, float, float, float]:
    """One step from ``(t, z)`` towards ``t_bound`` under scipy's step-size control,
    retried smaller until its error is accepted: (ok, its end, its length, the next
    step's length), its stages and new state left in ``buffers``. Not ok when the step
    falls below its minimum (or is NaN)."""
    k, z_new, work, weights = buffers
    min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
    rejected = False
    while True:
        if not h_abs >= min_step:  # also a NaN step: never loop on it
            return False, t, 0.0, h_abs
        t_new = min(t + h_abs, t_bound)
        h = t_new - t
        _step(t, z, f, h, scale, controls, model, k, z_new, work)
        for i in range(6):
            weights[i] = atol + max(abs(z[i]), abs(z_new[i])) * rtol
        error = _error_norm(k, h, weights)
        if error < 1.0:
            factor = (
                _MAX_FACTOR if error == 0.0 else min(_MAX_FACTOR, _SAFETY * error**_ERROR_EXPONENT)
            )
            if rejected:
                factor = min(1.0, factor)
            return True, t_new, h, h * factor
        shrink = _SAFETY * error**_ERROR_EXPONENT
        h_abs = h * (shrink if shrink > _MIN_FACTOR else _MIN_FACTOR)  # NaN: the minimum
        rejected = True


@njit(cache=True, error_model="numpy")
def _event_root(
    t: float,
    z: Array,
    f: Array,
    h: float,
    crossed: bool,
    scale: Array,
    controls: Arrays,
    model: Arrays,
    stop_energy: float,
    use_energy: bool,
    buffers: Arrays,
) -> float:
    """The length of the step from ``(t, z)`` to the event inside a step of length ``h``
    (the ground if ``crossed``, else the terminal energy), by bisection; the state there
    left as the new state in ``buffers``."""
    k, z_new, work, weights = buffers
    lo, hi = 0.0, h
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        _step(t, z, f, mid, scale, controls, model, k, work, weights)
        g, en = _event(work, scale, model, stop_energy, use_energy)
        value = g if crossed else en
        if value > 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * max(1.0, abs(t)):
            break
    _step(t, z, f, hi, scale, controls, model, k, z_new, work)
    return hi


@njit(cache=True, error_model="numpy")
def _path_history(ts: Array, ys: Array, controls: Arrays, model: Arrays) -> Array:
    ax, ac, _, _, lower, upper = controls
    out = np.empty((ts.shape[0], 3))
    for n in range(ts.shape[0]):
        alpha = _piecewise(ts[n], ax, ac, lower[0], upper[0])
        _, _, heat, load, q = _path(ys[n, 0], ys[n, 3], alpha, model)
        out[n, 0], out[n, 1], out[n, 2] = heat, load, q
    return out


def fly_compiled(
    problem: EntryProblem,
    controls: ControlTable,
    t_end: float,
    *,
    rtol: float,
    atol: float,
    stop_energy: float | None = None,
    breaks: NDArray[np.float64] | None = None,
    start: tuple[float, NDArray[np.float64]] | None = None,
    max_points: int = 200_000,
) -> KernelFlight:
    """:func:`ovtraj.studies.optimal_entry.flight.fly`'s flight, compiled (module notes).

    ``atol`` applies to the states scaled to order one (altitude and speed by their
    initial values, as in :func:`.flight.fly`); the flight restarts at every time of
    ``breaks``; it stops at the ground or at ``stop_energy``.
    """
    t0, y0 = (0.0, problem.initial_state) if start is None else start
    initial = problem.initial_state
    scale = np.array([max(abs(initial[0]), 1.0), 1.0, 1.0, abs(initial[3]), 1.0, 1.0])
    edges = [float(t0)]
    if breaks is not None:
        edges += sorted(float(b) for b in breaks if t0 < b < t_end)
    edges.append(float(t_end))
    model = model_arrays(problem)
    tables = tuple(
        _owned(a)
        for a in (
            controls.alpha_x,
            controls.alpha_c,
            controls.bank_x,
            controls.bank_c,
            controls.lower,
            controls.upper,
        )
    )
    ts, zs, code = _integrate(
        float(t0),
        np.asarray(y0, dtype=float) / scale,
        np.array(edges),
        scale,
        tables,
        model,
        float(rtol),
        float(atol),
        0.0 if stop_energy is None else float(stop_energy),
        stop_energy is not None,
        int(max_points),
    )
    ys = zs * scale
    return KernelFlight(
        t=ts.copy(), y=ys, path=_path_history(ts, ys, tables, model), status=STATUS_TEXT[code]
    )
