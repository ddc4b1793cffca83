"""The seed's improved DE against scipy's DE on the published case, 20 seeds.

The impulsive stage of ``configs/cases/upper_stage_rendezvous.yaml`` (three impulses,
minimum time, rendezvous, two-body, sum |dv| within eq. 14 and eq. 15 burn times within
t_e) is searched from 20 seeds by

* **IDE**: :func:`ovtraj.studies.maneuver.de.improved_de` with the config's settings (the seed's
  N = 5 n, F = 0.5, P_c = 0.1, 2000 generations), twice: accepting ties in the greedy
  selection (eq. 11 with ``<=``, Storn & Price; the config's choice) and refusing them
  (the seed's ``<`` as printed);
* **scipy DE, same settings**: ``scipy.optimize.differential_evolution``, rand1bin, the
  same population, F, P_c and generations, uniform random start, no polishing;
* **scipy DE, defaults** (``--scipy-defaults``): scipy's own choices (best1bin, dither
  F in [0.5, 1), CR 0.7, Latin hypercube start), same population and generations;
* **pygmo DE** (``pygmo.de``, rand/1/bin, Kuri's constraint handling) when pygmo is
  installed (it is not a project dependency).

Every method evaluates the same vectorised model (one trajectory per individual; the
evaluation count is the number of trajectories flown). A run *succeeds* when its best
feasible time of flight is within ``SUCCESS_TOLERANCE_S`` of the best any run found.
Printed per method: success rate, median / best / worst time of flight, median
evaluations until success and in total, median wall time.

Run: ``python benchmarks/maneuver.py [--seeds 20] [--generations N] [--scipy-defaults]
[--json]`` (about 6 minutes for the three default rows on this 2-core machine): the runs
and the table, then one JSON object with the figures per method as the last line
(``--json``: only that).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

from ovtraj.studies.maneuver import load_maneuver
from ovtraj.studies.maneuver.de import DEResult, improved_de, scipy_de
from ovtraj.studies.maneuver.impulsive import CONSTRAINT_NAMES, ImpulsiveModel
from ovtraj.studies.maneuver.solve import population_size

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "configs" / "cases" / "upper_stage_rendezvous.yaml"
SEEDS = 20  # the comparison's number of seeds
SUCCESS_TOLERANCE_S = 1.0  # within 1 s of the best time of flight any run found
# scipy's defaults for differential_evolution (scipy 1.17 documentation).
SCIPY_DEFAULTS = {
    "strategy": "best1bin",
    "mutation": (0.5, 1.0),
    "cr": 0.7,
    "init": "latinhypercube",
}

try:  # optional: pygmo is not a dependency of the project
    import pygmo as pg
except ImportError:  # pragma: no cover - depends on the machine
    pg = None


def _median(values):
    return statistics.median(values) if values else float("nan")


def _finite(value: float) -> float | None:
    """``value``, or None for NaN (strict JSON has no NaN)."""
    return None if math.isnan(value) else float(value)


def run_ide(problem, evaluate, seed, generations, accept_ties):
    opt = problem.optimizer
    lower, upper = problem.bounds()
    return improved_de(
        evaluate,
        lower,
        upper,
        population=population_size(problem),
        scale_factor=opt.scale_factor,
        crossover_probability=opt.crossover_probability,
        generations=generations,
        seed=seed,
        accept_equal=accept_ties,
    )


def run_scipy(problem, evaluate, seed, generations, defaults=False):
    opt = problem.optimizer
    lower, upper = problem.bounds()
    kwargs = {
        "scale_factor": opt.scale_factor,
        "crossover_probability": opt.crossover_probability,
        "strategy": "rand1bin",
        "init": "random",
    }
    if defaults:
        kwargs = {
            "scale_factor": SCIPY_DEFAULTS["mutation"],
            "crossover_probability": SCIPY_DEFAULTS["cr"],
            "strategy": SCIPY_DEFAULTS["strategy"],
            "init": SCIPY_DEFAULTS["init"],
        }
    return scipy_de(
        evaluate,
        lower,
        upper,
        n_constraints=len(CONSTRAINT_NAMES),
        population_per_variable=opt.population_per_variable,
        generations=generations,
        seed=seed,
        **kwargs,
    )


def run_pygmo(problem, model, seed, generations):  # pragma: no cover - needs pygmo
    """pygmo's DE (rand/1/bin, variant 7) with Kuri's constraint handling."""
    lower, upper = problem.bounds()
    history = []
    count = {"n": 0}

    class Udp:
        def fitness(self, x):
            batch = model.evaluate(np.asarray(x)[None, :])
            count["n"] += 1
            f = float(batch.objective[0])
            return [f if np.isfinite(f) else 1e12, *batch.constraints[0]]

        def get_bounds(self):
            return (list(lower), list(upper))

        def get_nic(self):
            return len(CONSTRAINT_NAMES)

    start = time.perf_counter()
    prob = pg.problem(pg.unconstrain(pg.problem(Udp()), method="kuri"))
    opt = problem.optimizer
    algo = pg.algorithm(
        pg.de(gen=1, F=opt.scale_factor, CR=opt.crossover_probability, variant=7, ftol=0, xtol=0)
    )
    pop = pg.population(prob, size=population_size(problem), seed=seed)
    best = np.inf
    for _ in range(generations):
        pop = algo.evolve(pop)
        batch = model.evaluate(np.asarray(pop.champion_x)[None, :])
        if batch.violation[0] <= 0.0:
            best = min(best, float(batch.objective[0]))
        history.append((count["n"], best, float(batch.violation[0])))
    x = np.asarray(pop.champion_x)
    batch = model.evaluate(x[None, :])
    return DEResult(
        x=x,
        objective=float(batch.objective[0]),
        constraints=batch.constraints[0],
        feasible=bool(batch.violation[0] <= 0.0),
        generations=generations,
        evaluations=count["n"],
        wall_time_s=time.perf_counter() - start,
        history=history,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=SEEDS)
    parser.add_argument("--generations", type=int, default=None, help="default: the config's")
    parser.add_argument("--scipy-defaults", action="store_true")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print

    problem = load_maneuver(CASE)
    generations = args.generations or problem.optimizer.generations
    model = ImpulsiveModel(problem)

    def evaluate(x):
        batch = model.evaluate(x)
        return batch.objective, batch.constraints

    lower, upper = problem.bounds()
    evaluate(lower + 0.5 * (upper - lower)[None, :])  # compile the Lambert solver first

    methods = [
        ("IDE, ties accepted", lambda s: run_ide(problem, evaluate, s, generations, True)),
        ("IDE, seed's strict eq. 11", lambda s: run_ide(problem, evaluate, s, generations, False)),
        ("scipy DE, same settings", lambda s: run_scipy(problem, evaluate, s, generations)),
    ]
    if args.scipy_defaults:
        methods.append(
            ("scipy DE, defaults", lambda s: run_scipy(problem, evaluate, s, generations, True))
        )
    if pg is not None:
        methods.append(("pygmo DE", lambda s: run_pygmo(problem, model, s, generations)))
    else:
        say("pygmo is not installed: its row is skipped")

    say(
        f"{CASE.name}: {problem.n_variables} variables, N = {population_size(problem)}, "
        f"{generations} generations, {args.seeds} seeds"
    )
    runs: dict[str, list[DEResult]] = {name: [] for name, _ in methods}
    for seed in range(args.seeds):
        for name, run in methods:
            result = run(seed)
            runs[name].append(result)
            tof = result.objective if result.feasible else float("nan")
            say(
                f"  seed {seed:2d} {name:26s} t_f {tof:9.3f} s  {result.evaluations:6d} evals"
                f"  {result.wall_time_s:6.2f} s"
            )

    best_known = min(r.objective for rs in runs.values() for r in rs if r.feasible)
    threshold = best_known + SUCCESS_TOLERANCE_S
    say(f"\nbest time of flight found by any run: {best_known:.4f} s")
    say(f"success: feasible and t_f <= {threshold:.4f} s (best + {SUCCESS_TOLERANCE_S:g} s)\n")
    header = (
        f"| {'method':26s} | success | median t_f [s] | best t_f [s] | worst t_f [s] "
        f"| median evals to success | median evals | median wall [s] |"
    )
    say(header)
    say("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|")
    methods_figures = {}
    for name, results in runs.items():
        feasible = [r.objective for r in results if r.feasible]
        wins = [r for r in results if r.feasible and r.objective <= threshold]
        to_success = []
        for r in wins:
            hit = next(e for e, f, _ in r.history if f <= threshold)
            to_success.append(hit)
        say(
            f"| {name:26s} | {len(wins):3d}/{len(results):<3d} "
            f"| {_median(feasible):14.3f} | {min(feasible, default=np.nan):12.3f} "
            f"| {max(feasible, default=np.nan):13.3f} | {_median(to_success):23.0f} "
            f"| {_median([r.evaluations for r in results]):12.0f} "
            f"| {_median([r.wall_time_s for r in results]):15.2f} |"
        )
        methods_figures[name] = {
            "successes": len(wins),
            "runs": len(results),
            "success_rate": round(len(wins) / len(results), 3),
            "median_tof_s": _finite(_median(feasible)),
            "best_tof_s": _finite(min(feasible, default=np.nan)),
            "worst_tof_s": _finite(max(feasible, default=np.nan)),
            "median_evaluations_to_success": _finite(_median(to_success)),
            "median_evaluations": _finite(_median([r.evaluations for r in results])),
            "median_wall_s": _finite(_median([r.wall_time_s for r in results])),
        }
    figures = {
        "case": CASE.name,
        "variables": problem.n_variables,
        "population": population_size(problem),
        "generations": generations,
        "seeds": args.seeds,
        "best_tof_s": best_known,
        "success_tolerance_s": SUCCESS_TOLERANCE_S,
        "methods": methods_figures,
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
