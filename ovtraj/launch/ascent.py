"""Ascent of an air-launched solid rocket, a whole population of designs at once.

Dynamics (patent step 101, eq. 1): a point mass in the Earth-fixed launch frame
(:mod:`ovtraj.launch.frame`), ``m a_r = P + A + m g - m a_e - m a_c``, i.e.::

    dr/dt = v
    dv/dt = (P + A) / m + g(R) - w x (w x R) - 2 w x v        R = R0 + r
    dm/dt = -F_vac / (Isp g0)

with ``v`` the velocity relative to the rotating Earth (hence also to the air),
``g`` the two-body + J2 attraction, ``-w x (w x R)`` the transport (centrifugal)
and ``-2 w x v`` the Coriolis acceleration (Zipfel, *Modeling and Simulation of
Aerospace Vehicle Dynamics*, 2nd ed., eq. 5.32). Altitude is ``|R| - R_E`` (spherical
Earth); the US76 atmosphere co-rotates with the Earth.

Flight programme (``docs/launch.md``): free fall at ``alpha_drop``; stage 1 flies
an angle-of-attack programme, ``alpha_1`` until ``t_12`` after ignition, then
``alpha_2`` until ``t_12 + t_23``, then zero (gravity turn), each change a ramp at
the configured rate limit; stages 2 and 3 follow linear pitch programmes
``phi = phi_0 + phi_dot (t - t_ignition)`` in the launch frame (stage 2 starts
from its velocity's pitch, stage 3 from the design's ignition pitch); the coast
``t_h`` between them flies at zero angle of attack. No yaw steering: the plane is
set by the azimuth.

Integration is classical fixed-step RK4 over every design at once (rows of a
state array): each phase is cut into the same number of steps for every row,
with the step size of each row its own (coast lengths differ), so staging falls
on step boundaries. The fairing leaves when the altitude first exceeds its
threshold; the step in which that happens is redone in two parts split at the
interpolated crossing, so results stay continuous in the design variables.
``tests/test_launch_dynamics.py`` checks the scheme against scipy's DOP853.

Along with the motion the state carries the speed budget in the inertial frame:
``d|V|/dt = F_vac/m - p_a A_e/m - F (1 - cos(P, V))/m - (-A.V/|V|)/m - (-g.V/|V|)``
(ideal, back-pressure, steering, aerodynamic and gravity terms), so that the
speed gained equals the rocket equation minus the losses.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.atmosphere import TabulatedAtmosphere
from ovtraj.astro.constants import EarthModel
from ovtraj.launch.frame import earth_rate_in_launch_frame, launch_frame_axes, launch_to_ecef
from ovtraj.launch.vehicle import LauncherModel

# State layout: position (3), velocity (3), mass, then the speed budget integrals.
POS = slice(0, 3)
VEL = slice(3, 6)
MASS = 6
IDEAL, GRAVITY, AERO, STEERING, BACK_PRESSURE = 7, 8, 9, 10, 11
STATE_SIZE = 12

# Column order of a design array (SI, absolute azimuth).
AZIMUTH, ALPHA_1, T_12, ALPHA_2, T_23, COAST, PITCH_RATE_2, PITCH_3, PITCH_RATE_3, PAYLOAD = range(
    10
)

Attitude = Callable[[NDArray, NDArray], NDArray]  # (phase time, state) -> body axis (N, 3)


@dataclass(frozen=True)
class DropPoint:
    """Release point: geocentric latitude/longitude [rad], altitude [m], Mach, fpa [rad]."""

    latitude_rad: float
    longitude_rad: float
    altitude_m: float
    mach: float
    flight_path_angle_rad: float


@dataclass(frozen=True)
class AscentModel:
    """Everything the ascent needs besides the design: vehicle, Earth, air, drop, steps."""

    launcher: LauncherModel
    earth: EarthModel
    atmosphere: TabulatedAtmosphere
    drop: DropPoint
    powered_step_s: float
    coast_step_s: float
    longest_coast_s: float  # coast steps are sized for this (the design bound)


@dataclass
class _Phase:
    name: str
    stage: int  # 0-based stage whose motor or airframe is flying
    grid: NDArray  # (steps + 1, N) attitude-clock times of the step boundaries of each row
    thrust_n: float
    mass_flow_kg_s: float
    exit_area_m2: float
    wing: bool
    axial_scale: float
    attitude: Attitude


@dataclass
class AscentOutcome:
    """End state and path figures of each design (arrays over the rows)."""

    design: NDArray
    time_s: NDArray  # drop to insertion
    state: NDArray  # (N, STATE_SIZE) launch frame at insertion, after payload separation mass
    r_ecef: NDArray
    v_ecef: NDArray  # Earth-relative
    v_inertial_ecef_axes: NDArray  # inertial velocity in Earth-fixed axes at insertion
    max_dynamic_pressure_pa: NDArray
    max_dynamic_pressure_time_s: NDArray
    max_axial_load_g: NDArray
    max_axial_load_time_s: NDArray
    min_altitude_m: NDArray
    fairing_stage: NDArray  # 0-based stage during whose flight it left, -1 if never
    fairing_time_s: NDArray  # from the drop
    fairing_burn_time_s: NDArray  # into that stage's burn
    speed_start_inertial_mps: NDArray
    crashed: NDArray  # reached the ground (stopped there)
    history: list[dict[str, NDArray]] = field(default_factory=list)

    @property
    def payload_kg(self) -> NDArray:
        return self.design[:, PAYLOAD]


class _Dynamics:
    """Right-hand side for one population; frame vectors are per row (azimuth differs).

    States are stored component-major, ``y[k]`` is component ``k`` of every row, so
    each vector operation below works on contiguous arrays.
    """

    def __init__(self, model: AscentModel, azimuth: NDArray) -> None:
        earth = model.earth
        self.mu = earth.mu
        self.re = earth.radius
        self.j2_factor = 1.5 * earth.j2 * earth.mu * earth.radius**2
        self.g0 = earth.g0_m_s2
        self.omega = earth_rate_in_launch_frame(model.drop.latitude_rad, azimuth, earth.omega).T
        self.pole = self.omega / earth.omega
        self.atmosphere = model.atmosphere
        self.aero = model.launcher.aero

    def altitude(self, y: NDArray) -> NDArray:
        return np.sqrt(y[0] ** 2 + (y[1] + self.re) ** 2 + y[2] ** 2) - self.re

    def __call__(self, t: NDArray, y: NDArray, phase: _Phase, *, diagnostics: bool = False) -> Any:
        rx, ry, rz = y[0], y[1] + self.re, y[2]
        vx, vy, vz = y[3], y[4], y[5]
        m = y[MASS]
        wx, wy, wz = self.omega

        r2 = rx * rx + ry * ry + rz * rz
        r_norm = np.sqrt(r2)
        altitude = r_norm - self.re
        rho, pressure, sound = self.atmosphere.lookup(altitude)
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        qbar = 0.5 * rho * speed * speed
        mach = speed / sound

        bx, by, bz = phase.attitude(t, y)
        inv_speed = 1.0 / speed
        ux, uy, uz = vx * inv_speed, vy * inv_speed, vz * inv_speed
        cos_alpha = bx * ux + by * uy + bz * uz
        ca, cna = self.aero.coefficients(mach, wing=phase.wing, axial_scale=phase.axial_scale)
        qs = qbar * self.aero.reference_area_m2
        # Normal force C_N_alpha sin(alpha) along the body normal on the lift side,
        # (b cos a - v_hat) / sin a: the sin a cancels. Axial force along -b.
        qn = qs * cna
        qa = qs * ca
        ax_ = qn * (bx * cos_alpha - ux) - qa * bx
        ay_ = qn * (by * cos_alpha - uy) - qa * by
        az_ = qn * (bz * cos_alpha - uz) - qa * bz

        powered = phase.thrust_n > 0.0
        thrust = np.maximum(phase.thrust_n - pressure * phase.exit_area_m2, 0.0) if powered else 0.0
        inv_m = 1.0 / m
        fx = (thrust * bx + ax_) * inv_m
        fy = (thrust * by + ay_) * inv_m
        fz = (thrust * bz + az_) * inv_m

        # Two-body + J2 attraction, frame-free form: -mu R/R^3 - (3/2) J2 mu Re^2 / R^5
        # [(1 - 5 s^2) R + 2 (R.p) p], s = R.p / R (Vallado 4th ed. eq. 8-29 rotated).
        px, py, pz = self.pole
        r_dot_p = rx * px + ry * py + rz * pz
        s2 = r_dot_p * r_dot_p / r2
        j2_term = self.j2_factor / (r2 * r2 * r_norm)
        radial = self.mu / (r2 * r_norm) + j2_term * (1.0 - 5.0 * s2)
        polar = 2.0 * j2_term * r_dot_p
        gx = -radial * rx - polar * px
        gy = -radial * ry - polar * py
        gz = -radial * rz - polar * pz

        # w x R, w x (w x R), w x v
        cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        ccx, ccy, ccz = wy * cz - wz * cy, wz * cx - wx * cz, wx * cy - wy * cx
        kx, ky, kz = wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx

        dy = np.empty_like(y)
        dy[0], dy[1], dy[2] = vx, vy, vz
        dy[3] = fx + gx - ccx - 2.0 * kx
        dy[4] = fy + gy - ccy - 2.0 * ky
        dy[5] = fz + gz - ccz - 2.0 * kz
        dy[MASS] = -phase.mass_flow_kg_s if powered else 0.0

        vix, viy, viz = vx + cx, vy + cy, vz + cz
        inv_vi = 1.0 / np.sqrt(vix * vix + viy * viy + viz * viz)
        dy[IDEAL] = phase.thrust_n * inv_m if powered else 0.0
        dy[GRAVITY] = -(gx * vix + gy * viy + gz * viz) * inv_vi
        dy[AERO] = -(ax_ * vix + ay_ * viy + az_ * viz) * inv_vi * inv_m
        dy[STEERING] = thrust * (1.0 - (bx * vix + by * viy + bz * viz) * inv_vi) * inv_m
        dy[BACK_PRESSURE] = (phase.thrust_n - thrust) * inv_m if powered else 0.0
        if not diagnostics:
            return dy
        return dy, {
            "altitude_m": altitude,
            "dynamic_pressure_pa": qbar,
            "axial_load_g": (thrust - qa) * inv_m / self.g0,
            "mach": mach,
            "alpha_rad": np.arccos(np.clip(cos_alpha, -1.0, 1.0)),
            "thrust_n": thrust + np.zeros_like(m),
        }


def _inertial_speed(dyn: _Dynamics, y: NDArray) -> NDArray:
    """|v + w x R| [m/s] of every row."""
    wx, wy, wz = dyn.omega
    rx, ry, rz = y[0], y[1] + dyn.re, y[2]
    vix = y[3] + wy * rz - wz * ry
    viy = y[4] + wz * rx - wx * rz
    viz = y[5] + wx * ry - wy * rx
    return np.sqrt(vix * vix + viy * viy + viz * viz)


def _velocity_pitch(y: NDArray) -> NDArray:
    return np.arctan2(y[4], y[3])


def _pitch_axis(phi: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    return np.cos(phi), np.sin(phi), np.zeros_like(phi)


def _ramp(t: NDArray, start: NDArray | float, duration: NDArray) -> NDArray:
    return np.clip((t - start) / duration, 0.0, 1.0)


def _alpha_programme(design: NDArray, launcher: LauncherModel) -> Attitude:
    """Stage-1 attitude: velocity pitch plus the angle-of-attack programme."""
    rate = launcher.max_alpha_rate_rad_s
    a0 = launcher.alpha_drop_rad
    a1, a2 = design[:, ALPHA_1], design[:, ALPHA_2]
    t12 = design[:, T_12]
    t23 = t12 + design[:, T_23]
    tiny = 1e-6
    d1 = np.maximum(np.abs(a1 - a0) / rate, tiny)
    d2 = np.maximum(np.abs(a2 - a1) / rate, tiny)
    d3 = np.maximum(np.abs(a2) / rate, tiny)

    def attitude(t: NDArray, y: NDArray) -> NDArray:
        alpha = (
            a0
            + (a1 - a0) * _ramp(t, 0.0, d1)
            + (a2 - a1) * _ramp(t, t12, d2)
            - a2 * _ramp(t, t23, d3)
        )
        return _pitch_axis(_velocity_pitch(y) + alpha)

    return attitude


def _alpha_programme_knots(design: NDArray, launcher: LauncherModel) -> NDArray:
    """Times after ignition where the angle-of-attack programme has a corner, (N, 5)."""
    rate = launcher.max_alpha_rate_rad_s
    a0 = launcher.alpha_drop_rad
    a1, a2 = design[:, ALPHA_1], design[:, ALPHA_2]
    t12 = design[:, T_12]
    t23 = t12 + design[:, T_23]
    return np.stack(
        [np.abs(a1 - a0) / rate, t12, t12 + np.abs(a2 - a1) / rate, t23, t23 + np.abs(a2) / rate],
        axis=1,
    )


def _fixed_alpha(alpha: float) -> Attitude:
    def attitude(t: NDArray, y: NDArray) -> NDArray:
        return _pitch_axis(_velocity_pitch(y) + alpha)

    return attitude


def _along_velocity(t: NDArray, y: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    inv = 1.0 / np.sqrt(y[3] ** 2 + y[4] ** 2 + y[5] ** 2)
    return y[3] * inv, y[4] * inv, y[5] * inv


def _linear_pitch(start: NDArray, rate: NDArray) -> Attitude:
    def attitude(t: NDArray, y: NDArray) -> NDArray:
        return _pitch_axis(start + rate * t)

    return attitude


class _Recorder:
    """Path maxima per phase (refined by a parabola through the peak) and the history."""

    def __init__(self, n: int, keep_history: bool) -> None:
        self.keep_history = keep_history
        self.history: list[dict[str, NDArray]] = []
        self.max_q = np.zeros(n)
        self.max_q_t = np.zeros(n)
        self.max_load = np.full(n, -np.inf)
        self.max_load_t = np.zeros(n)
        self.min_alt = np.full(n, np.inf)
        self._phase: list[tuple[NDArray, dict[str, NDArray]]] = []

    def sample(self, t_abs: NDArray, y: NDArray, diag: dict[str, NDArray], phase: _Phase) -> None:
        self._phase.append((t_abs.copy(), diag))
        self.min_alt = np.minimum(self.min_alt, diag["altitude_m"])
        if self.keep_history:
            self.history.append(
                {"t": t_abs.copy(), "y": y.copy(), "stage": phase.stage, "phase": phase.name}
                | {k: v.copy() for k, v in diag.items()}
            )

    def close_phase(self) -> None:
        if not self._phase:
            return
        times = np.stack([t for t, _ in self._phase])
        for key, best, best_t in (
            ("dynamic_pressure_pa", self.max_q, self.max_q_t),
            ("axial_load_g", self.max_load, self.max_load_t),
        ):
            values = np.stack([d[key] for _, d in self._phase])
            peak, peak_t = _refined_max(times, values)
            better = peak > best
            best[better] = peak[better]
            best_t[better] = peak_t[better]
        self._phase = []


def _refined_max(times: NDArray, values: NDArray) -> tuple[NDArray, NDArray]:
    """Column-wise maximum of samples, refined by a parabola through an interior peak."""
    k = np.argmax(values, axis=0)
    cols = np.arange(values.shape[1])
    peak = values[k, cols]
    peak_t = times[k, cols]
    interior = (k > 0) & (k < len(values) - 1)
    if np.any(interior):
        c = cols[interior]
        ki = k[interior]
        t0, t1, t2 = times[ki - 1, c], times[ki, c], times[ki + 1, c]
        f0, f1, f2 = values[ki - 1, c], values[ki, c], values[ki + 1, c]
        # Vertex of the parabola through three unevenly spaced points (corners of the
        # programme put extra, possibly zero-length, steps in the grid).
        h0, h1 = t1 - t0, t2 - t1
        ok = (h0 > 0.0) & (h1 > 0.0)
        d0 = np.where(ok, (f1 - f0) / np.where(ok, h0, 1.0), 0.0)
        d1 = np.where(ok, (f2 - f1) / np.where(ok, h1, 1.0), 0.0)
        curvature = np.where(ok, (d1 - d0) / np.where(ok, h0 + h1, 1.0), 0.0)
        ok &= curvature < 0.0
        slope_at_t1 = d0 + curvature * h0  # derivative of the parabola at t1
        shift = np.where(ok, -slope_at_t1 / (2.0 * np.where(ok, curvature, -1.0)), 0.0)
        shift = np.clip(shift, -h0, h1)
        peak[interior] = f1 + slope_at_t1 * shift + curvature * shift * shift
        peak_t[interior] = t1 + shift
    return peak, peak_t


def _rk4_step(
    dyn: _Dynamics, t: NDArray, y: NDArray, h: NDArray, phase: _Phase
) -> tuple[NDArray, dict[str, NDArray]]:
    """One classical Runge-Kutta step; also returns the diagnostics at its start."""
    hc = h
    k1, diag = dyn(t, y, phase, diagnostics=True)
    k2 = dyn(t + 0.5 * h, y + 0.5 * hc * k1, phase)
    k3 = dyn(t + 0.5 * h, y + 0.5 * hc * k2, phase)
    k4 = dyn(t + h, y + hc * k3, phase)
    return y + hc / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), diag


def initial_state(model: AscentModel, n: int, payload_kg: NDArray) -> NDArray:
    """Launch-frame state at the drop for ``n`` designs."""
    drop = model.drop
    _, _, sound = model.atmosphere.lookup(np.array([drop.altitude_m]))
    speed = drop.mach * float(sound[0])
    y = np.zeros((STATE_SIZE, n))
    y[1] = drop.altitude_m
    y[3] = speed * math.cos(drop.flight_path_angle_rad)
    y[4] = speed * math.sin(drop.flight_path_angle_rad)
    y[MASS] = model.launcher.lift_off_mass_without_payload_kg + payload_kg
    return y


def simulate(model: AscentModel, design: NDArray, *, keep_history: bool = False) -> AscentOutcome:
    """Fly every row of ``design`` (SI units, absolute azimuth; see the column constants)."""
    design = np.atleast_2d(np.asarray(design, dtype=float))
    n = len(design)
    stages = model.launcher.stages
    dyn = _Dynamics(model, design[:, AZIMUTH])
    y0 = initial_state(model, n, design[:, PAYLOAD])
    flight = _Flight(dyn, model.launcher, y0, _Recorder(n, keep_history))
    speed0 = _inertial_speed(dyn, flight.y)
    drops_before = {2: stages[0].burnout_drop_kg, 4: stages[1].burnout_drop_kg}
    for index, make in enumerate(_programme(model, design)):
        if index in drops_before:
            flight.y[MASS] -= drops_before[index]
        for phase in make(flight.y):
            flight.fly(phase)
    return _outcome(model, design, flight, speed0)


PhaseMaker = Callable[[NDArray], list[_Phase]]  # (state at the phase's start) -> its phases


def _uniform_grid(duration: NDArray, longest: float, step: float) -> NDArray:
    """Step boundaries: the same number of steps for every row, whatever the batch,
    so that a design's trajectory never depends on the other rows."""
    steps = max(1, math.ceil(longest / step - 1e-9))
    return np.linspace(0.0, 1.0, steps + 1)[:, None] * duration[None, :]


def _programme(model: AscentModel, design: NDArray) -> list[PhaseMaker]:
    """The flight in order: free fall, stage 1, separation coast, stage 2, coast, stage 3."""
    launcher = model.launcher
    n = len(design)
    return [
        _free_fall(model, n),
        _burn(
            model,
            n,
            0,
            lambda _: _alpha_programme(design, launcher),
            _alpha_programme_knots(design, launcher),
        ),
        _coast(
            model,
            1,
            np.full(n, launcher.separation_coast_s),
            launcher.separation_coast_s,
            model.powered_step_s,
            "separation coast",
        ),
        _burn(
            model,
            n,
            1,
            lambda y_now: _linear_pitch(_velocity_pitch(y_now), design[:, PITCH_RATE_2]),
        ),
        _coast(model, 2, design[:, COAST], model.longest_coast_s, model.coast_step_s, "coast"),
        _burn(model, n, 2, lambda _: _linear_pitch(design[:, PITCH_3], design[:, PITCH_RATE_3])),
    ]


def _free_fall(model: AscentModel, n: int) -> PhaseMaker:
    """The drop: no thrust, wing on, at the drop's angle of attack."""
    launcher = model.launcher

    def make(_: NDArray) -> list[_Phase]:
        d = np.full(n, launcher.free_fall_s)
        return [
            _Phase(
                "free fall",
                0,
                _uniform_grid(d, launcher.free_fall_s, model.powered_step_s),
                0.0,
                0.0,
                0.0,
                True,
                1.0,
                _fixed_alpha(launcher.alpha_drop_rad),
            )
        ]

    return make


def _burn(
    model: AscentModel,
    n: int,
    k: int,
    attitude_of: Callable[[NDArray], Attitude],
    knots: NDArray | None = None,
) -> PhaseMaker:
    """A stage burn on a uniform grid; the programme's corners (rows of ``knots``)
    are added to each row's grid so that no RK4 step straddles one. A corner
    passing a grid point only shrinks a step to zero: results stay continuous."""
    launcher = model.launcher
    stage = launcher.stages[k]

    def make(y_now: NDArray) -> list[_Phase]:
        total = stage.burn_time_s
        grid = _uniform_grid(np.full(n, total), total, model.powered_step_s)
        if knots is not None:
            grid = np.sort(np.vstack([grid, np.clip(knots, 0.0, total).T]), axis=0)
        return [
            _Phase(
                f"stage {k + 1} burn",
                k,
                grid,
                stage.vacuum_thrust_n,
                stage.mass_flow_kg_s,
                stage.nozzle_exit_area_m2,
                k == 0,
                1.0 if k == 0 else launcher.aero.upper_axial_scale,
                attitude_of(y_now),
            )
        ]

    return make


def _coast(
    model: AscentModel, k: int, duration: NDArray, longest: float, step: float, name: str
) -> PhaseMaker:
    """A coast of ``duration`` [s] per row along the velocity, in steps sized for
    ``longest`` [s]."""

    def make(_: NDArray) -> list[_Phase]:
        return [
            _Phase(
                name,
                k,
                _uniform_grid(duration, longest, step),
                0.0,
                0.0,
                0.0,
                False,
                model.launcher.aero.upper_axial_scale,
                _along_velocity,
            )
        ]

    return make


class _Flight:
    """The population in flight: its state, clocks, ground contact and fairing, stepped
    through one phase after another."""

    def __init__(
        self, dyn: _Dynamics, launcher: LauncherModel, y: NDArray, recorder: _Recorder
    ) -> None:
        n = y.shape[1]
        self.dyn = dyn
        self.launcher = launcher
        self.y = y
        self.t_abs = np.zeros(n)
        self.recorder = recorder
        self.fairing_on = np.ones(n, dtype=bool)
        self.fairing_stage = np.full(n, -1)
        self.fairing_time = np.full(n, np.nan)
        self.fairing_burn_time = np.zeros(n)
        self.crashed = np.zeros(n, dtype=bool)

    def fly(self, phase: _Phase) -> None:
        """Every RK4 step of ``phase``, its path figures recorded."""
        t_local = phase.grid[0].copy()
        for k in range(len(phase.grid) - 1):
            h_live = np.where(self.crashed, 0.0, phase.grid[k + 1] - phase.grid[k])
            self._step(phase, t_local, h_live)
            t_local = t_local + h_live
            self.t_abs = self.t_abs + h_live
        _, diag = self.dyn(t_local, self.y, phase, diagnostics=True)
        self.recorder.sample(self.t_abs, self.y, diag, phase)
        self.recorder.close_phase()

    def _step(self, phase: _Phase, t_local: NDArray, h_live: NDArray) -> None:
        dyn, y = self.dyn, self.y
        y_new, diag = _rk4_step(dyn, t_local, y, h_live, phase)
        self.recorder.sample(self.t_abs, y, diag, phase)
        # A row that reaches the ground stops there (its errors stay finite).
        down = ~np.isfinite(y_new).all(axis=0) | (dyn.altitude(y_new) < 0.0)
        if np.any(down):
            self.crashed |= down
            y_new[:, down] = y[:, down]
        if phase.stage >= self.launcher.fairing_earliest_stage:
            y_new, rows, frac = _jettison_fairing(
                dyn, phase, self.launcher, t_local, y, y_new, h_live, self.fairing_on
            )
            self.fairing_stage[rows] = phase.stage
            self.fairing_time[rows] = self.t_abs[rows] + frac * h_live[rows]
            self.fairing_burn_time[rows] = (
                t_local[rows] + frac * h_live[rows] if phase.thrust_n > 0 else 0.0
            )
        self.y = y_new


def _outcome(
    model: AscentModel, design: NDArray, flight: _Flight, speed0: NDArray
) -> AscentOutcome:
    """The end state at payload separation (stage-3 burnout: what flies on is the
    payload) and the path figures."""
    y = flight.y
    y[MASS] = design[:, PAYLOAD]
    axes = launch_frame_axes(model.drop.latitude_rad, model.drop.longitude_rad, design[:, AZIMUTH])
    r_ecef, v_ecef = launch_to_ecef(y[POS].T, y[VEL].T, axes, radius_m=model.earth.radius)
    omega_ecef = np.array([0.0, 0.0, model.earth.omega])
    v_inertial = v_ecef + np.cross(omega_ecef, r_ecef)
    recorder = flight.recorder
    return AscentOutcome(
        design=design,
        time_s=flight.t_abs,
        state=y.T.copy(),
        r_ecef=r_ecef,
        v_ecef=v_ecef,
        v_inertial_ecef_axes=v_inertial,
        max_dynamic_pressure_pa=recorder.max_q,
        max_dynamic_pressure_time_s=recorder.max_q_t,
        max_axial_load_g=recorder.max_load,
        max_axial_load_time_s=recorder.max_load_t,
        min_altitude_m=recorder.min_alt,
        fairing_stage=flight.fairing_stage,
        fairing_time_s=flight.fairing_time,
        fairing_burn_time_s=flight.fairing_burn_time,
        speed_start_inertial_mps=speed0,
        crashed=flight.crashed,
        history=recorder.history,
    )


def _jettison_fairing(
    dyn: _Dynamics,
    phase: _Phase,
    launcher: LauncherModel,
    t_local: NDArray,
    y: NDArray,
    y_new: NDArray,
    h: NDArray,
    fairing_on: NDArray,
) -> tuple[NDArray, NDArray, NDArray]:
    """Redo the step of the rows that crossed the fairing altitude, split at the crossing.

    Returns the new states, the rows that dropped the fairing and the fraction of
    the step at which each did.
    """
    threshold = launcher.fairing_jettison_altitude_m
    alt_old = dyn.altitude(y)
    alt_new = dyn.altitude(y_new)
    crossed = fairing_on & (alt_new >= threshold)
    if not np.any(crossed):
        return y_new, np.empty(0, dtype=np.intp), np.empty(0)
    frac = np.where(
        crossed & (alt_old < threshold),
        (threshold - alt_old) / np.where(alt_new > alt_old, alt_new - alt_old, 1.0),
        0.0,
    )
    frac = np.clip(frac, 0.0, 1.0)
    # Whole-population steps keep the attitude closures aligned with the rows; rows
    # that did not cross take a zero-length step and keep their result.
    h1 = np.where(crossed, frac * h, 0.0)
    y_mid, _ = _rk4_step(dyn, t_local, y, h1, phase)
    y_mid[MASS, crossed] -= launcher.fairing_mass_kg
    h2 = np.where(crossed, h - h1, 0.0)
    y_end, _ = _rk4_step(dyn, t_local + h1, y_mid, h2, phase)
    out = y_new.copy()
    out[:, crossed] = y_end[:, crossed]
    fairing_on[crossed] = False
    return out, np.flatnonzero(crossed), frac[crossed]
