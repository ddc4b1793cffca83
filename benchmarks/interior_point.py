"""The J2 correction's interior point against scipy's trust-constr, side by side.

Collects the correction problems the mission chain poses on the reference designs
(``configs/mission_reference.yaml``: each design's rendezvous, solved from its two
starts, and its transfer), then solves every one of them in this process with

1. ``ovtraj.rendezvous.interior_point`` (the shipped solver), and
2. scipy's ``trust-constr`` with the same derivatives, tolerances, barrier parameter and
   trust radius (the solver the interior point replaced to make the mission chain faster;
   its call is kept here for the comparison),

alternating the two ``--repeats`` times. It prints, per solver, the median wall time
of a correction (``correct_transfer``: start shots plus the solves), the summed
iterations, and the largest difference of the optimum's total impulse and arrival
epoch between the two; as its last line one JSON object with those figures and the
speed-up; the goal is the same optimum within the equality tolerances the replacement had to
meet (total impulse within 0.01 m/s, arrival within 1 s). ``--json`` prints only the JSON.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time
import warnings

import numpy as np
from goals import goal
from scipy.optimize import Bounds, NonlinearConstraint, minimize

import ovtraj.rendezvous.correction as correction
from ovtraj.deadline import Deadline
from ovtraj.mission import evaluate, reference
from ovtraj.rendezvous.interior_point import ITERATION_LIMIT, InteriorPointResult

# The equality tolerances of the replacement: the two solvers must give the same optima.
DV_GOAL_MPS = goal("interior_point", "dv_mps")
ARRIVAL_GOAL_S = goal("interior_point", "arrival_s")


def _trust_constr(transfer, start, problem) -> InteriorPointResult:
    """The call the correction made before the interior point, its result in the new type."""
    scale = transfer.miss_scale
    constraint = NonlinearConstraint(
        lambda x: transfer.at(x).miss / scale,
        0.0,
        0.0,
        jac=lambda x: transfer.at(x).d_miss / scale,
        hess=lambda x, v: np.einsum("i,ijk->jk", v, transfer.hessians(x)[1]) / scale,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        solution = minimize(
            lambda x: transfer.at(x).cost,
            start.x,
            jac=lambda x: transfer.at(x).grad,
            hess=lambda x: transfer.hessians(x)[0],
            method="trust-constr",
            constraints=[constraint],
            bounds=Bounds(*transfer.bounds()),
            options={
                "maxiter": problem.max_iterations,
                "gtol": problem.optimality_tol,
                "xtol": problem.optimality_tol * 1e-4,
                "initial_barrier_parameter": problem.initial_barrier_parameter,
                "barrier_tol": problem.optimality_tol,
                "initial_tr_radius": problem.initial_trust_radius,
            },
        )
    status = ITERATION_LIMIT if solution.status == 0 else str(solution.message)
    return InteriorPointResult(solution.x, np.zeros(3), int(solution.nit), status, np.nan)


def collect_problems(extra_designs: int, seed: int) -> list[correction.CorrectionProblem]:
    """Every correction problem of the reference designs' chains, and of ``extra_designs``
    more from a Latin hypercube over the design bounds (``seed``)."""
    from ovtraj.mission import MissionDesign
    from ovtraj.mission.chain import DESIGN_NAMES
    from ovtraj.mission.design_space import latin_hypercube

    problems: list[correction.CorrectionProblem] = []
    solve = correction.correct_transfer

    def recording(problem):
        # Replayed later: the stage's wall-time limit started with the stage.
        problems.append(dataclasses.replace(problem, deadline=Deadline.unlimited()))
        return solve(problem)

    correction.correct_transfer = recording
    import ovtraj.rendezvous.stage as stage

    stage.correct_transfer = recording
    try:
        settings = reference.load_settings()
        context = reference.context(settings)
        designs = reference.designs(context.scenario, settings)
        if extra_designs:
            bounds = context.scenario.mission.design_bounds
            table = latin_hypercube(bounds, extra_designs, seed)
            designs += [
                MissionDesign(**{name: float(getattr(row, name)) for name in DESIGN_NAMES})
                for row in table.itertuples(index=False)
            ]
        for design in designs:
            evaluate(context, design)
    finally:
        correction.correct_transfer = solve
        stage.correct_transfer = solve
    return problems


def solve_all(problems, solver) -> tuple[list[float], list[correction.CorrectionResult]]:
    shipped = correction._interior_point
    correction._interior_point = solver or shipped
    try:
        times, results = [], []
        for problem in problems:
            start = time.perf_counter()
            results.append(correction.correct_transfer(problem))
            times.append(time.perf_counter() - start)
    finally:
        correction._interior_point = shipped
    return times, results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--extra-designs", type=int, default=0, help="hypercube designs beyond the reference"
    )
    parser.add_argument("--seed", type=int, default=1, help="of the extra designs' hypercube")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print

    problems = collect_problems(args.extra_designs, args.seed)
    runs: dict[str, list[list[float]]] = {"interior point": [], "trust-constr": []}
    results: dict[str, list] = {}
    for _ in range(args.repeats):
        for name, solver in (("interior point", None), ("trust-constr", _trust_constr)):
            times, results[name] = solve_all(problems, solver)
            runs[name].append(times)
    medians = {
        name: [statistics.median(t[k] for t in rounds) for k in range(len(problems))]
        for name, rounds in runs.items()
    }
    ours, theirs = results["interior point"], results["trust-constr"]
    dv_diff = max(
        abs(
            float(np.linalg.norm(a.dv1_eci) + np.linalg.norm(a.dv2_eci))
            - float(np.linalg.norm(b.dv1_eci) + np.linalg.norm(b.dv2_eci))
        )
        for a, b in zip(ours, theirs, strict=True)
    )
    arrival_diff = max(
        abs((a.burn_time_s + a.transfer_time_s) - (b.burn_time_s + b.transfer_time_s))
        for a, b in zip(ours, theirs, strict=True)
    )
    figures = {
        name: {
            "median_correction_ms": round(statistics.median(medians[name]) * 1e3, 3),
            "total_ms": round(sum(medians[name]) * 1e3, 2),
            "iterations": sum(r.iterations for r in results[name]),
            "converged": sum(r.converged for r in results[name]),
        }
        for name in runs
    }
    speedup = figures["trust-constr"]["total_ms"] / figures["interior point"]["total_ms"]
    say(
        f"J2 corrections of the {len(problems)} problems the chains of the reference designs "
        f"and {args.extra_designs} more pose (rendezvous and transfers), medians of "
        f"{args.repeats} alternating rounds"
    )
    say(f"  {'':16}{'median [ms]':>12}{'total [ms]':>12}{'iterations':>12}{'converged':>11}")
    for name, row in figures.items():
        say(
            f"  {name:16}{row['median_correction_ms']:12.2f}{row['total_ms']:12.1f}"
            f"{row['iterations']:12d}{row['converged']:11d}"
        )
    same = dv_diff <= DV_GOAL_MPS and arrival_diff <= ARRIVAL_GOAL_S
    say(
        f"  speed-up {speedup:.2f}x; largest difference of the optima: total impulse "
        f"{dv_diff:.1e} m/s (goal <= {DV_GOAL_MPS:g}), arrival epoch {arrival_diff:.1e} s "
        f"(goal <= {ARRIVAL_GOAL_S:g}): {'met' if same else 'NOT met'}"
    )
    print(
        json.dumps(
            {
                "problems": len(problems),
                "extra_designs": args.extra_designs,
                "repeats": args.repeats,
                "solvers": figures,
                "speedup": round(speedup, 3),
                "max_dv_difference_mps": dv_diff,
                "max_dv_difference_goal_mps": DV_GOAL_MPS,
                "max_arrival_difference_s": arrival_diff,
                "max_arrival_difference_goal_s": ARRIVAL_GOAL_S,
            }
        )
    )


if __name__ == "__main__":
    main()
