"""Store the direct reference front of the shipped scenario: data/reference/direct_front/.

NSGA-II on the real chain (:mod:`ovtraj.optimize.direct`), ``--population`` x
``--generations`` evaluations (by default 48 x 125 = 6,000, ten times the 600 of the
direct method of ``benchmarks/surrogate_vs_direct.py``), seeded, on a pool of
``--workers`` spawned processes each holding the scenario's mission context. The front,
its hypervolume, the command and the scenario's key are stored
(:mod:`ovtraj.pipeline.reference_front`); ``ovtraj pipeline`` then reports its verified
front's hypervolume as a fraction of this one when the scenario matches. It never
overwrites: move a stored reference aside first (a deliberate change of the chain or of
the normalisation makes a new one necessary).

Run: ``python tools/direct_reference.py [--population 48] [--generations 125] [--seed 11]
[--workers 2] [--config FILE] [--out DIR]`` (prints the path it wrote; about 4 minutes of
CPU here at ~40 ms an evaluation).
"""

from __future__ import annotations

import argparse
import multiprocessing
import shlex
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_CONTEXT = None
_NAMES: tuple[str, ...] = ()


def _init(config: str) -> None:
    global _CONTEXT, _NAMES
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.mission import MissionContext
    from ovtraj.optimize import Normalisation
    from ovtraj.parallel import EVALUATION_BLAS_THREADS
    from ovtraj.runs.runners import limit_threads
    from ovtraj.target_sources import load_scenario

    limit_threads(EVALUATION_BLAS_THREADS)
    scenario = load_scenario(config)
    _CONTEXT = MissionContext(scenario, find_launch_fit(scenario))
    _NAMES = Normalisation.mission(scenario.mission.optimize).names


def _evaluate(design: tuple[float, ...]) -> tuple[bool, list[float]]:
    from ovtraj.mission import MissionDesign, evaluate

    record = evaluate(_CONTEXT, MissionDesign(*design))
    totals = record.totals()
    if not record.feasible:
        return False, [float("nan")] * len(_NAMES)
    return True, [float(totals[name]) for name in _NAMES]


def main() -> None:
    from ovtraj.mission.design_space import bounds_arrays
    from ovtraj.optimize import Normalisation
    from ovtraj.optimize.direct import direct_front
    from ovtraj.pipeline import reference_front
    from ovtraj.target_sources import load_scenario
    from ovtraj.version import code_version

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--population", type=int, default=48)
    parser.add_argument("--generations", type=int, default=125)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "scenario.yaml")
    parser.add_argument("--out", type=Path, default=None, help="default: the shipped place")
    args = parser.parse_args()
    scenario = load_scenario(args.config)
    normalisation = Normalisation.mission(scenario.mission.optimize)
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    start = time.perf_counter()
    with ProcessPoolExecutor(
        args.workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_init,
        initargs=(str(args.config.resolve()),),
    ) as pool:
        front = direct_front(
            lambda designs: list(pool.map(_evaluate, designs, chunksize=4)),
            lower,
            upper,
            normalisation,
            population=args.population,
            generations=args.generations,
            seed=args.seed,
        )
    directory = (args.out or reference_front.reference_front_directory()).resolve()
    # The command that makes this front again (where it is written does not change it).
    given = sys.argv[1:]
    kept = [a for k, a in enumerate(given) if a != "--out" and (k == 0 or given[k - 1] != "--out")]
    command = "python tools/direct_reference.py " + shlex.join(kept)
    written = reference_front.store(
        directory,
        front,
        scenario,
        {
            "what": "direct reference front: NSGA-II (pymoo) on the real mission chain",
            "command": command.strip(),
            "seed": args.seed,
            "population": args.population,
            "generations": args.generations,
            "code_version": code_version(),
            "ideal": normalisation.ideal.tolist(),
            "reference_point": normalisation.reference.tolist(),
        },
    )
    print(
        f"{front.evaluations} evaluations ({front.feasible_evaluations} feasible) in "
        f"{time.perf_counter() - start:.0f} s: {len(front.objectives)} front points, "
        f"hypervolume {front.hypervolume:.5f}"
    )
    print(f"stored: {written}")


if __name__ == "__main__":
    main()
