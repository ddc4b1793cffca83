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
from pymoo.operators.crossover.sbx import cross_sbx
from pymoo.operators.mutation.pm import mut_pm
from pymoo.operators.survival.rank_and_crowding.metrics import get_crowding_function
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
from pymoo.util.randomized_argsort import randomized_argsort
from scipy.spatial.distance import cdist

from ovtraj.config.mission import OptimizeSettings
from ovtraj.deadline import Deadline
from ovtraj.optimize.front import hypervolume
from ovtraj.optimize.objectives import Normalisation

UnitModel = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray | None]]


# pymoo's NSGA-II defaults (pymoo.algorithms.moo.nsga2.NSGA2, after Deb et al. 2002).
_CROSSOVER_PROBABILITY = 0.9  # SBX per mating
_CROSSOVER_ETA = 15.0
_CROSSOVER_VARIABLE_PROBABILITY = 0.5  # SBX per variable
_CROSSOVER_EXCHANGE_PROBABILITY = 0.5
_MUTATION_PROBABILITY = 0.9  # PM per offspring
_MUTATION_ETA = 20.0
_DUPLICATE_DISTANCE = 1e-16  # unit-cube distance under which two designs are one
_MATING_ATTEMPTS = 100  # matings redrawn while duplicates leave the offspring short
_CROWDING = get_crowding_function("cd")  # NSGA-II's crowding distance (inf at a front's ends)


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

    pymoo's NSGA-II (its defaults: binary tournaments on constraint violation, then
    dominance, then crowding; SBX and polynomial mutation; duplicates eliminated;
    survival by rank and crowding distance) run on arrays: pymoo's operators, sorting
    and crowding distance, without its per-individual objects, which took ~70 % of a
    search on the mission surrogates (docs/optimize.md).
    """
    deadline = deadline or Deadline.unlimited()
    rng = np.random.default_rng(seed)
    if initial is not None and len(initial):
        # Seeded first generation: the given designs, topped up with seeded random ones.
        start = np.asarray(initial, dtype=float)[:population]
        x = np.vstack([start, rng.random((population - len(start), n_var))])
    else:
        x = rng.random((population, n_var))
    f, cv = _evaluated(model, x, n_constr)
    evaluations = len(x)
    x, f, cv, rank, crowding = _survivors(x, f, cv, population, rng)
    generation = 1
    while generation < generations:
        if deadline.expired():
            break
        offspring = _offspring(x, f, cv, crowding, population, rng)
        if not len(offspring):
            break  # every new design repeats one already in the population
        f_new, cv_new = _evaluated(model, offspring, n_constr)
        evaluations += len(offspring)
        x, f, cv, rank, crowding = _survivors(
            np.vstack([x, offspring]),
            np.vstack([f, f_new]),
            np.concatenate([cv, cv_new]),
            population,
            rng,
        )
        generation += 1
    info: dict[str, Any] = {"generations": generation, "evaluations": evaluations, "reason": None}
    if deadline.reached:
        info["reason"] = f"NSGA-II stopped: {deadline.reason(generation, 'generations')}"
        info["time_limit_reached"] = True
        return np.zeros((0, n_var)), np.zeros((0, n_obj)), info
    best = (cv <= 0.0) & (rank == 0)
    if not best.any():
        info["reason"] = "no feasible design in the final population"
        return np.zeros((0, n_var)), np.zeros((0, n_obj)), info
    designs, objectives = x[best], f[best]
    order = np.lexsort(objectives.T[::-1])
    return designs[order], objectives[order], info


def _evaluated(model: UnitModel, x: np.ndarray, n_constr: int) -> tuple[np.ndarray, np.ndarray]:
    """Objectives (n, n_obj) and constraint violations (n,) of designs ``x``."""
    objectives, constraints = model(x)
    f = np.asarray(objectives, dtype=float).reshape(len(x), -1)
    if not n_constr:
        return f, np.zeros(len(x))
    g = np.asarray(constraints, dtype=float).reshape(len(x), n_constr)
    return f, np.maximum(g, 0.0).sum(axis=1)


def _survivors(
    x: np.ndarray, f: np.ndarray, cv: np.ndarray, size: int, rng: np.random.Generator
) -> tuple[np.ndarray, ...]:
    """The next population: feasible designs by non-dominated rank, the last front cut
    by crowding distance (ties in random order), then the least violating infeasible
    ones; with each survivor's rank and crowding (infeasible: rank inf, crowding 0)."""
    feasible = np.flatnonzero(cv <= 0.0)
    kept: list[int] = []
    rank = np.full(len(x), np.inf)
    crowding = np.zeros(len(x))
    if len(feasible):
        fronts = NonDominatedSorting().do(f[feasible], n_stop_if_ranked=size)
        for k, front in enumerate(fronts):
            members = feasible[front]
            distance = _CROWDING.do(f[members])
            rank[members], crowding[members] = k, distance
            if len(kept) + len(members) > size:
                order = randomized_argsort(
                    distance, order="descending", method="numpy", random_state=rng
                )
                members = members[order[: size - len(kept)]]
            kept.extend(members)
            if len(kept) >= size:
                break
    if len(kept) < size:
        infeasible = np.flatnonzero(cv > 0.0)
        kept.extend(infeasible[np.argsort(cv[infeasible], kind="stable")][: size - len(kept)])
    kept_index = np.array(kept, dtype=int)
    return x[kept_index], f[kept_index], cv[kept_index], rank[kept_index], crowding[kept_index]


def _tournament_winners(
    f: np.ndarray, cv: np.ndarray, crowding: np.ndarray, pairs: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """pymoo's binary tournament: the smaller violation if either violates (a coin on a
    tie), else the dominating design, else the larger crowding distance (a coin on a tie)."""
    a, b = pairs[:, 0], pairs[:, 1]
    coin = rng.random(len(pairs)) < 0.5
    a_dominates = np.all(f[a] <= f[b], axis=1) & np.any(f[a] < f[b], axis=1)
    b_dominates = np.all(f[b] <= f[a], axis=1) & np.any(f[b] < f[a], axis=1)
    by_crowding = np.where(
        crowding[a] > crowding[b], a, np.where(crowding[b] > crowding[a], b, np.where(coin, a, b))
    )
    feasible_pick = np.where(a_dominates, a, np.where(b_dominates, b, by_crowding))
    by_violation = np.where(cv[a] < cv[b], a, np.where(cv[b] < cv[a], b, np.where(coin, a, b)))
    return np.where((cv[a] > 0.0) | (cv[b] > 0.0), by_violation, feasible_pick)


def _offspring(
    x: np.ndarray,
    f: np.ndarray,
    cv: np.ndarray,
    crowding: np.ndarray,
    size: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """``size`` new designs by tournaments, SBX and polynomial mutation, none within
    ``_DUPLICATE_DISTANCE`` of each other or of the population."""
    n, n_var = x.shape
    lower, upper = np.zeros(n_var), np.ones(n_var)
    matings = -(-size // 2)
    children = np.zeros((0, n_var))
    for _ in range(_MATING_ATTEMPTS):
        # Two tournaments per mating, contestants from concatenated permutations.
        needed = matings * 2 * 2
        contestants = np.concatenate([rng.permutation(n) for _ in range(-(-needed // n))])
        parents = _tournament_winners(f, cv, crowding, contestants[:needed].reshape(-1, 2), rng)
        pairs = x[parents.reshape(matings, 2)]
        mates = np.stack([pairs[:, 0], pairs[:, 1]])
        crossed = cross_sbx(
            mates,
            lower,
            upper,
            np.full((matings, 1), _CROSSOVER_ETA),
            np.full((matings, 1), _CROSSOVER_VARIABLE_PROBABILITY),
            np.full((matings, 1), _CROSSOVER_EXCHANGE_PROBABILITY),
            random_state=rng,
        )
        skip = rng.random(matings) >= _CROSSOVER_PROBABILITY
        crossed[:, skip] = mates[:, skip]
        new = crossed.reshape(-1, n_var)
        mutate = rng.random(len(new)) < _MUTATION_PROBABILITY
        if mutate.any():
            new[mutate] = mut_pm(
                new[mutate],
                lower,
                upper,
                np.full(int(mutate.sum()), _MUTATION_ETA),
                np.full(int(mutate.sum()), min(0.5, 1.0 / n_var)),
                at_least_once=False,
                random_state=rng,
            )
        new = new[_unique_rows(new, np.vstack([x, children]))]
        children = np.vstack([children, new])
        if len(children) >= size:
            break
    return children[:size]


def _unique_rows(new: np.ndarray, existing: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``new`` farther than ``_DUPLICATE_DISTANCE`` from every row of
    ``existing`` and from every earlier row of ``new``."""
    distance = cdist(new, new)
    distance[np.triu_indices(len(new))] = np.inf
    repeats = np.any(distance <= _DUPLICATE_DISTANCE, axis=1)
    if len(existing):
        repeats |= np.any(cdist(new, existing) <= _DUPLICATE_DISTANCE, axis=1)
    return np.flatnonzero(~repeats)


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

    threshold = settings.feasibility_threshold

    def constraints(designs: np.ndarray) -> np.ndarray:
        # A set that models known limits of its own (MissionSurrogates) gives one column
        # each besides the classifier's; otherwise the classifier's probability alone.
        if hasattr(surrogates, "constraints"):
            return surrogates.constraints(designs, threshold)
        return (threshold - surrogates.feasibility(designs))[:, None]

    def model(units: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return normalisation.normalise(predicted(units)), constraints(cube.from_unit(units))

    n_constr = constraints(cube.from_unit(np.full((1, cube.dim), 0.5))).shape[1]
    units, normalised, info = nsga2_front(
        model,
        len(surrogates.input_names),
        len(names),
        population=settings.population,
        generations=settings.generations,
        seed=settings.seed,
        n_constr=n_constr,
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
