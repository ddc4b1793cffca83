"""The surrogate pipeline against a direct NSGA-II on the real chain (issue 7).

Both on the default scenario, side by side in one process:

- **direct**: pymoo NSGA-II whose every evaluation is the real mission chain
  (``population`` x ``generations`` evaluations, on a pool of worker processes that
  each build the mission context once); infeasible missions violate its constraint.
  Its front is the non-dominated set of *every* design it evaluated (its archive),
  which is the most generous reading of the direct method.
- **surrogate pipeline**: the DoE (``doe_samples`` Latin hypercube samples), then
  ``ovtraj.pipeline.run_pipeline`` with the scenario's surrogate, optimisation and
  verification settings (the infill budget ``mission.verify.budget``): its front is
  the verified front (real values only).

Printed: each method's real evaluations, front size and hypervolume (normalised
objectives, reference point ``mission.optimize.reference``), the hypervolume ratio
and the evaluation ratio. Goal: >= 95 % of the direct hypervolume with <= 10 % of its
real evaluations.

Run: ``python benchmarks/surrogate_vs_direct.py [doe_samples] [population] [generations]``
(default 24 samples + the configured infill budget of 36 against 24 x 25 = 600 direct
evaluations).
"""

from __future__ import annotations

import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
DOE_SAMPLES = int(sys.argv[1]) if len(sys.argv) > 1 else 24
POPULATION = int(sys.argv[2]) if len(sys.argv) > 2 else 24
GENERATIONS = int(sys.argv[3]) if len(sys.argv) > 3 else 25
WORKERS = 2
DIRECT_SEED = 11
HV_GOAL = 0.95
EVALUATION_GOAL = 0.10

_CONTEXT = None


def _init() -> None:
    global _CONTEXT
    from ovtraj.config import load_scenario
    from ovtraj.launch.fit import find_launch_fit
    from ovtraj.mission import MissionContext

    scenario = load_scenario(ROOT / "configs" / "scenario.yaml")
    _CONTEXT = MissionContext(scenario, find_launch_fit(scenario))


def _evaluate(design: tuple[float, float, float]) -> tuple[bool, float, float, float]:
    from ovtraj.mission import MissionDesign, evaluate

    record = evaluate(_CONTEXT, MissionDesign(*design))
    if not record.feasible:
        return False, np.nan, np.nan, np.nan
    return True, record.t_total_s, record.dv_total_mps, record.m_load_kg


def direct(scenario, normalisation, pool) -> dict:
    from ovtraj.optimize import hypervolume, non_dominated, nsga2_front
    from ovtraj.runs.doe import bounds_arrays

    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    archive = []

    def model(units):
        designs = lower + units * (upper - lower)
        results = list(pool.map(_evaluate, [tuple(map(float, d)) for d in designs]))
        values = np.array([r[1:] for r in results], dtype=float)
        feasible = np.array([r[0] for r in results])
        archive.extend(v for v, ok in zip(values, feasible, strict=True) if ok)
        normalised = np.where(feasible[:, None], normalisation.normalise(values), 10.0)
        return normalised, np.where(feasible, -1.0, 1.0)[:, None]

    start = time.perf_counter()
    _, _, info = nsga2_front(
        model, 3, 3, population=POPULATION, generations=GENERATIONS, seed=DIRECT_SEED, n_constr=1
    )
    values = normalisation.normalise(np.array(archive))
    front = values[non_dominated(values)]
    return {
        "evaluations": info["evaluations"],
        "front_points": len(front),
        "hypervolume": hypervolume(front),
        "wall_s": time.perf_counter() - start,
    }


def pipeline(scenario, fit, store) -> dict:
    from ovtraj.pipeline import PipelineSteps, run_pipeline
    from ovtraj.runs import prepare_run, run_doe

    def evaluate(run):
        return run_doe(scenario, run, fit, batch_size=scenario.mission.doe.batch_size)

    start = time.perf_counter()
    doe = prepare_run(scenario, samples=DOE_SAMPLES, seed=2026, code="benchmark", store=store)
    evaluate(doe)
    result = run_pipeline(
        scenario,
        doe,
        store=store,
        code="benchmark",
        steps=PipelineSteps(evaluate=evaluate),
        progress=print,
    )
    spent = result.summary["real_evaluations"]
    return {
        "evaluations": spent["doe"] + spent["infill"],
        "front_points": len(result.front),
        "hypervolume": result.summary["hypervolume"],
        "stop": result.summary["stop_reason"],
        "wall_s": time.perf_counter() - start,
    }


def main() -> None:
    from ovtraj.config import load_scenario
    from ovtraj.launch.fit import find_launch_fit
    from ovtraj.optimize import Normalisation
    from ovtraj.runs import RunStore

    scenario = load_scenario(ROOT / "configs" / "scenario.yaml")
    normalisation = Normalisation.mission(scenario.mission.optimize)
    fit = find_launch_fit(scenario)
    store = RunStore(Path(tempfile.mkdtemp(prefix="ovtraj-svd-")))
    surrogate = pipeline(scenario, fit, store)
    with ProcessPoolExecutor(WORKERS, initializer=_init) as pool:
        reference = direct(scenario, normalisation, pool)
    hv_ratio = surrogate["hypervolume"] / reference["hypervolume"]
    eval_ratio = surrogate["evaluations"] / reference["evaluations"]
    header = ("method", "real evaluations", "front points", "hypervolume", "wall [s]")
    print(f"{header[0]:<20}{header[1]:>18}{header[2]:>14}{header[3]:>13}{header[4]:>10}")
    for name, row in (("surrogate pipeline", surrogate), ("direct NSGA-II", reference)):
        print(
            f"{name:<20}{row['evaluations']:>18d}{row['front_points']:>14d}"
            f"{row['hypervolume']:>13.4f}{row['wall_s']:>10.1f}"
        )
    print(f"pipeline stop: {surrogate['stop']}")
    print(
        f"hypervolume ratio {hv_ratio:.3f} (goal >= {HV_GOAL}), evaluation ratio "
        f"{eval_ratio:.3f} (goal <= {EVALUATION_GOAL}): "
        f"{'met' if hv_ratio >= HV_GOAL and eval_ratio <= EVALUATION_GOAL else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
