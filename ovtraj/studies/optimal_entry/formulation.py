"""The entry problem as an optimal-control problem, in energy or in time.

**Energy** (seed 001 sec. 1.2): the independent variable is the normalised energy
``e = (E - E0) / (Ef - E0)`` on the fixed interval [0, 1] (seed eq. 10), the speed is no
longer a state (``V = sqrt(2 (E - U(h)))``, seed eq. 8) and the five states
``(h, lon, lat, gamma, psi)`` obey ``dx/de = (Ef - E0) x' / E'`` with
``E' = V V' + g h'`` (``= -V D`` without Earth rotation, seed eq. 9; seed eqs. 11-15 are
this with ``r / R`` for ``h``). Time is recovered by quadrature of
``dt/de = (Ef - E0) / E'``. ``Ef`` is an NLP parameter: fixed when the terminal altitude
and speed are, bounded otherwise (then the terminal speed is a boundary constraint on
``2 (Ef - U(h_f))``). Path constraints add ``V^2`` within the speed bounds.

**Time**: six states ``(h, lon, lat, V, gamma, psi)``, free final time within its bounds.

A control with a rate limit becomes a state, and its rate the (bounded) control
(Betts, *Practical Methods for Optimal Control*, 2nd ed., 2010, sec. 4.12). Objectives
(all minimised): ``-downrange`` (central angle along the initial great circle,
:mod:`ovtraj.studies.optimal_entry.geometry`), ``-latitude(tf)`` (maximum cross-range
as in Betts' shuttle problem, sec. 6.1), ``integral Q dt`` (heat load), ``tf``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from ovtraj.studies.optimal_entry.dynamics import EntryExpressions
from ovtraj.studies.optimal_entry.flight import PointMass
from ovtraj.studies.optimal_entry.geometry import GreatCircle
from ovtraj.studies.optimal_entry.guess import GuessTrajectory
from ovtraj.studies.optimal_entry.ocp import Guess, OptimalControlProblem
from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["AUX_NAMES", "POINT_NAMES", "Formulation", "formulate"]

# Quantities the aux function returns at the collocation points, in this order.
AUX_NAMES = (
    "dt_ds",
    "altitude",
    "longitude",
    "latitude",
    "speed",
    "fpa",
    "heading",
    "alpha",
    "bank",
    "density",
    "mach",
    "cl",
    "cd",
    "dynamic_pressure",
    "load_g",
    "heat_rate",
)
# Physical quantities at every state point (no control needed).
POINT_NAMES = ("altitude", "longitude", "latitude", "speed", "fpa", "heading", "energy")


@dataclass(frozen=True)
class Formulation:
    """An :class:`OptimalControlProblem` with the functions to read its solution back."""

    problem: EntryProblem
    independent: str
    ocp: OptimalControlProblem
    aux: ca.Function  # (x, u, s, p) -> AUX_NAMES
    point: ca.Function  # (x, s, p) -> POINT_NAMES
    rate_limited: tuple[bool, bool]  # alpha, bank are states
    circle: GreatCircle

    def guess(self, traj: GuessTrajectory) -> Guess:
        """The flown guess in this formulation's variables."""
        p = self.problem
        y = traj.y
        rl = self.rate_limited
        extra = [
            np.full(len(traj.t), c) for c, r in zip((traj.alpha, traj.bank), rl, strict=True) if r
        ]
        controls = [
            np.zeros(len(traj.t)) if r else np.full(len(traj.t), c)
            for c, r in zip((traj.alpha, traj.bank), rl, strict=True)
        ]
        u = np.column_stack(controls)
        if self.independent == "time":
            x = np.column_stack([y, *extra])
            return Guess(s=traj.t, x=x, u=u, sf=float(traj.t[-1]))
        e0 = p.initial_energy
        energy = p.energy(y[:, 0], y[:, 3])
        s = (energy - e0) / (traj.target_energy - e0)
        # Earth rotation can make E wiggle; keep the increasing envelope for interpolation.
        s = np.maximum.accumulate(s)
        keep = np.concatenate(([True], np.diff(s) > 0.0))
        x = np.column_stack([y[:, [0, 1, 2, 4, 5]], *extra, traj.t])[keep]
        return Guess(s=s[keep], x=x, u=u[keep], sf=1.0, p=np.array([traj.target_energy]))


def _objective_scale(problem: EntryProblem, traj: GuessTrajectory, circle: GreatCircle) -> float:
    """The guess's value of the objective, so that the scaled objective is of order one."""
    y = traj.y
    downrange, _ = circle.angles(y[-1, 1], y[-1, 2])
    if problem.objective in ("max_downrange", "max_crossrange"):
        value = abs(float(downrange))
    elif problem.objective == "min_time":
        value = float(traj.t[-1])
    else:
        value = _guess_heat_load(problem, traj)
    return value if value > 0.0 and np.isfinite(value) else 1.0


def _guess_heat_load(problem: EntryProblem, traj: GuessTrajectory) -> float:
    model = PointMass(problem)
    q = np.array([model.path_values(row[0], row[3], traj.alpha).heat_rate for row in traj.y])
    return float(np.trapezoid(q, traj.t)) if len(q) > 1 else 0.0


def formulate(problem: EntryProblem, independent: str, traj: GuessTrajectory) -> Formulation:
    """Build the OCP of ``problem`` with ``independent`` = ``"energy"`` or ``"time"``.

    In the parts of the problem, the ODE apart from what constrains it (as dymos keeps the
    ODE apart from the transcription): the variables with their bounds and scales, the
    dynamics (:class:`_EntryOde`), the path constraints, the boundary conditions (the
    final energy and the final value of ``s``) and the objective.
    """
    if independent not in ("energy", "time"):
        raise ValueError(f"independent must be 'energy' or 'time', got {independent!r}")
    p = problem
    circle = GreatCircle(
        float(p.initial_state[1]), float(p.initial_state[2]), float(p.initial_state[5])
    )
    energy_form = independent == "energy"
    v = _variables(p, energy_form, traj)
    ode = _EntryOde(p, energy_form, v.rate_limited)
    path_lower, path_upper = _path_bounds(p, energy_form)
    mayer, lagrange = _objective(p, energy_form, ode, circle)
    ends = _boundary_conditions(p, energy_form, traj)
    ocp = OptimalControlProblem(
        state_names=tuple(v.state_names),
        control_names=tuple(v.control_names),
        dynamics=ode.dynamics,
        state_lower=np.array(v.state_lower, dtype=float),
        state_upper=np.array(v.state_upper, dtype=float),
        control_lower=np.array(v.control_lower, dtype=float),
        control_upper=np.array(v.control_upper, dtype=float),
        initial_lower=np.array([x if np.isfinite(x) else -np.inf for x in v.initial], dtype=float),
        initial_upper=np.array([x if np.isfinite(x) else np.inf for x in v.initial], dtype=float),
        final_lower=np.array(v.final_lower, dtype=float),
        final_upper=np.array(v.final_upper, dtype=float),
        s0=0.0,
        sf_bounds=ends.sf_bounds,
        state_scale=np.array(v.state_scale, dtype=float),
        control_scale=np.array(v.control_scale, dtype=float),
        sf_scale=ends.sf_scale,
        objective_scale=_objective_scale(p, traj, circle),
        mayer=mayer,
        lagrange=lagrange,
        path=ode.path if path_lower else None,
        path_lower=np.array(path_lower, dtype=float),
        path_upper=np.array(path_upper, dtype=float),
        increasing_states=v.increasing,
        boundary=ends.boundary,
        boundary_lower=ends.boundary_lower,
        boundary_upper=ends.boundary_upper,
        parameter_names=ends.parameter_names,
        parameter_lower=ends.parameter_lower,
        parameter_upper=ends.parameter_upper,
        parameter_scale=ends.parameter_scale,
    )
    return Formulation(
        problem=p,
        independent=independent,
        ocp=ocp,
        aux=_aux_function(ocp, ode),
        point=_point_function(ocp, ode),
        rate_limited=v.rate_limited,
        circle=circle,
    )


def _kinematic_states(energy_form: bool) -> list[int]:
    """Which of (h, lon, lat, V, gamma, psi) are states: the energy form recovers V from E."""
    return [0, 1, 2, 4, 5] if energy_form else [0, 1, 2, 3, 4, 5]


def _speed_scale(p: EntryProblem) -> float:
    """The initial speed [m/s]: the unit of V and of V^2 constraints in the NLP."""
    return float(p.initial_state[3])


@dataclass
class _Variables:
    """The OCP's states and controls in order, with their bounds and scales."""

    rate_limited: tuple[bool, bool]  # alpha, bank are states (their rates the controls)
    state_names: list[str]
    state_lower: list[float]
    state_upper: list[float]
    initial: list[float]  # -inf: free
    final_lower: list[float]
    final_upper: list[float]
    state_scale: list[float]
    control_names: list[str] = field(default_factory=list)
    control_lower: list[float] = field(default_factory=list)
    control_upper: list[float] = field(default_factory=list)
    control_scale: list[float] = field(default_factory=list)
    increasing: tuple[int, ...] = ()


def _variables(p: EntryProblem, energy_form: bool, traj: GuessTrajectory) -> _Variables:
    """The kinematic states, then the angles (states when rate-limited, else controls),
    then, in energy, the time."""
    base = _kinematic_states(energy_form)
    base_names = ("altitude", "longitude", "latitude", "speed", "fpa", "heading")
    # Altitude in units of the initial one (or of its bound, starting on the ground).
    h0 = float(p.initial_state[0])
    altitude_scale = h0 if h0 > 0.0 else float(max(abs(p.state_lower[0]), abs(p.state_upper[0])))
    scale = [altitude_scale, 1.0, 1.0, _speed_scale(p), 1.0, 1.0]
    v = _Variables(
        rate_limited=(p.control_rate[0] is not None, p.control_rate[1] is not None),
        state_names=[base_names[i] for i in base],
        state_lower=list(p.state_lower[base]),
        state_upper=list(p.state_upper[base]),
        initial=list(p.initial_state[base]),
        final_lower=list(p.final_lower[base]),
        final_upper=list(p.final_upper[base]),
        state_scale=[scale[i] for i in base],
    )
    _add_angles(v, p)
    if energy_form:
        _add_time(v, p, traj)
    return v


def _add_angles(v: _Variables, p: EntryProblem) -> None:
    """Angle of attack and bank: a state with its bounded rate as the control when the
    rate is limited (Betts 2010, sec. 4.12), else the control itself."""
    for j, name in enumerate(("alpha", "bank")):
        if v.rate_limited[j]:
            v.state_names.append(name)
            v.state_lower.append(p.control_lower[j])
            v.state_upper.append(p.control_upper[j])
            v.initial.append(-np.inf)
            v.final_lower.append(-np.inf)
            v.final_upper.append(np.inf)
            v.state_scale.append(1.0)
            rate = float(p.control_rate[j])  # type: ignore[arg-type]
            v.control_names.append(f"{name}_rate")
            v.control_lower.append(-rate)
            v.control_upper.append(rate)
        else:
            v.control_names.append(name)
            v.control_lower.append(p.control_lower[j])
            v.control_upper.append(p.control_upper[j])
        v.control_scale.append(1.0)


def _add_time(v: _Variables, p: EntryProblem, traj: GuessTrajectory) -> None:
    """Time as a state (rate dt/de): collocated like the others, so the recovered time is
    the collocation polynomial's, and it must increase between the state points."""
    v.increasing = (len(v.state_names),)
    v.state_names.append("time")
    v.state_lower.append(0.0)
    v.state_upper.append(float(p.final_time_bounds[1]))
    v.initial.append(0.0)
    v.final_lower.append(0.0)
    v.final_upper.append(float(p.final_time_bounds[1]))
    v.state_scale.append(float(traj.t[-1]) if traj.t[-1] > 0 else 1.0)


class _EntryOde:
    """The entry dynamics in the formulation's variables ``(x, u, s, p)``: the physical
    quantities, ``dx/ds``, ``dt/ds`` and the path rows, as CasADi expressions."""

    def __init__(
        self, problem: EntryProblem, energy_form: bool, rate_limited: tuple[bool, bool]
    ) -> None:
        self.p = problem
        self.model = EntryExpressions(problem)
        self.energy_form = energy_form
        self.rate_limited = rate_limited
        self.base = _kinematic_states(energy_form)
        self.e0 = problem.initial_energy
        self.v_lo = float(problem.state_lower[3])
        self.v_scale = _speed_scale(problem)

    def unpack(self, x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> tuple:
        """Physical (h, lon, lat, V, gamma, psi, alpha, bank, [rates or None], E)."""
        p, e0 = self.p, self.e0
        h, lon, lat = x[0], x[1], x[2]
        if self.energy_form:
            ef = par[0]
            energy = e0 + s * (ef - e0)
            v2 = 2.0 * (energy - p.potential(h))
            # The floor keeps V real at infeasible iterates; the path constraint on V^2
            # keeps the solution above it.
            v = ca.sqrt(ca.fmax(v2, self.v_lo**2))
            gamma, psi = x[3], x[4]
        else:
            v, gamma, psi = x[3], x[4], x[5]
            energy = p.energy(h, v)
        controls = []
        rates = []
        k_state, k_control = len(self.base), 0
        for j in range(2):
            if self.rate_limited[j]:
                controls.append(x[k_state])
                rates.append(u[k_control])
                k_state += 1
            else:
                controls.append(u[k_control])
                rates.append(None)
            k_control += 1
        return h, lon, lat, v, gamma, psi, controls[0], controls[1], rates, energy

    def time_derivatives(self, x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> tuple:
        h, lon, lat, v, gamma, psi, alpha, bank, rates, energy = self.unpack(x, u, s, par)
        av = self.model.aero(h, v, alpha)
        d = self.model.time_rates(h, lat, v, gamma, psi, bank, av)
        return d, av, rates, (h, lon, lat, v, gamma, psi, alpha, bank, energy)

    def energy_rate(self, x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        """E' = V V' + g h' [W/kg] (-V D without Earth rotation, seed eq. 9)."""
        d, _, _, phys = self.time_derivatives(x, u, s, par)
        h, v = phys[0], phys[3]
        return v * d[3] + self.model.gravity(h) * d[0]

    def dt_ds(self, x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        if not self.energy_form:
            return ca.SX(1.0)
        return (par[0] - self.e0) / self.energy_rate(x, u, s, par)

    def dynamics(self, x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        """dx/ds: the time rates of the states, times dt/ds in energy (time's own rate last)."""
        d, _, rates, _ = self.time_derivatives(x, u, s, par)
        rows = [d[i] for i in self.base] + [r for r in rates if r is not None]
        if not self.energy_form:
            return ca.vertcat(*rows)
        rate = self.dt_ds(x, u, s, par)
        return ca.vertcat(ca.vertcat(*rows) * rate, rate)

    def path(self, x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        """The path rows, scaled by their limits, in the order of :func:`_path_bounds`."""
        p, e0, v_scale = self.p, self.e0, self.v_scale
        _, av, _, phys = self.time_derivatives(x, u, s, par)
        rows = []
        if p.max_load_g is not None:
            rows.append(av.load_g / p.max_load_g)
        if p.max_dynamic_pressure is not None:
            rows.append(av.dynamic_pressure / p.max_dynamic_pressure)
        if p.max_heat_rate is not None:
            rows.append(av.heat_rate / p.max_heat_rate)
        if self.energy_form:
            h = phys[0]
            rows.append(2.0 * (e0 + s * (par[0] - e0) - p.potential(h)) / v_scale**2)
            # The energy must decrease (dt/de > 0): E' <= 0, scaled by g0 V0.
            rows.append(self.energy_rate(x, u, s, par) / (p.g0 * v_scale))
        return ca.vertcat(*rows)


def _path_bounds(p: EntryProblem, energy_form: bool) -> tuple[list[float], list[float]]:
    """Bounds of :meth:`_EntryOde.path`'s rows: load, dynamic pressure and heat rate
    within their limits; in energy, V^2 within the speed bounds and E' <= 0."""
    path_lower: list[float] = []
    path_upper: list[float] = []
    if p.max_load_g is not None:
        path_lower.append(-1.0 if p.load_definition == "normal" else -np.inf)
        path_upper.append(1.0)
    if p.max_dynamic_pressure is not None:
        path_lower.append(-np.inf)
        path_upper.append(1.0)
    if p.max_heat_rate is not None:
        path_lower.append(-np.inf)
        path_upper.append(1.0)
    if energy_form:
        v_lo, v_hi = float(p.state_lower[3]), float(p.state_upper[3])
        v_scale = _speed_scale(p)
        path_lower.append(v_lo**2 / v_scale**2)
        path_upper.append(v_hi**2 / v_scale**2)
        path_lower.append(-np.inf)
        path_upper.append(0.0)
    return path_lower, path_upper


def _objective(
    p: EntryProblem, energy_form: bool, ode: _EntryOde, circle: GreatCircle
) -> tuple[Callable | None, Callable | None]:
    """(Mayer term, Lagrange integrand) of the objective (module notes)."""
    if p.objective == "max_downrange":

        def mayer(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
            return -circle.angles_sx(xf[1], xf[2])[0]

        return mayer, None
    if p.objective == "max_crossrange":

        def mayer(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
            return -xf[2]

        return mayer, None
    if p.objective == "min_time" and not energy_form:

        def mayer(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
            return sf

        return mayer, None
    if p.objective == "min_time":
        return None, ode.dt_ds

    def lagrange(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        _, av, _, _ = ode.time_derivatives(x, u, s, par)
        return av.heat_rate * ode.dt_ds(x, u, s, par)

    return None, lagrange


@dataclass(frozen=True)
class _BoundaryConditions:
    """The final value of ``s``, the NLP parameters and the boundary constraints."""

    sf_bounds: tuple[float, float]
    sf_scale: float
    boundary: Callable | None = None
    boundary_lower: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    boundary_upper: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    parameter_names: tuple[str, ...] = ()
    parameter_lower: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    parameter_upper: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    parameter_scale: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))


def _boundary_conditions(
    p: EntryProblem, energy_form: bool, traj: GuessTrajectory
) -> _BoundaryConditions:
    """Time: a free final time within its bounds. Energy: s ends at 1, the final energy is
    a parameter within what the terminal bounds allow and, unless they fix it, the
    terminal speed a boundary constraint on ``2 (Ef - U(h_f))``."""
    if not energy_form:
        return _BoundaryConditions(
            sf_bounds=p.final_time_bounds,
            sf_scale=float(traj.t[-1]) if traj.t[-1] > 0 else 1.0,
        )
    e0 = p.initial_energy
    v_scale = _speed_scale(p)
    e_lo, e_hi = p.terminal_energy_bounds()
    parameters = {
        "parameter_names": ("final_energy",),
        "parameter_lower": np.array([e_lo]),
        "parameter_upper": np.array([min(e_hi, e0)]),
        "parameter_scale": np.array([abs(e0)]),
    }
    if p.terminal_energy_fixed:
        return _BoundaryConditions(sf_bounds=(1.0, 1.0), sf_scale=1.0, **parameters)
    v_f_lo, v_f_hi = float(p.final_lower[3]), float(p.final_upper[3])

    def boundary(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
        return 2.0 * (par[0] - p.potential(xf[0])) / v_scale**2

    return _BoundaryConditions(
        sf_bounds=(1.0, 1.0),
        sf_scale=1.0,
        boundary=boundary,
        boundary_lower=np.array([max(v_f_lo, 0.0) ** 2 / v_scale**2]),
        boundary_upper=np.array([v_f_hi**2 / v_scale**2]),
        **parameters,
    )


def _aux_function(ocp: OptimalControlProblem, ode: _EntryOde) -> ca.Function:
    """(x, u, s, p) -> the quantities of :data:`AUX_NAMES` at a collocation point."""
    xs = ca.SX.sym("x", ocp.nx)
    us = ca.SX.sym("u", ocp.nu)
    ss = ca.SX.sym("s")
    ps = ca.SX.sym("p", ocp.npar)
    _, av, _, phys = ode.time_derivatives(xs, us, ss, ps)
    h, lon, lat, v, gamma, psi, alpha, bank, _ = phys
    values = ca.vertcat(
        ode.dt_ds(xs, us, ss, ps),
        h,
        lon,
        lat,
        v,
        gamma,
        psi,
        alpha,
        bank,
        av.rho,
        av.mach,
        av.cl,
        av.cd,
        av.dynamic_pressure,
        av.load_g,
        av.heat_rate,
    )
    return ca.Function("aux", [xs, us, ss, ps], [values])


def _point_function(ocp: OptimalControlProblem, ode: _EntryOde) -> ca.Function:
    """(x, s, p) -> :data:`POINT_NAMES` at a state point: the kinematic state and the
    energy, without controls."""
    xs = ca.SX.sym("x", ocp.nx)
    ss = ca.SX.sym("s")
    ps = ca.SX.sym("p", ocp.npar)
    zero_u = ca.SX.zeros(ocp.nu)
    h, lon, lat, v, gamma, psi, _, _, _, energy = ode.unpack(xs, zero_u, ss, ps)
    if ode.energy_form:
        # The exact speed, without the floor used inside the NLP.
        v = ca.sqrt(ca.fmax(2.0 * (energy - ode.p.potential(h)), 0.0))
    return ca.Function("point", [xs, ss, ps], [ca.vertcat(h, lon, lat, v, gamma, psi, energy)])
