"""Solve an optimal-entry problem: guess, transcribe, optimise, read back, re-fly.

:func:`solve_optimal_entry` runs the whole chain of seed 001 on an
:class:`~ovtraj.studies.optimal_entry.problem.EntryProblem`:

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
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ovtraj.config.base import ConfigError
from ovtraj.deadline import Deadline
from ovtraj.studies.optimal_entry.feasibility import (
    FeasibilityReport,
    check_feasibility,
    control_table,
)
from ovtraj.studies.optimal_entry.flight_kernel import ControlTable
from ovtraj.studies.optimal_entry.formulation import AUX_NAMES, POINT_NAMES, Formulation, formulate
from ovtraj.studies.optimal_entry.guess import guess_trajectory
from ovtraj.studies.optimal_entry.mesh import refined_edges, segment_errors
from ovtraj.studies.optimal_entry.nlp import NlpSolution, solve_nlp, stopped_before
from ovtraj.studies.optimal_entry.ocp import Guess
from ovtraj.studies.optimal_entry.problem import EntryProblem
from ovtraj.studies.optimal_entry.result import OptimalEntryResult
from ovtraj.studies.optimal_entry.transcription import (
    DiscreteSolution,
    Transcription,
    transcribe,
)

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
    independent = problem.independent if independent is None else independent
    method = problem.method if transcription is None else transcription
    _check_choices(problem, independent, method)
    start = time.perf_counter()
    deadline = Deadline(problem.solver.time_limit_s, "solver.time_limit_s")
    traj = guess_trajectory(problem, deadline)
    form = formulate(problem, independent, traj)
    guess = form.guess(traj)
    mesh = problem.config.transcription
    edges = np.linspace(0.0, 1.0, problem.segments + 1)
    refinements, iterations = 0, 0
    while True:
        tr = transcribe(form.ocp, method, problem.nodes_per_segment, edges=edges)
        sol = _solve_mesh(problem, tr, tr.initial_point(guess), refinements, deadline)
        iterations += sol.iterations
        discrete = tr.unpack(sol.w)
        outcome = _assess(problem, form, discrete, sol, deadline)
        if (
            outcome.accepted
            or not sol.converged
            or refinements >= mesh.max_refinements
            or deadline.reached
        ):
            break
        refined = _refined_mesh(problem, tr, edges, outcome, deadline)
        if refined is None:
            break
        edges = refined
        guess = _warm_start(discrete)
        refinements += 1
    solve_time = time.perf_counter() - start
    return _result(
        problem, form, discrete, sol, outcome, method, solve_time, refinements, iterations
    )


def _check_choices(problem: EntryProblem, independent: str, method: str) -> None:
    """Refuse an unknown formulation or transcription, and the energy formulation of a
    problem whose speed may reach zero."""
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


def _solve_mesh(
    problem: EntryProblem,
    tr: Transcription,
    w0: np.ndarray,
    refinements: int,
    deadline: Deadline,
) -> NlpSolution:
    """One mesh's NLP solved from ``w0``, or not started once the deadline has passed."""
    if deadline.reached:
        when = "while flying the initial guess" if refinements == 0 else "refining the mesh"
        return stopped_before(w0, f"{deadline.reason()} {when}", problem.solver.backend)
    return solve_nlp(tr, w0, problem.solver, deadline)


def _refined_mesh(
    problem: EntryProblem,
    tr: Transcription,
    edges: np.ndarray,
    outcome: _Outcome,
    deadline: Deadline,
) -> np.ndarray | None:
    """The next mesh's segment edges, split where a segment's re-flight misses (None: no
    refinement, the verdict stands)."""
    t_points = outcome.states["time_s"].to_numpy()
    if np.all(np.diff(t_points) > 0.0):
        try:
            errors = segment_errors(
                problem,
                t_points,
                _physical_states(outcome.states),
                tr.segment_points,
                _controls(problem, outcome),
                deadline,
            )
        except (ArithmeticError, ValueError):  # no refinement then: the verdict stands
            return None
    else:  # energy: split the segments where the recovered time goes backwards
        errors = np.array(
            [np.inf if np.any(np.diff(t_points[pts]) <= 0.0) else 0.0 for pts in tr.segment_points]
        )
    terminal = min((r.position_error_km for r in outcome.reports), default=None)
    return refined_edges(
        edges,
        errors,
        problem.config.feasibility.tolerance_km,
        problem.config.transcription.max_segments,
        terminal,
    )


def _histories(
    form: Formulation, d: DiscreteSolution
) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray, np.ndarray]:
    """States at every state point, controls and path quantities at the collocation points,
    the heat load and dt/ds at the collocation points."""
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
        t_points = d.x[:, form.ocp.state_names.index("time")]
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
    return states, controls, np.array([heat_load]), a["dt_ds"]


def _control_samples(
    states: pd.DataFrame, controls: pd.DataFrame
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times [s], angle of attack and bank [rad] where the controls are known."""
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
    return t, alpha, bank


def _feasibility(
    form: Formulation, states: pd.DataFrame, controls: pd.DataFrame, deadline: Deadline
) -> tuple[FeasibilityReport, ...]:
    p = form.problem
    final_state = _physical_states(states)[-1]
    final_time = float(states["time_s"].iloc[-1])
    t, alpha, bank = _control_samples(states, controls)
    return tuple(
        check_feasibility(p, t, alpha, bank, final_time, final_state, kind, deadline)
        for kind in p.config.feasibility.interpolations
    )


@dataclass(frozen=True)
class _Outcome:
    """One mesh's solution read back, re-flown and judged."""

    states: pd.DataFrame
    controls: pd.DataFrame
    heat_load: float
    reports: tuple[FeasibilityReport, ...]
    accepted: bool
    reason: str | None


def _assess(
    problem: EntryProblem,
    form: Formulation,
    d: DiscreteSolution,
    sol: NlpSolution,
    deadline: Deadline,
) -> _Outcome:
    """Histories, the re-flights and the verdict: converged means the NLP succeeded and
    every re-flight of the interpolated controls meets ``feasibility.tolerance_km`` and
    ``tolerance_deg``; anything else says why."""
    states, controls, extra, dt_ds = _histories(form, d)
    settings = problem.config.feasibility

    def refused(reason: str) -> _Outcome:
        return _Outcome(states, controls, float(extra[0]), (), False, reason)

    if sol.limit is not None:
        return refused(f"{sol.limit} ({sol.backend}: {sol.status})")
    if not sol.converged:
        return refused(f"{sol.backend}: {sol.status}")
    if not bool(np.all(np.isfinite(states.to_numpy(dtype=float)))):
        return refused("the solution has non-finite values")
    if form.independent == "energy":
        refusal = _energy_refusal(dt_ds, states)
        if refusal is not None:
            return refused(refusal)
    try:
        reports = _feasibility(form, states, controls, deadline)
    except (ArithmeticError, ValueError) as err:  # e.g. controls that cannot be splined
        return refused(f"the re-flight of the optimal controls failed: {err}")
    if any(r.status == "time limit" for r in reports):
        reason = f"{deadline.reason()} while re-flying the optimal controls (feasibility check)"
        return _Outcome(states, controls, float(extra[0]), reports, False, reason)
    # A flight needs one reconstruction of the controls that flies: any configured one.
    if any(
        r.position_error_km <= settings.tolerance_km and r.angle_error_deg <= settings.tolerance_deg
        for r in reports
    ):
        return _Outcome(states, controls, float(extra[0]), reports, True, None)
    closest = min(reports, key=lambda r: r.position_error_km)
    reason = (
        f"no re-flight of the interpolated controls meets the tolerance: the closest "
        f"({closest.interpolation}) ends {closest.position_error_km:.3g} km and "
        f"{closest.angle_error_deg:.3g} deg from the optimised terminal state "
        f"(feasibility.tolerance_km {settings.tolerance_km:g}, tolerance_deg "
        f"{settings.tolerance_deg:g})"
    )
    return _Outcome(states, controls, float(extra[0]), reports, False, reason)


def _energy_refusal(dt_de: np.ndarray, states: pd.DataFrame) -> str | None:
    """Why an energy-formulation solution cannot stand, if it cannot: the energy must
    decrease along the flight (dt/dE > 0 at the collocation points: drag work), and the
    time recovered from dt/dE must then increase from state point to state point."""
    if np.any(dt_de <= 0.0):
        return (
            "the energy formulation needs the energy to decrease along the flight (drag "
            f"work); it does not at {int(np.sum(dt_de <= 0.0))} collocation points: solve "
            "this problem in time (transcription.independent: time)"
        )
    steps = np.diff(states["time_s"].to_numpy())
    if np.any(steps <= 0.0):
        return (
            "the time recovered from dt/dE decreases between state points (by up to "
            f"{-float(np.min(steps)):.3g} s): the mesh does not resolve dt/dE"
        )
    return None


def _physical_states(states: pd.DataFrame) -> np.ndarray:
    """Rows of (h, lon, lat, V, gamma, psi), SI, at every state point."""
    return np.column_stack(
        [
            states["altitude_km"].to_numpy() * 1e3,
            np.radians(states["longitude_deg"].to_numpy()),
            np.radians(states["latitude_deg"].to_numpy()),
            states["speed_mps"].to_numpy(),
            np.radians(states["fpa_deg"].to_numpy()),
            np.radians(states["heading_deg"].to_numpy()),
        ]
    )


def _controls(problem: EntryProblem, outcome: _Outcome) -> ControlTable:
    """The optimal controls of the first configured interpolation, as functions of time."""
    kind = problem.config.feasibility.interpolations[0]
    t, alpha, bank = _control_samples(outcome.states, outcome.controls)
    lo, hi = problem.control_lower, problem.control_upper
    return control_table(t, alpha, bank, kind, lo, hi)


def _warm_start(d: DiscreteSolution) -> Guess:
    """A solved mesh as the next mesh's starting point (controls onto the state points)."""
    u = np.column_stack([np.interp(d.s, d.s_colloc, col) for col in d.u.T])
    return Guess(s=d.s, x=d.x, u=u, sf=d.sf, p=d.p)


def _result(
    problem: EntryProblem,
    form: Formulation,
    d: DiscreteSolution,
    sol: NlpSolution,
    outcome: _Outcome,
    method: str,
    solve_time: float,
    refinements: int,
    iterations: int,
) -> OptimalEntryResult:
    states, controls, reports = outcome.states, outcome.controls, outcome.reports
    final = states.iloc[-1]
    objective = problem.objective
    value = {
        "max_downrange": float(final["downrange_km"]),
        "max_crossrange": float(final["latitude_deg"]),
        "min_heat_load": outcome.heat_load / 1e6,
        "min_time": float(final["time_s"]),
    }[objective]
    reason = outcome.reason
    if reason is not None and refinements:
        reason += (
            f"; after {refinements} mesh refinement(s), {d.transcription.segments} segments "
            f"(transcription.max_refinements {problem.config.transcription.max_refinements}, "
            f"max_segments {problem.config.transcription.max_segments})"
        )
    return OptimalEntryResult(
        name=problem.name,
        objective=objective,
        independent=form.independent,
        method=method,
        segments=d.transcription.segments,
        nodes_per_segment=problem.nodes_per_segment,
        converged=outcome.accepted,
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
        heat_load_mj_m2=outcome.heat_load / 1e6,
        nlp_iterations=iterations,
        solve_time_s=solve_time,
        nlp_build_time_s=sol.build_time_s,
        nlp_solve_time_s=sol.solve_time_s,
        max_constraint_violation=sol.max_constraint_violation,
        feasibility_error_km=max((r.position_error_km for r in reports), default=math.nan),
        feasibility_error_deg=max((r.angle_error_deg for r in reports), default=math.nan),
        refinements=refinements,
        feasibility=reports,
        states=states,
        controls=controls,
    )
