"""Solve a manoeuvre: global search of the impulse plan, then the finite-thrust correction.

1. :func:`search_impulses`: the seed's IDE (or scipy's DE) over the decision vector of
   :mod:`ovtraj.studies.maneuver.problem`, every individual flown by
   :class:`~ovtraj.studies.maneuver.impulsive.ImpulsiveModel` (exact last leg, constraints).
2. The best plan is flown again, impulse by impulse, with the propagator (the check
   that the exact last leg really meets the end condition).
3. :class:`~ovtraj.studies.maneuver.finite_burn.FiniteBurnSolver` turns it into finite burns and
   re-optimises them with SLSQP (when enabled and the plan is feasible).

Infeasible requests (e.g. a budget too small for the end condition) return a result with
``converged = False``, the best violation found and the reason; they never raise. So does
a search stopped by ``optimizer.time_limit_s`` (the finite burns are then not tried) and a
correction stopped by ``finite_burn.time_limit_s`` or ``finite_burn.max_iterations``: the
reason names the limit.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.deadline import Deadline
from ovtraj.studies.maneuver.de import DEResult, improved_de, scipy_de
from ovtraj.studies.maneuver.endpoint import orbit_point
from ovtraj.studies.maneuver.finite_burn import FiniteBurnResult, FiniteBurnSolver
from ovtraj.studies.maneuver.impulsive import CONSTRAINT_NAMES, ImpulsiveModel, PlanBatch
from ovtraj.studies.maneuver.problem import ManeuverProblem
from ovtraj.studies.maneuver.result import BurnReport, ManeuverResult

__all__ = ["population_size", "reflight_impulses", "search_impulses", "solve_maneuver"]


def population_size(problem: ManeuverProblem) -> int:
    """N = max(min_population, population_per_variable x number of variables) (seed: 5 n)."""
    opt = problem.optimizer
    return max(opt.min_population, opt.population_per_variable * problem.n_variables)


def search_impulses(
    problem: ManeuverProblem,
    *,
    method: str | None = None,
    seed: int | None = None,
    model: ImpulsiveModel | None = None,
) -> DEResult:
    """Global search of the impulse plan; ``method`` "ide" or "scipy" overrides the config."""
    model = model or ImpulsiveModel(problem)
    opt = problem.optimizer
    method = method or opt.method
    seed = opt.seed if seed is None else seed
    lower, upper = problem.bounds()

    def evaluate(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        batch = model.evaluate(x)
        return batch.objective, batch.constraints

    common = {
        "scale_factor": opt.scale_factor,
        "crossover_probability": opt.crossover_probability,
        "generations": opt.generations,
        "seed": seed,
        "stall_generations": opt.stall_generations,
        "stall_tolerance": opt.stall_tolerance,
        "deadline": Deadline(opt.time_limit_s, "optimizer.time_limit_s"),
    }
    if method == "ide":
        return improved_de(
            evaluate,
            lower,
            upper,
            population=population_size(problem),
            accept_equal=opt.accept_ties,
            **common,
        )
    if method == "scipy":
        # scipy sizes its population as popsize x variables (at least 5).
        return scipy_de(
            evaluate,
            lower,
            upper,
            n_constraints=len(CONSTRAINT_NAMES),
            population_per_variable=opt.population_per_variable,
            **common,
        )
    raise ValueError(f"unknown method {method!r} (ide or scipy)")


def reflight_impulses(
    problem: ManeuverProblem, plan: PlanBatch, index: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fly one plan impulse by impulse with the impulsive model's propagator.

    Returns the stage's state at t_f after any final impulse, and the goal there
    (target, or the target orbit's point at the stage's argument of latitude).
    """
    propagator = OrbitPropagator(problem.earth, tol=problem.integrator_tol, j2=problem.j2)
    epochs, dv, tof = plan.epochs[index], plan.dv[index], float(plan.time_of_flight[index])
    state = problem.chaser_state.copy()
    t = 0.0
    for k in range(problem.n_impulses):
        if epochs[k] > t:
            state = propagator.propagate(state, t, float(epochs[k])).state
            t = float(epochs[k])
        state = state.copy()
        state[3:] += dv[k]
    if tof > t:
        state = propagator.propagate(state, t, tof).state
    target = propagator.propagate(problem.target_state, 0.0, tof).state
    goal = (
        orbit_point(target, state[:3], problem.earth.mu) if problem.has_final_latitude else target
    )
    return state, goal


def _violation_reason(problem: ManeuverProblem, plan: PlanBatch) -> str:
    c = plan.constraints[0]
    parts = []
    if not plan.ok[0]:
        parts.append("the last leg could not be solved")
    if c[0] > 0:
        parts.append(
            f"sum |dv| = {plan.total_dv[0]:.1f} m/s > {problem.dv_limit_mps:.1f} m/s (eq. 4)"
        )
    if c[1] > 0:
        parts.append(
            f"burn time {plan.burn_time[0]:.1f} s > t_e = {problem.max_burn_time_s:.1f} s (eq. 13)"
        )
    if c[2] > 0:
        parts.append(
            f"an arc dips to {(plan.min_radius[0] - problem.earth.radius) / 1e3:.1f} km altitude"
        )
    return (
        f"no feasible impulse plan found (best violation {float(plan.violation[0]):.4g}): "
        + "; ".join(parts)
    )


def solve_maneuver(
    problem: ManeuverProblem,
    *,
    method: str | None = None,
    seed: int | None = None,
    finite: bool | None = None,
) -> ManeuverResult:
    """Solve ``problem`` (see the module notes); never raises for an infeasible request.

    ``method`` ("ide" or "scipy"), ``seed`` and ``finite`` (run the finite-thrust
    correction) override the config.
    """
    start = time.perf_counter()
    model = ImpulsiveModel(problem)
    search = search_impulses(problem, method=method, seed=seed, model=model)
    plan = model.evaluate(search.x[None, :])
    feasible = bool(plan.ok[0]) and float(plan.violation[0]) <= 0.0
    run_finite = problem.finite.enabled if finite is None else finite
    imp_dr, imp_dv = _impulsive_errors(problem, plan)
    reason = "" if feasible else _violation_reason(problem, plan)
    if search.limit is not None:
        reason = f"search stopped: {search.limit}" + (f"; {reason}" if reason else "")
    fin: FiniteBurnResult | None = None
    if feasible and run_finite and search.limit is None:
        solver = FiniteBurnSolver(
            problem, plan.epochs[0], plan.dv[0], float(plan.time_of_flight[0])
        )
        fin = solver.solve()
        if not fin.converged:
            reason = fin.message
    converged = feasible and search.limit is None and (fin is None or fin.converged)
    tof_imp = float(plan.time_of_flight[0]) if plan.ok[0] else None
    return ManeuverResult(
        name=problem.name,
        end_condition=problem.end_condition,
        objective=problem.objective,
        dynamics="j2" if problem.j2 else "two_body",
        n_impulses=problem.n_impulses,
        optimizer=method or problem.optimizer.method,
        seed=problem.optimizer.seed if seed is None else seed,
        converged=converged,
        reason=reason,
        impulsive_time_of_flight_s=tof_imp,
        **_impulse_fields(problem, plan, search),
        impulsive_position_error_m=imp_dr,
        impulsive_velocity_error_mps=imp_dv,
        **_finite_fields(problem, fin, tof_imp, imp_dr, imp_dv),
        generations=search.generations,
        evaluations=search.evaluations,
        search_time_s=search.wall_time_s,
        wall_time_s=time.perf_counter() - start,
        history=search.history,
    )


def _impulsive_errors(
    problem: ManeuverProblem, plan: PlanBatch
) -> tuple[float | None, float | None]:
    """Position [m] and (but for an interception) velocity [m/s] errors of the best plan
    flown again impulse by impulse; None when its last leg could not be solved."""
    imp_dr = imp_dv = None
    if plan.ok[0]:
        state, goal = reflight_impulses(problem, plan)
        imp_dr = float(np.linalg.norm(state[:3] - goal[:3]))
        if problem.end_condition != "interception":
            imp_dv = float(np.linalg.norm(state[3:] - goal[3:]))
    return imp_dr, imp_dv


def _impulse_fields(problem: ManeuverProblem, plan: PlanBatch, search: DEResult) -> dict:
    """The result's figures of the impulse plan: epochs, impulses, budget, constraints."""
    norms = np.linalg.norm(plan.dv[0], axis=1)
    return {
        "impulse_epochs_s": [float(t) for t in plan.epochs[0]],
        "impulse_dv_mps": [float(v) for v in norms],
        "impulse_vectors_eci_mps": [[float(c) for c in v] for v in plan.dv[0]],
        "total_dv_mps": float(plan.total_dv[0]),
        "dv_budget_mps": problem.dv_budget_mps,
        "dv_capacity_mps": problem.dv_capacity_mps,
        "dv_limit_mps": problem.dv_limit_mps,
        "impulse_burn_time_s": float(plan.burn_time[0]),
        "max_burn_time_s": problem.max_burn_time_s,
        "constraint_violation": float(plan.violation[0]) if plan.ok[0] else search.violation,
        "constraints": {
            name: float(v) for name, v in zip(CONSTRAINT_NAMES, plan.constraints[0], strict=True)
        },
    }


def _finite_fields(
    problem: ManeuverProblem,
    fin: FiniteBurnResult | None,
    tof_imp: float | None,
    imp_dr: float | None,
    imp_dv: float | None,
) -> dict:
    """The result's figures of the finite burns; where none were flown, the impulse
    plan's time of flight and errors and no burns."""
    burns = [
        BurnReport(
            start_s=b.start_s,
            duration_s=b.duration_s,
            dv_mps=b.dv_mps,
            mass_before_kg=b.mass_before_kg,
            mass_after_kg=b.mass_after_kg,
            direction_eci=tuple(float(c) for c in b.direction),
        )
        for b in (fin.burns if fin is not None else ())
    ]
    return {
        "finite_dynamics": problem.finite.dynamics if fin is not None else None,
        "time_of_flight_s": fin.time_of_flight_s if fin is not None else tof_imp,
        "burns": burns,
        "finite_total_dv_mps": sum(b.dv_mps for b in burns) if fin is not None else None,
        "total_burn_time_s": fin.total_burn_time_s if fin is not None else None,
        "final_mass_kg": burns[-1].mass_after_kg if burns else None,
        "final_position_error_m": fin.final_position_error_m if fin is not None else imp_dr,
        "final_velocity_error_mps": fin.final_velocity_error_mps if fin is not None else imp_dv,
        "relative_speed_mps": fin.relative_speed_mps if fin is not None else None,
        "conversion_position_error_m": fin.initial_position_error_m if fin is not None else None,
        "conversion_velocity_error_mps": fin.initial_velocity_error_mps
        if fin is not None
        else None,
        "final_state_eci": [float(c) for c in fin.final_state] if fin is not None else None,
        "goal_state_eci": [float(c) for c in fin.goal_state] if fin is not None else None,
        "finite_iterations": fin.iterations if fin is not None else None,
        "finite_flights": fin.flights if fin is not None else None,
        "finite_time_s": fin.wall_time_s if fin is not None else None,
    }
