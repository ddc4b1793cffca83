"""Solve an optimal-entry problem: guess, transcribe, optimise, read back, re-fly.

:func:`solve_optimal_entry` runs the whole chain of seed 001 on an
:class:`~ovtraj.reentry.pseudospectral.problem.EntryProblem`:

1. an initial guess flown with constant controls (:mod:`.guess`);
2. the problem in energy or time (:mod:`.formulation`), transcribed by LG or LGR
   collocation (:mod:`.transcription`);
3. the NLP solved by IPOPT or a scipy method (:mod:`.nlp`);
4. histories at the nodes (time recovered by the exact quadrature of ``dt/de`` in the
   energy formulation) and the feasibility check (:mod:`.feasibility`).

It never raises for a problem that was accepted at load time: a failed optimisation is a
result with ``converged=False`` and the solver's status. The whole solve (guess, NLP,
re-flights) runs under ``solver.time_limit_s`` of wall time: when the guess flight uses
it up, the NLP is not started; either way the result is unconverged and its reason
names the limit (as it does for ``solver.max_iterations``).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from ovtraj.config.base import ConfigError
from ovtraj.deadline import Deadline
from ovtraj.reentry.pseudospectral.feasibility import FeasibilityReport, check_feasibility
from ovtraj.reentry.pseudospectral.formulation import AUX_NAMES, POINT_NAMES, Formulation, formulate
from ovtraj.reentry.pseudospectral.guess import guess_trajectory
from ovtraj.reentry.pseudospectral.nlp import NlpSolution, solve_nlp, stopped_before
from ovtraj.reentry.pseudospectral.problem import EntryProblem
from ovtraj.reentry.pseudospectral.result import OptimalEntryResult
from ovtraj.reentry.pseudospectral.transcription import DiscreteSolution, transcribe

__all__ = ["solve_optimal_entry"]

_OBJECTIVE_UNIT = {
    "max_downrange": "km",
    "max_crossrange": "deg",
    "min_heat_load": "MJ/m^2",
    "min_time": "s",
}


def solve_optimal_entry(
    problem: EntryProblem,
    *,
    independent: str | None = None,
    transcription: str | None = None,
) -> OptimalEntryResult:
    """Optimise ``problem``; ``independent`` (``"energy"``/``"time"``) and ``transcription``
    (``"lg"``/``"lgr"``) override the config's choices.

    Raises :class:`ValueError` for an unknown choice and
    :class:`~ovtraj.config.ConfigError` when the energy formulation is asked for a problem
    it cannot pose; every outcome of the optimisation itself is a result.
    """
    independent = independent or problem.independent
    method = transcription or problem.method
    if independent not in ("energy", "time"):
        raise ValueError(f"independent must be 'energy' or 'time', got {independent!r}")
    if method not in ("lg", "lgr"):
        raise ValueError(f"transcription must be 'lg' or 'lgr', got {method!r}")
    if independent == "energy" and problem.state_lower[3] <= 0.0:
        raise ConfigError(
            [
                "state_bounds.speed_mps: the energy formulation needs a positive lower speed "
                "(the speed is recovered from the energy by a square root)"
            ],
            problem.source,
        )
    start = time.perf_counter()
    deadline = Deadline(problem.solver.time_limit_s, "solver.time_limit_s")
    traj = guess_trajectory(problem, deadline)
    form = formulate(problem, independent, traj)
    tr = transcribe(form.ocp, method, problem.nodes_per_segment, problem.segments)
    w0 = tr.initial_point(form.guess(traj))
    if deadline.reached:
        reason = f"{deadline.reason()} while flying the initial guess"
        sol = stopped_before(w0, reason, problem.solver.backend)
    else:
        sol = solve_nlp(tr, w0, problem.solver, deadline)
    solve_time = time.perf_counter() - start
    discrete = tr.unpack(sol.w)
    return _result(problem, form, discrete, sol, method, solve_time, deadline)


def _histories(
    form: Formulation, d: DiscreteSolution
) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray]:
    """States at every state point, controls and path quantities at the collocation points."""
    p = form.problem
    tr = d.transcription
    k = tr.n_colloc
    params = np.tile(d.p, (k, 1)).T if d.p.size else np.zeros((0, k))
    aux = np.asarray(form.aux.map(k)(d.x_colloc.T, d.u.T, d.s_colloc, params), dtype=float)
    a = dict(zip(AUX_NAMES, aux, strict=True))
    m = tr.n_points
    point_params = np.tile(d.p, (m, 1)).T if d.p.size else np.zeros((0, m))
    pts = np.asarray(form.point.map(m)(d.x.T, d.s, point_params), dtype=float)
    pt = dict(zip(POINT_NAMES, pts, strict=True))
    if form.independent == "energy":
        t_points = d.cumulative(a["dt_ds"])
    else:
        t_points = d.s
    t_colloc = t_points[tr.colloc_point]
    downrange, crossrange = form.circle.angles(pt["longitude"], pt["latitude"])
    s_name = "energy_normalised" if form.independent == "energy" else "time_s"
    states = pd.DataFrame(
        {
            s_name: d.s,
            "time_s": t_points,
            "altitude_km": pt["altitude"] / 1e3,
            "longitude_deg": np.degrees(pt["longitude"]),
            "latitude_deg": np.degrees(pt["latitude"]),
            "speed_mps": pt["speed"],
            "fpa_deg": np.degrees(pt["fpa"]),
            "heading_deg": np.degrees(pt["heading"]),
            "downrange_km": downrange * p.radius / 1e3,
            "crossrange_km": crossrange * p.radius / 1e3,
            "energy_mj_kg": pt["energy"] / 1e6,
        }
    )
    names = form.ocp.state_names
    for j, name in enumerate(("alpha", "bank")):
        if form.rate_limited[j]:
            states[f"{name}_deg"] = np.degrees(d.x[:, names.index(name)])
    controls = pd.DataFrame(
        {
            s_name: d.s_colloc,
            "time_s": t_colloc,
            "alpha_deg": np.degrees(a["alpha"]),
            "bank_deg": np.degrees(a["bank"]),
            "mach": a["mach"],
            "density_kg_m3": a["density"],
            "cl": a["cl"],
            "cd": a["cd"],
            "lift_to_drag": a["cl"] / a["cd"],
            "dynamic_pressure_kpa": a["dynamic_pressure"] / 1e3,
            "load_g": a["load_g"],
            "heat_rate_kw_m2": a["heat_rate"] / 1e3,
        }
    )
    for j, name in enumerate(form.ocp.control_names):
        if name.endswith("_rate"):
            controls[f"{name}_deg_s"] = np.degrees(d.u[:, j])
    heat_rate_dt = a["heat_rate"] * a["dt_ds"]
    heat_load = d.integral(heat_rate_dt)
    return states, controls, np.array([heat_load])


def _feasibility(
    form: Formulation, states: pd.DataFrame, controls: pd.DataFrame, deadline: Deadline
) -> tuple[FeasibilityReport, ...]:
    p = form.problem
    final = states.iloc[-1]
    final_state = np.array(
        [
            final["altitude_km"] * 1e3,
            math.radians(final["longitude_deg"]),
            math.radians(final["latitude_deg"]),
            final["speed_mps"],
            math.radians(final["fpa_deg"]),
            math.radians(final["heading_deg"]),
        ]
    )
    final_time = float(final["time_s"])
    # Rate-limited angles are states, known at every state point (ends included).
    source = states if "alpha_deg" in states else controls
    t = source["time_s"].to_numpy()
    alpha = np.radians(source["alpha_deg"].to_numpy())
    bank = np.radians((states if "bank_deg" in states else controls)["bank_deg"].to_numpy())
    t_bank = (states if "bank_deg" in states else controls)["time_s"].to_numpy()
    if len(t_bank) != len(t):
        # One angle a state, the other a control: put both on the collocation times.
        t = controls["time_s"].to_numpy()
        alpha = np.interp(t, source["time_s"].to_numpy(), alpha)
        bank = np.interp(t, t_bank, bank)
    reports = []
    for kind in p.config.feasibility.interpolations:
        reports.append(
            check_feasibility(p, t, alpha, bank, final_time, final_state, kind, deadline)
        )
    return tuple(reports)


def _result(
    problem: EntryProblem,
    form: Formulation,
    d: DiscreteSolution,
    sol: NlpSolution,
    method: str,
    solve_time: float,
    deadline: Deadline,
) -> OptimalEntryResult:
    states, controls, extra = _histories(form, d)
    finite = bool(np.all(np.isfinite(states.to_numpy(dtype=float))))
    reports: tuple[FeasibilityReport, ...] = ()
    # Re-flying is meaningful (and affordable) only for an optimum.
    if sol.converged and finite and states["time_s"].iloc[-1] > 0.0:
        reports = _feasibility(form, states, controls, deadline)
    final = states.iloc[-1]
    objective = problem.objective
    value = {
        "max_downrange": float(final["downrange_km"]),
        "max_crossrange": float(final["latitude_deg"]),
        "min_heat_load": float(extra[0]) / 1e6,
        "min_time": float(final["time_s"]),
    }[objective]
    reason = None
    converged = sol.converged
    if sol.limit is not None:
        reason = f"{sol.limit} ({sol.backend}: {sol.status})"
    elif not sol.converged:
        reason = f"{sol.backend}: {sol.status}"
    elif any(r.status == "time limit" for r in reports):
        converged = False
        reason = f"{deadline.reason()} while re-flying the optimal controls (feasibility check)"
    return OptimalEntryResult(
        name=problem.name,
        objective=objective,
        independent=form.independent,
        method=method,
        segments=problem.segments,
        nodes_per_segment=problem.nodes_per_segment,
        converged=converged,
        status=sol.status,
        reason=reason,
        backend=sol.backend,
        objective_value=value,
        objective_unit=_OBJECTIVE_UNIT[objective],
        final_time_s=float(final["time_s"]),
        range_km=float(final["downrange_km"]),
        crossrange_km=float(final["crossrange_km"]),
        final_latitude_deg=float(final["latitude_deg"]),
        final_longitude_deg=float(final["longitude_deg"]),
        final_altitude_km=float(final["altitude_km"]),
        final_speed_mps=float(final["speed_mps"]),
        final_fpa_deg=float(final["fpa_deg"]),
        final_heading_deg=float(final["heading_deg"]),
        max_load_g=float(np.max(np.abs(controls["load_g"]))),
        max_dynamic_pressure_kpa=float(np.max(controls["dynamic_pressure_kpa"])),
        max_heat_rate=float(np.max(controls["heat_rate_kw_m2"])),
        heat_load_mj_m2=float(extra[0]) / 1e6,
        nlp_iterations=sol.iterations,
        solve_time_s=solve_time,
        nlp_build_time_s=sol.build_time_s,
        nlp_solve_time_s=sol.solve_time_s,
        max_constraint_violation=sol.max_constraint_violation,
        feasibility_error_km=max((r.position_error_km for r in reports), default=math.nan),
        feasibility_error_deg=max((r.angle_error_deg for r in reports), default=math.nan),
        feasibility=reports,
        states=states,
        controls=controls,
    )
