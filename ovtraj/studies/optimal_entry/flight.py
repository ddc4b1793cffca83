"""Numerical (numpy) flight of an entry with given controls, outside the NLP.

Used for the initial guess and for the seed's feasibility check. It is a second,
independent implementation of the time-domain equations (the NLP's are CasADi
expressions in :mod:`ovtraj.studies.optimal_entry.dynamics`): 3-DOF point mass over a
spherical, optionally rotating Earth (Vinh, Busemann & Culp, *Hypersonic and Planetary
Entry Flight Mechanics*, 1980, ch. 2; seed 001 eqs. 1-6 without rotation), states
``(h, lon, lat, V, gamma, psi)``, heading from north, clockwise. The atmosphere is the
library's numpy model (:mod:`ovtraj.astro.atmosphere`), not the NLP's expressions, and
the integrator is scipy's ``solve_ivp`` (DOP853, Hairer, Norsett & Wanner, 1993).

Controls given as a :class:`~.flight_kernel.ControlTable` (splined or piecewise-linear
samples, constants) are flown by the same equations and integrator compiled with numba
(:mod:`.flight_kernel`, milliseconds per flight); any other callable by the Python
right-hand side below (the reference the compiled flight is tested against).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ovtraj.deadline import Deadline
from ovtraj.studies.optimal_entry.flight_kernel import ControlTable, fly_compiled
from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["Flown", "PointMass", "fly"]

Controls = Callable[[float], tuple[float, float]]


@dataclass(frozen=True)
class PathValues:
    """Aerodynamic and path quantities at one point (SI; load in g)."""

    rho: float
    mach: float
    lift: float  # acceleration [m/s^2]
    drag: float
    dynamic_pressure: float
    heat_rate: float
    load_g: float


def _poly(c: list[float], x: float) -> float:
    total = 0.0
    for coefficient in reversed(c):
        total = total * x + coefficient
    return total


def _poly2(c: list[list[float]], x: float, y: float) -> float:
    """``sum_ij c[i][j] x^i y^j`` (Horner in both variables; scalars are much faster than
    numpy's polyval2d inside an integrator)."""
    total = 0.0
    for row in reversed(c):
        total = total * x + _poly(row, y)
    return total


class PointMass:
    """The entry equations of motion of one problem, in numpy."""

    def __init__(self, problem: EntryProblem) -> None:
        self.p = problem
        self._cl = problem.cl.tolist()
        self._cd = problem.cd.tolist()
        self._heat = problem.heat_alpha_polynomial.tolist()

    def gravity(self, h: float) -> float:
        p = self.p
        if p.gravity == "constant":
            return p.g0
        return p.mu / (p.radius + h) ** 2

    def path_values(self, h: float, v: float, alpha: float) -> PathValues:
        p = self.p
        z = min(max(h, 0.0), p.atmosphere_top_m)
        rho = float(p.atmosphere.density(z))
        mach = v / float(p.atmosphere.speed_of_sound(z))
        a = alpha * p.alpha_scale
        cl = _poly2(self._cl, a, mach)
        cd = _poly2(self._cd, a, mach)
        q = 0.5 * rho * v * v
        lift = q * p.area * cl / p.mass
        drag = q * p.area * cd / p.mass
        heat = 0.0
        if p.heat_coefficient is not None:
            heat = (
                p.heat_coefficient
                * rho**p.heat_density_exponent
                * v**p.heat_speed_exponent
                * _poly(self._heat, a)
            )
        if p.load_definition == "normal":
            load = (lift * math.cos(alpha) + drag * math.sin(alpha)) / p.g0
        else:
            load = math.hypot(lift, drag) / p.g0
        return PathValues(rho, mach, lift, drag, q, heat, load)

    def rates(self, y: NDArray[np.float64], alpha: float, bank: float) -> NDArray[np.float64]:
        """d/dt of ``(h, lon, lat, V, gamma, psi)`` (Vinh et al. 1980, ch. 2)."""
        h, _, lat, v, gamma, psi = y
        p = self.p
        r = p.radius + h
        g = self.gravity(h)
        w = p.omega
        pv = self.path_values(h, v, alpha)
        sg, cg = math.sin(gamma), math.cos(gamma)
        sp, cp = math.sin(psi), math.cos(psi)
        sl, cl = math.sin(lat), math.cos(lat)
        dv = -pv.drag - g * sg + w * w * r * cl * (sg * cl - cg * sl * cp)
        dgamma = (
            pv.lift * math.cos(bank)
            + (v * v / r - g) * cg
            + 2.0 * w * v * cl * sp
            + w * w * r * cl * (cg * cl + sg * cp * sl)
        ) / v
        dpsi = (
            pv.lift * math.sin(bank) / cg
            + v * v / r * cg * sp * math.tan(lat)
            - 2.0 * w * v * (math.tan(gamma) * cp * cl - sl)
            + w * w * r * sp * sl * cl / cg
        ) / v
        return np.array(
            [v * sg, v * cg * sp / (r * cl), v * cg * cp / r, dv, dgamma, dpsi], dtype=float
        )

    def energy(self, h: float, v: float) -> float:
        return self.p.energy(h, v)


@dataclass(frozen=True)
class Flown:
    """An integrated trajectory: times [s] and states (rows of h, lon, lat, V, gamma, psi)."""

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    status: str
    # Heat rate [W/m^2], load [g] and dynamic pressure [Pa] at each point (compiled flights).
    path: NDArray[np.float64] | None = None


def fly(
    problem: EntryProblem,
    controls: Controls,
    t_end: float,
    *,
    rtol: float,
    atol: float,
    stop_energy: float | None = None,
    breaks: NDArray[np.float64] | None = None,
    deadline: Deadline | None = None,
    start: tuple[float, NDArray[np.float64]] | None = None,
) -> Flown:
    """Integrate from the problem's initial state to ``t_end`` [s] with ``controls(t)``.

    ``start``: ``(t0, state)`` to begin elsewhere than the initial state at 0 (one mesh
    segment, :mod:`.mesh`).

    Stops early at ``stop_energy`` [J/kg] (if given) or on the ground. ``atol`` applies to
    the states scaled to order one (altitude and speed by their initial values). The
    integration restarts at every time of ``breaks`` (e.g. the knots of piecewise-linear
    controls), so that no step straddles a kink of the controls.

    At ``deadline`` the states freeze (zero rates: the integrator then runs out to
    ``t_end`` in a few long steps) and the status is ``time limit``: what was flown
    until then is kept.
    """
    if isinstance(controls, ControlTable):
        return _fly_table(
            problem, controls, t_end, rtol, atol, stop_energy, breaks, deadline, start
        )
    return _fly_python(problem, controls, t_end, rtol, atol, stop_energy, breaks, deadline, start)


def _fly_table(
    problem: EntryProblem,
    controls: ControlTable,
    t_end: float,
    rtol: float,
    atol: float,
    stop_energy: float | None,
    breaks: NDArray[np.float64] | None,
    deadline: Deadline | None,
    start: tuple[float, NDArray[np.float64]] | None,
) -> Flown:
    """The compiled flight (milliseconds); the deadline is checked before it."""
    if deadline is not None and deadline.expired():
        t0, y0 = (0.0, problem.initial_state) if start is None else start
        return Flown(np.array([t0]), np.array([y0], dtype=float), "time limit")
    flown = fly_compiled(
        problem,
        controls,
        t_end,
        rtol=rtol,
        atol=atol,
        stop_energy=stop_energy,
        breaks=breaks,
        start=start,
    )
    return Flown(flown.t, flown.y, flown.status, flown.path)


def _fly_python(
    problem: EntryProblem,
    controls: Controls,
    t_end: float,
    rtol: float,
    atol: float,
    stop_energy: float | None,
    breaks: NDArray[np.float64] | None,
    deadline: Deadline | None,
    start: tuple[float, NDArray[np.float64]] | None,
) -> Flown:
    """The Python right-hand side under scipy's DOP853, from break to break."""
    model = PointMass(problem)
    frozen = np.zeros(6)
    t0, y0 = (0.0, problem.initial_state.copy()) if start is None else start
    y0 = np.asarray(y0, dtype=float)
    initial = problem.initial_state
    scale = np.array([max(abs(initial[0]), 1.0), 1.0, 1.0, abs(initial[3]), 1.0, 1.0])

    def rhs(t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        if deadline is not None and deadline.expired():
            return frozen
        alpha, bank = controls(t)
        return model.rates(z * scale, alpha, bank) / scale

    events = _stop_events(model, scale, stop_energy)
    edges = [t0]
    if breaks is not None:
        edges += sorted(float(b) for b in breaks if t0 < b < t_end)
    edges.append(t_end)
    times, states = [np.array([t0])], [(y0 / scale)[None, :]]
    z = y0 / scale
    status = "completed"
    for a, b in itertools.pairwise(edges):
        if b <= a:
            continue
        sol = solve_ivp(rhs, (a, b), z, method="DOP853", rtol=rtol, atol=atol, events=events)
        times.append(sol.t[1:])
        states.append(sol.y.T[1:])
        z = sol.y[:, -1]
        if deadline is not None and deadline.reached:
            status = "time limit"
            break
        if sol.status == 1:
            status = "ground" if len(sol.t_events[0]) else "terminal energy"
            break
        if sol.status < 0:
            status = f"integration failed: {sol.message}"
            break
    return Flown(t=np.concatenate(times), y=np.vstack(states) * scale, status=status)


def _stop_events(
    model: PointMass, scale: NDArray[np.float64], stop_energy: float | None
) -> list[Callable[[float, NDArray[np.float64]], float]]:
    """solve_ivp's terminal events on the scaled state: the ground, then (if given) the
    energy falling to ``stop_energy``."""

    def ground(t: float, z: NDArray[np.float64]) -> float:
        return z[0] * scale[0]

    ground.terminal = True  # type: ignore[attr-defined]
    events = [ground]
    if stop_energy is not None:

        def energy(t: float, z: NDArray[np.float64]) -> float:
            return model.energy(z[0] * scale[0], z[3] * scale[3]) - stop_energy

        energy.terminal = True  # type: ignore[attr-defined]
        energy.direction = -1  # type: ignore[attr-defined]
        events.append(energy)
    return events
