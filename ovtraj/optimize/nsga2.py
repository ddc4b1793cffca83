"""NSGA-II (Deb, Pratap, Agarwal & Meyarivan 2002; pymoo) on vectorised models.

:func:`nsga2_front` searches the unit cube for any vectorised objective function;
:func:`surrogate_front` applies it to the mission surrogates: the three normalised
objectives (:mod:`.objectives`) and one constraint, the predicted probability of a
feasible mission at least ``feasibility_threshold``.

The search stops after its generations or at its wall-time limit
(``mission.optimize.time_limit_s``), whichever comes first; a search stopped by the
time limit returns no front (its result would depend on the machine's speed), with
``info["reason"]`` naming the limit and ``info["time_limit_reached"]`` set.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.problem import Problem
from pymoo.optimize import minimize

from ovtraj.config.mission import OptimizeSettings
from ovtraj.deadline import Deadline, pymoo_termination
from ovtraj.optimize.front import hypervolume
from ovtraj.optimize.objectives import Normalisation

UnitModel = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray | None]]


class _UnitCubeProblem(Problem):
    def __init__(self, model: UnitModel, n_var: int, n_obj: int, n_constr: int) -> None:
        super().__init__(
            n_var=n_var, n_obj=n_obj, n_ieq_constr=n_constr, xl=0.0, xu=1.0, vtype=float
        )
        self.model = model

    def _evaluate(self, x: np.ndarray, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
        objectives, constraints = self.model(x)
        out["F"] = objectives
        if self.n_ieq_constr:
            out["G"] = constraints


def nsga2_front(
    model: UnitModel,
    n_var: int,
    n_obj: int,
    *,
    population: int,
    generations: int,
    seed: int,
    n_constr: int = 0,
    initial: np.ndarray | None = None,
    deadline: Deadline | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The non-dominated feasible designs NSGA-II finds on ``[0, 1]^n_var``.

    ``model(U)`` maps a population (n, n_var) to the minimisation objectives (n, n_obj)
    and the inequality constraints (n, n_constr), feasible when <= 0 (``None`` without
    constraints). Returns the designs and objectives of the final non-dominated feasible
    set, sorted by objective (a reproducible order), and what the search did; with no
    feasible design, or when ``deadline`` stopped the search, the arrays are empty and
    ``info["reason"]`` says why.
    """
    deadline = deadline or Deadline.unlimited()
    problem = _UnitCubeProblem(model, n_var, n_obj, n_constr)
    algorithm = NSGA2(pop_size=population)
    if initial is not None and len(initial):
        # Seeded first generation: the given designs, topped up with seeded random ones.
        rng = np.random.default_rng(seed)
        start = np.asarray(initial, dtype=float)[:population]
        fill = rng.random((population - len(start), n_var))
        algorithm = NSGA2(pop_size=population, sampling=np.vstack([start, fill]))
    result = minimize(
        problem,
        algorithm,
        pymoo_termination(generations, deadline),
        seed=seed,
        verbose=False,
    )
    info: dict[str, Any] = {
        "generations": int(result.algorithm.n_gen),
        "evaluations": int(result.algorithm.evaluator.n_eval),
        "reason": None,
    }
    if deadline.reached:
        # pymoo counts the generation it would start next.
        done = int(result.algorithm.n_gen) - 1
        info["reason"] = f"NSGA-II stopped: {deadline.reason(done, 'generations')}"
        info["time_limit_reached"] = True
        return np.zeros((0, n_var)), np.zeros((0, n_obj)), info
    if result.X is None or result.F is None:
        info["reason"] = "no feasible design in the final population"
        return np.zeros((0, n_var)), np.zeros((0, n_obj)), info
    designs = np.atleast_2d(result.X)
    objectives = np.atleast_2d(result.F)
    order = np.lexsort(objectives.T[::-1])
    return designs[order], objectives[order], info


@dataclass
class SurrogateFront:
    """The front NSGA-II finds on the surrogates (predicted values, not verified)."""

    designs: pd.DataFrame  # design variables, physical units
    predicted: pd.DataFrame  # objectives, physical units (``Normalisation.names``)
    normalised: np.ndarray  # (n, m) minimisation form
    p_feasible: np.ndarray
    hypervolume: float
    info: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.designs)

    def to_frame(self) -> pd.DataFrame:
        frame = pd.concat([self.designs, self.predicted], axis=1)
        frame.insert(0, "front_index", np.arange(len(frame), dtype=np.int64))
        frame["p_feasible"] = self.p_feasible
        return frame


def surrogate_front(
    surrogates: Any,
    normalisation: Normalisation,
    settings: OptimizeSettings,
    initial: np.ndarray | None = None,
) -> SurrogateFront:
    """NSGA-II on a :class:`~ovtraj.surrogate.SurrogateSet` of the mission objectives."""
    names = normalisation.names
    missing = [n for n in names if n not in surrogates.output_names]
    if missing:
        raise ValueError(f"the surrogates have no model of {', '.join(missing)}")
    cube = surrogates.cube

    def predicted(units: np.ndarray) -> np.ndarray:
        values = surrogates.predict(cube.from_unit(units))
        return np.column_stack([values[n] for n in names])

    def model(units: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        probability = surrogates.feasibility(cube.from_unit(units))
        return normalisation.normalise(predicted(units)), (
            settings.feasibility_threshold - probability
        )[:, None]

    units, normalised, info = nsga2_front(
        model,
        len(surrogates.input_names),
        len(names),
        population=settings.population,
        generations=settings.generations,
        seed=settings.seed,
        n_constr=1,
        initial=None if initial is None else cube.to_unit(initial),
        deadline=Deadline(settings.time_limit_s, "mission.optimize.time_limit_s"),
    )
    physical = cube.from_unit(units) if len(units) else np.zeros((0, len(surrogates.input_names)))
    return SurrogateFront(
        designs=pd.DataFrame(physical, columns=list(surrogates.input_names)),
        predicted=pd.DataFrame(normalisation.physical(normalised), columns=list(names)),
        normalised=normalised,
        p_feasible=surrogates.feasibility(physical) if len(units) else np.zeros(0),
        hypervolume=hypervolume(normalised),
        info=info,
    )
