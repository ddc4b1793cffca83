"""NSGA-II directly on the mission chain: the reference the surrogate pipeline is judged by.

Every evaluation is a real one, so this costs what the surrogate pipeline saves (hundreds
to thousands of chain evaluations); it answers "what front is there to find" for a
scenario. pymoo's own NSGA-II runs on the unit cube of the design bounds, one constraint
(an infeasible mission violates it), seeded; the front is the non-dominated set of
*every* feasible design it evaluated (its archive), the most generous reading of the
method. The pipeline's surrogate searches run :func:`ovtraj.optimize.nsga2_front` (the same
algorithm on arrays); the reference keeps pymoo's implementation so that it does not move
with ours.

``evaluate`` maps a list of designs (physical units, design-variable order) to one
``(feasible, objectives)`` pair each (objectives in the normalisation's order, physical
units, NaN when infeasible): a process pool's ``map`` in practice.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ovtraj.optimize.front import hypervolume, non_dominated
from ovtraj.optimize.objectives import Normalisation

Evaluations = Callable[[list[tuple[float, ...]]], Sequence[tuple[bool, Sequence[float]]]]


@dataclass(frozen=True)
class DirectFront:
    """The archive's non-dominated feasible designs and their real objectives (physical
    units), how many evaluations it took, and the front's hypervolume (normalised)."""

    designs: np.ndarray  # (n, d)
    objectives: np.ndarray  # (n, m), physical units
    evaluations: int
    feasible_evaluations: int
    hypervolume: float


def direct_front(
    evaluate: Evaluations,
    lower: np.ndarray,
    upper: np.ndarray,
    normalisation: Normalisation,
    *,
    population: int,
    generations: int,
    seed: int,
) -> DirectFront:
    """pymoo NSGA-II on the real chain through ``evaluate``; see the module notes."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize

    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    designs: list[np.ndarray] = []
    values: list[np.ndarray] = []
    counted = {"evaluations": 0}

    def model(units: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        physical = lower + units * (upper - lower)
        results = list(evaluate([tuple(map(float, d)) for d in physical]))
        counted["evaluations"] += len(results)
        feasible = np.array([bool(ok) for ok, _ in results])
        objectives = np.array([np.asarray(v, dtype=float) for _, v in results])
        for design, value, ok in zip(physical, objectives, feasible, strict=True):
            if ok:
                designs.append(design)
                values.append(value)
        # An infeasible design gets the worst objectives NSGA-II can see and violates the
        # constraint; its objectives never reach the archive.
        normalised = np.where(feasible[:, None], normalisation.normalise(objectives), 10.0)
        return normalised, np.where(feasible, -1.0, 1.0)[:, None]

    class UnitCube(Problem):
        def __init__(self) -> None:
            super().__init__(
                n_var=len(lower), n_obj=len(normalisation.names), n_ieq_constr=1, xl=0.0, xu=1.0
            )

        def _evaluate(self, x, out, *args, **kwargs) -> None:  # noqa: ANN001
            out["F"], out["G"] = model(x)

    minimize(UnitCube(), NSGA2(pop_size=population), ("n_gen", generations), seed=seed)
    if not values:
        raise ValueError("the direct search evaluated no feasible design")
    archive = np.array(values)
    normalised = normalisation.normalise(archive)
    keep = non_dominated(normalised)
    order = np.lexsort(archive[keep].T[::-1])
    return DirectFront(
        designs=np.array(designs)[keep][order],
        objectives=archive[keep][order],
        evaluations=counted["evaluations"],
        feasible_evaluations=len(values),
        hypervolume=float(hypervolume(normalised[keep])),
    )
