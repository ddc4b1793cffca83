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

from dataclasses import dataclass

import casadi as ca
import numpy as np

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
    """Build the OCP of ``problem`` with ``independent`` = ``"energy"`` or ``"time"``."""
    if independent not in ("energy", "time"):
        raise ValueError(f"independent must be 'energy' or 'time', got {independent!r}")
    p = problem
    model = EntryExpressions(p)
    circle = GreatCircle(
        float(p.initial_state[1]), float(p.initial_state[2]), float(p.initial_state[5])
    )
    rl = (p.control_rate[0] is not None, p.control_rate[1] is not None)
    energy_form = independent == "energy"
    base = [0, 1, 2, 4, 5] if energy_form else [0, 1, 2, 3, 4, 5]
    base_names = ("altitude", "longitude", "latitude", "speed", "fpa", "heading")
    state_names = [base_names[i] for i in base]
    state_lower = list(p.state_lower[base])
    state_upper = list(p.state_upper[base])
    initial = list(p.initial_state[base])
    final_lower = list(p.final_lower[base])
    final_upper = list(p.final_upper[base])
    v_scale = float(p.initial_state[3])
    # Altitude in units of the initial one (or of its bound, starting on the ground).
    h0 = float(p.initial_state[0])
    altitude_scale = h0 if h0 > 0.0 else float(max(abs(p.state_lower[0]), abs(p.state_upper[0])))
    scale = [altitude_scale, 1.0, 1.0, v_scale, 1.0, 1.0]
    state_scale = [scale[i] for i in base]
    control_names, control_lower, control_upper, control_scale = [], [], [], []
    for j, name in enumerate(("alpha", "bank")):
        if rl[j]:
            state_names.append(name)
            state_lower.append(p.control_lower[j])
            state_upper.append(p.control_upper[j])
            initial.append(-np.inf)
            final_lower.append(-np.inf)
            final_upper.append(np.inf)
            state_scale.append(1.0)
            rate = float(p.control_rate[j])  # type: ignore[arg-type]
            control_names.append(f"{name}_rate")
            control_lower.append(-rate)
            control_upper.append(rate)
        else:
            control_names.append(name)
            control_lower.append(p.control_lower[j])
            control_upper.append(p.control_upper[j])
        control_scale.append(1.0)
    increasing: tuple[int, ...] = ()
    if energy_form:
        # Time is a state (rate dt/de): collocated like the others, so the recovered time
        # is the collocation polynomial's, and it must increase between the state points.
        increasing = (len(state_names),)
        state_names.append("time")
        state_lower.append(0.0)
        state_upper.append(float(p.final_time_bounds[1]))
        initial.append(0.0)
        final_lower.append(0.0)
        final_upper.append(float(p.final_time_bounds[1]))
        state_scale.append(float(traj.t[-1]) if traj.t[-1] > 0 else 1.0)
    initial_lower = [v if np.isfinite(v) else -np.inf for v in initial]
    initial_upper = [v if np.isfinite(v) else np.inf for v in initial]
    nbase = len(base)

    e0 = p.initial_energy
    v_lo, v_hi = float(p.state_lower[3]), float(p.state_upper[3])

    def unpack(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> tuple:
        """Physical (h, lon, lat, V, gamma, psi, alpha, bank, [rates or None], E)."""
        h, lon, lat = x[0], x[1], x[2]
        if energy_form:
            ef = par[0]
            energy = e0 + s * (ef - e0)
            v2 = 2.0 * (energy - p.potential(h))
            # The floor keeps V real at infeasible iterates; the path constraint on V^2
            # keeps the solution above it.
            v = ca.sqrt(ca.fmax(v2, v_lo**2))
            gamma, psi = x[3], x[4]
        else:
            v, gamma, psi = x[3], x[4], x[5]
            energy = p.energy(h, v)
        controls = []
        rates = []
        k_state, k_control = nbase, 0
        for j in range(2):
            if rl[j]:
                controls.append(x[k_state])
                rates.append(u[k_control])
                k_state += 1
            else:
                controls.append(u[k_control])
                rates.append(None)
            k_control += 1
        return h, lon, lat, v, gamma, psi, controls[0], controls[1], rates, energy

    def time_derivatives(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> tuple:
        h, lon, lat, v, gamma, psi, alpha, bank, rates, energy = unpack(x, u, s, par)
        av = model.aero(h, v, alpha)
        d = model.time_rates(h, lat, v, gamma, psi, bank, av)
        return d, av, rates, (h, lon, lat, v, gamma, psi, alpha, bank, energy)

    def energy_rate(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        """E' = V V' + g h' [W/kg] (-V D without Earth rotation, seed eq. 9)."""
        d, _, _, phys = time_derivatives(x, u, s, par)
        h, v = phys[0], phys[3]
        return v * d[3] + model.gravity(h) * d[0]

    def dt_ds(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        if not energy_form:
            return ca.SX(1.0)
        return (par[0] - e0) / energy_rate(x, u, s, par)

    def dynamics(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        d, _, rates, _ = time_derivatives(x, u, s, par)
        rows = [d[i] for i in base] + [r for r in rates if r is not None]
        if not energy_form:
            return ca.vertcat(*rows)
        rate = dt_ds(x, u, s, par)
        return ca.vertcat(ca.vertcat(*rows) * rate, rate)

    path_lower: list[float] = []
    path_upper: list[float] = []

    def path(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
        _, av, _, phys = time_derivatives(x, u, s, par)
        rows = []
        if p.max_load_g is not None:
            rows.append(av.load_g / p.max_load_g)
        if p.max_dynamic_pressure is not None:
            rows.append(av.dynamic_pressure / p.max_dynamic_pressure)
        if p.max_heat_rate is not None:
            rows.append(av.heat_rate / p.max_heat_rate)
        if energy_form:
            h = phys[0]
            rows.append(2.0 * (e0 + s * (par[0] - e0) - p.potential(h)) / v_scale**2)
            # The energy must decrease (dt/de > 0): E' <= 0, scaled by g0 V0.
            rows.append(energy_rate(x, u, s, par) / (p.g0 * v_scale))
        return ca.vertcat(*rows)

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
        path_lower.append(v_lo**2 / v_scale**2)
        path_upper.append(v_hi**2 / v_scale**2)
        path_lower.append(-np.inf)
        path_upper.append(0.0)

    def final_angles(xf: ca.SX) -> tuple[ca.SX, ca.SX]:
        return circle.angles_sx(xf[1], xf[2])

    mayer = None
    lagrange = None
    if p.objective == "max_downrange":

        def mayer(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
            return -final_angles(xf)[0]

    elif p.objective == "max_crossrange":

        def mayer(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
            return -xf[2]

    elif p.objective == "min_time" and not energy_form:

        def mayer(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
            return sf

    elif p.objective == "min_time":
        lagrange = dt_ds
    else:

        def lagrange(x: ca.SX, u: ca.SX, s: ca.SX, par: ca.SX) -> ca.SX:
            _, av, _, _ = time_derivatives(x, u, s, par)
            return av.heat_rate * dt_ds(x, u, s, par)

    boundary = None
    boundary_lower = np.zeros(0)
    boundary_upper = np.zeros(0)
    parameter_names: tuple[str, ...] = ()
    parameter_lower = parameter_upper = parameter_scale = np.zeros(0)
    if energy_form:
        parameter_names = ("final_energy",)
        e_lo, e_hi = p.terminal_energy_bounds()
        parameter_lower = np.array([e_lo])
        parameter_upper = np.array([min(e_hi, e0)])
        parameter_scale = np.array([abs(e0)])
        if not p.terminal_energy_fixed:
            v_f_lo, v_f_hi = float(p.final_lower[3]), float(p.final_upper[3])

            def boundary(x0: ca.SX, xf: ca.SX, sf: ca.SX, par: ca.SX) -> ca.SX:
                return 2.0 * (par[0] - p.potential(xf[0])) / v_scale**2

            boundary_lower = np.array([max(v_f_lo, 0.0) ** 2 / v_scale**2])
            boundary_upper = np.array([v_f_hi**2 / v_scale**2])
        sf_bounds = (1.0, 1.0)
        sf_scale = 1.0
    else:
        sf_bounds = p.final_time_bounds
        sf_scale = float(traj.t[-1]) if traj.t[-1] > 0 else 1.0

    ocp = OptimalControlProblem(
        state_names=tuple(state_names),
        control_names=tuple(control_names),
        dynamics=dynamics,
        state_lower=np.array(state_lower, dtype=float),
        state_upper=np.array(state_upper, dtype=float),
        control_lower=np.array(control_lower, dtype=float),
        control_upper=np.array(control_upper, dtype=float),
        initial_lower=np.array(initial_lower, dtype=float),
        initial_upper=np.array(initial_upper, dtype=float),
        final_lower=np.array(final_lower, dtype=float),
        final_upper=np.array(final_upper, dtype=float),
        s0=0.0,
        sf_bounds=sf_bounds,
        state_scale=np.array(state_scale, dtype=float),
        control_scale=np.array(control_scale, dtype=float),
        sf_scale=sf_scale,
        objective_scale=_objective_scale(p, traj, circle),
        mayer=mayer,
        lagrange=lagrange,
        path=path if path_lower else None,
        path_lower=np.array(path_lower, dtype=float),
        path_upper=np.array(path_upper, dtype=float),
        increasing_states=increasing,
        boundary=boundary,
        boundary_lower=boundary_lower,
        boundary_upper=boundary_upper,
        parameter_names=parameter_names,
        parameter_lower=parameter_lower,
        parameter_upper=parameter_upper,
        parameter_scale=parameter_scale,
    )

    xs = ca.SX.sym("x", ocp.nx)
    us = ca.SX.sym("u", ocp.nu)
    ss = ca.SX.sym("s")
    ps = ca.SX.sym("p", ocp.npar)
    _, av, _, phys = time_derivatives(xs, us, ss, ps)
    h, lon, lat, v, gamma, psi, alpha, bank, energy = phys
    aux = ca.Function(
        "aux",
        [xs, us, ss, ps],
        [
            ca.vertcat(
                dt_ds(xs, us, ss, ps),
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
        ],
    )
    # At state points without controls: the kinematic state and the energy.
    zero_u = ca.SX.zeros(ocp.nu)
    h, lon, lat, v, gamma, psi, _, _, _, energy = unpack(xs, zero_u, ss, ps)
    if energy_form:
        # The exact speed, without the floor used inside the NLP.
        v = ca.sqrt(ca.fmax(2.0 * (energy - p.potential(h)), 0.0))
    point = ca.Function("point", [xs, ss, ps], [ca.vertcat(h, lon, lat, v, gamma, psi, energy)])
    return Formulation(
        problem=p,
        independent=independent,
        ocp=ocp,
        aux=aux,
        point=point,
        rate_limited=rl,
        circle=circle,
    )
