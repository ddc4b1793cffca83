"""The seed's improved differential evolution (IDE), and scipy's DE on the same problem.

Seed 003 sec. 1.2 (after Storn & Price 1997 and Lampinen & Zelinka 1999, the seed's
ref. [8]):

1. initialise: ``N`` individuals drawn uniformly inside the bounds ``[x^L, x^U]``;
2. evaluate every individual;
3. mutate and cross (eqs. 8-9): for individual ``i`` draw three distinct indices
   ``r1, r2, r3`` (all different from ``i``, as in Storn & Price) and a component
   ``j_rand``; component ``j`` of the trial is ``x_j^(r1) + F (x_j^(r2) - x_j^(r3))``
   when ``rand < P_c`` or ``j = j_rand``, else ``x_j^(i)``;
   **the improvement** (eq. 10): a trial component outside ``[x_j^L, x_j^U]`` is drawn
   again uniformly inside the bounds;
4. select greedily (eq. 11): the trial replaces ``i`` when it is better (the seed's
   strict ``<``) or, with ``accept_equal``, no worse (Storn & Price's ``<=``, which
   scipy uses too);
5. stop after the given number of generations (or, as an option, once the best
   feasible objective has not improved for ``stall_generations``).

Generations are synchronous (every trial is built from generation ``t``, as the seed
writes ``X(t+1)`` from ``X(t)``), so a whole generation is evaluated in one vectorised
call. "Better" in eq. 11 is ``f(trial) < f(x)`` (or ``<=``) between feasible individuals,
extended to the constraints that remain once the end conditions are exact (budget, burn
time, perigee) by the feasibility rules of Lampinen (2002, "A constraint handling
approach for the differential evolution algorithm", CEC 2002), which scipy's DE uses
too: a feasible individual beats an infeasible one, and between infeasible ones the
smaller total violation wins. No penalty weight is needed.

All random numbers come from one ``numpy.random.Generator`` seeded by the config, so a
run is reproducible bit for bit.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import NonlinearConstraint, differential_evolution

from ovtraj.deadline import Deadline

__all__ = ["DEResult", "Evaluator", "improved_de", "scipy_de"]

# Plans kept for scipy's repeated requests (a few generations' worth).
_CACHE_SIZE = 4096
# evaluate(X (S, d)) -> (objective (S,), constraints (S, M)); constraints <= 0 when met.
Evaluator = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]


@dataclass
class DEResult:
    """Best individual of a run and how the run went."""

    x: NDArray[np.float64]
    objective: float
    constraints: NDArray[np.float64]
    feasible: bool
    generations: int
    evaluations: int
    wall_time_s: float
    # (evaluations so far, best feasible objective or inf, smallest violation) per generation
    history: list[tuple[int, float, float]] = field(default_factory=list)
    limit: str | None = None  # the wall-time limit that stopped the search, if one did

    @property
    def violation(self) -> float:
        return float(np.sum(np.maximum(self.constraints, 0.0)))


def _violation(constraints: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.sum(np.maximum(constraints, 0.0), axis=1)


def _better(
    f_new: NDArray[np.float64],
    c_new: NDArray[np.float64],
    f_old: NDArray[np.float64],
    c_old: NDArray[np.float64],
    accept_equal: bool,
) -> NDArray[np.bool_]:
    """Eq. 11 with Lampinen's feasibility rules (see the module notes)."""
    feas_new, feas_old = c_new <= 0.0, c_old <= 0.0
    gain = (f_new <= f_old) if accept_equal else (f_new < f_old)
    less_violation = (c_new <= c_old) if accept_equal else (c_new < c_old)
    return (
        (feas_new & feas_old & gain)
        | (feas_new & ~feas_old)
        | (~feas_new & ~feas_old & less_violation)
    )


def _best_index(f: NDArray[np.float64], c: NDArray[np.float64]) -> int:
    feasible = c <= 0.0
    if np.any(feasible):
        return int(np.flatnonzero(feasible)[np.argmin(f[feasible])])
    return int(np.argmin(c))


def improved_de(
    evaluate: Evaluator,
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    *,
    population: int,
    scale_factor: float,
    crossover_probability: float,
    generations: int,
    seed: int,
    stall_generations: int = 0,
    stall_tolerance: float = 0.0,
    accept_equal: bool = False,
    deadline: Deadline | None = None,
) -> DEResult:
    """Minimise under constraints with the seed's IDE (module notes); seeded, reproducible.

    ``lower``, ``upper`` (d,) bound the decision vector; ``population`` is N (>= 4).
    ``accept_equal`` accepts ties in eq. 11 (module notes). When the objective is one of
    the variables (the time of flight), a trial that changes only other components ties
    with its parent: the strict rule refuses every such move and the search stalls.
    At ``deadline`` the search stops after the generation under way (``limit`` says so).
    """
    start = time.perf_counter()
    deadline = deadline or Deadline.unlimited()
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    d = len(lower)
    if population < 4:
        raise ValueError(f"the population needs at least 4 individuals, got {population}")
    rng = np.random.default_rng(seed)
    span = upper - lower
    pop = lower + rng.random((population, d)) * span
    f, cons = evaluate(pop)
    c = _violation(cons)
    evaluations = population
    history: list[tuple[int, float, float]] = []
    stall = _Stall(stall_generations, stall_tolerance)
    generation = 0
    while generation < generations:
        if deadline.expired():
            break
        generation += 1
        trial = _trials(rng, pop, lower, upper, scale_factor, crossover_probability)
        f_trial, cons_trial = evaluate(trial)
        c_trial = _violation(cons_trial)
        evaluations += population
        take = _better(f_trial, c_trial, f, c, accept_equal)  # eq. 11
        _replace(take, (pop, f, c, cons), (trial, f_trial, c_trial, cons_trial))
        feasible = c <= 0.0
        gen_best = float(np.min(f[feasible])) if np.any(feasible) else np.inf
        history.append((evaluations, gen_best, float(np.min(c))))
        if stall.stalled(gen_best):
            break
    i = _best_index(f, c)
    return DEResult(
        x=pop[i].copy(),
        objective=float(f[i]),
        constraints=cons[i].copy(),
        feasible=bool(c[i] <= 0.0),
        generations=generation,
        evaluations=evaluations,
        wall_time_s=time.perf_counter() - start,
        history=history,
        limit=deadline.reason(generation, "generations") if deadline.reached else None,
    )


def _replace(
    take: NDArray[np.bool_],
    parents: tuple[NDArray[np.float64], ...],
    trials: tuple[NDArray[np.float64], ...],
) -> None:
    """The winning trials' rows replace their parents' (decision vectors, objectives,
    violations, constraints), in place."""
    for parent, trial in zip(parents, trials, strict=True):
        parent[take] = trial[take]


class _Stall:
    """The optional stop: the best feasible objective has not improved by more than
    ``tolerance`` for ``generations`` generations in a row (0: never stop)."""

    def __init__(self, generations: int, tolerance: float) -> None:
        self.generations = generations
        self.tolerance = tolerance
        self.best = np.inf
        self.count = 0

    def stalled(self, gen_best: float) -> bool:
        """Count this generation's best; True when the search should stop."""
        if self.generations > 0:
            improved = gen_best < self.best - self.tolerance
            self.count = 0 if improved or not np.isfinite(gen_best) else self.count + 1
            if self.count >= self.generations:
                self.best = min(self.best, gen_best)
                return True
        self.best = min(self.best, gen_best)
        return False


def _trials(
    rng: np.random.Generator,
    pop: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    scale_factor: float,
    crossover_probability: float,
) -> NDArray[np.float64]:
    """A trial per individual: mutation and crossover (eqs. 8-9), components outside the
    bounds drawn again inside them (eq. 10). The random draws in a fixed order (the
    partners, the crossover, j_rand, the redraws) keep a seeded run reproducible."""
    population, d = pop.shape
    rows = np.arange(population)
    span = upper - lower
    # Three distinct partners per individual, none of them the individual itself.
    keys = rng.random((population, population))
    keys[rows, rows] = np.inf
    partners = np.argpartition(keys, 3, axis=1)[:, :3]
    r1, r2, r3 = partners[:, 0], partners[:, 1], partners[:, 2]
    mutant = pop[r1] + scale_factor * (pop[r2] - pop[r3])  # eq. 8
    cross = rng.random((population, d)) < crossover_probability
    cross[rows, rng.integers(0, d, population)] = True
    trial = np.where(cross, mutant, pop)  # eqs. 8-9
    outside = (trial < lower) | (trial > upper)
    redraw = lower + rng.random((population, d)) * span
    return np.where(outside, redraw, trial)  # eq. 10


class _Cached:
    """One trajectory evaluation per decision vector for scipy's separate calls.

    scipy asks for the constraints of a whole trial population, then for the objective
    of its feasible members: both come from the same plans, kept from the last call.
    """

    def __init__(self, evaluate: Evaluator) -> None:
        self.evaluate = evaluate
        self.store: dict[bytes, tuple[float, NDArray[np.float64]]] = {}
        self.evaluations = 0
        self.history: list[tuple[int, float, float]] = []
        self.best_f = np.inf
        self.best_c = np.inf

    def _get(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        x = np.atleast_2d(x)
        keys = [row.tobytes() for row in x]
        missing = [i for i, k in enumerate(keys) if k not in self.store]
        if missing:
            f_new, c_new = self.evaluate(x[missing])
            if len(self.store) > _CACHE_SIZE:
                # Oldest first (dicts keep insertion order); the population's best, which
                # scipy re-checks every generation, is usually recent.
                for key in list(self.store)[: len(self.store) // 2]:
                    del self.store[key]
            for i, fi, ci in zip(missing, f_new, c_new, strict=True):
                self.store[keys[i]] = (float(fi), ci)
            self.evaluations += len(missing)
            viol = _violation(c_new)
            feas = viol <= 0.0
            if np.any(feas):
                self.best_f = min(self.best_f, float(np.min(f_new[feas])))
            self.best_c = min(self.best_c, float(np.min(viol)))
        f = np.array([self.store[k][0] for k in keys])
        c = np.array([self.store[k][1] for k in keys])
        return f, c

    def objective(self, x_cols: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._get(np.asarray(x_cols).T)[0]

    def constraints(self, x_cols: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._get(np.asarray(x_cols).T)[1].T


def scipy_de(
    evaluate: Evaluator,
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    *,
    n_constraints: int,
    population_per_variable: int,
    scale_factor: float | tuple[float, float],
    crossover_probability: float,
    generations: int,
    seed: int,
    strategy: str = "rand1bin",
    init: str = "random",
    stall_generations: int = 0,
    stall_tolerance: float = 0.0,
    deadline: Deadline | None = None,
) -> DEResult:
    """scipy's ``differential_evolution`` on the same problem (Lampinen's constraints).

    Same DE/rand/1/bin scheme, population, F and P_c as the IDE unless told otherwise
    (``scale_factor`` may be scipy's dither interval); no polishing, no convergence test
    other than the stall rule; vectorised, deferred updating (synchronous generations,
    as the IDE). scipy also redraws out-of-bounds components uniformly (eq. 10).
    At ``deadline`` the search stops after the generation under way (``limit`` says so).
    """
    start = time.perf_counter()
    deadline = deadline or Deadline.unlimited()
    cached = _Cached(evaluate)
    constraint = NonlinearConstraint(cached.constraints, -np.inf, np.zeros(n_constraints))
    state = {"best": np.inf, "stall": 0, "generations": 0}

    def callback(intermediate_result) -> bool:  # noqa: ANN001
        state["generations"] += 1
        cached.history.append((cached.evaluations, cached.best_f, cached.best_c))
        if deadline.expired():
            return True
        if stall_generations <= 0:
            return False
        improved = cached.best_f < state["best"] - stall_tolerance
        state["stall"] = 0 if improved or not np.isfinite(cached.best_f) else state["stall"] + 1
        state["best"] = min(state["best"], cached.best_f)
        return state["stall"] >= stall_generations

    res = differential_evolution(
        cached.objective,
        list(zip(lower, upper, strict=True)),
        strategy=strategy,
        maxiter=generations,
        popsize=population_per_variable,
        tol=0.0,
        atol=0.0,
        mutation=scale_factor,
        recombination=crossover_probability,
        rng=seed,
        callback=callback,
        polish=False,
        init=init,
        updating="deferred",
        vectorized=True,
        constraints=constraint,
    )
    f, c = cached._get(np.atleast_2d(res.x))
    viol = float(_violation(c)[0])
    return DEResult(
        x=np.asarray(res.x, dtype=float),
        objective=float(f[0]),
        constraints=c[0],
        feasible=viol <= 0.0,
        generations=state["generations"],
        evaluations=cached.evaluations,
        wall_time_s=time.perf_counter() - start,
        history=cached.history,
        limit=deadline.reason(state["generations"], "generations") if deadline.reached else None,
    )
