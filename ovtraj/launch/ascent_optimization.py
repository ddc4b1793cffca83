"""Hierarchical optimisation of the ascent (patent step 101).

A genetic algorithm screens the design space (pymoo ``GA``, seeded), an active-set
SQP (scipy SLSQP) converges from its best design, and an interior-point method
(scipy ``trust-constr``, which uses its barrier algorithm when inequalities are
present) polishes the result. Each phase starts from the best design so far and
its end point replaces it only if it is better: feasible beats infeasible, then
the larger payload wins, and between infeasible designs the smaller violation.
What each phase reached is recorded either way.

Gradients are central differences evaluated as one batch of ``2n + 1`` rows, which
costs about as much as a single trajectory in the vectorised ascent. The objective
``-x_payload`` is linear in the scaled variables, so its gradient is exact.

Each phase runs under its wall-time limit (``genetic.time_limit_s`` for the GA,
``local.time_limit_s`` for each local phase) besides its iteration limit. A phase that
reaches its time limit stops at its best design, no further phase runs, and the
outcome's ``limit`` names the limit (the stage reports the launch infeasible).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.core.problem import Problem
from pymoo.optimize import minimize as pymoo_minimize
from scipy.optimize import BFGS, Bounds, NonlinearConstraint, minimize

from ovtraj.config.launch import GeneticConfig, LocalConfig
from ovtraj.deadline import Deadline, pymoo_termination
from ovtraj.launch.problem import Evaluation, LaunchProblem

PAYLOAD_INDEX = 9

logger = logging.getLogger(__name__)

Progress = Callable[[int, int, str], None]
"""``on_progress(done, total, phase)``: generations of the GA, iterations of a local phase
(of its iteration limit; a phase usually ends earlier, when it stalls)."""


@dataclass(frozen=True)
class PhaseRecord:
    """What one optimisation phase reached (payload and violation at its end point)."""

    name: str
    payload_kg: float
    max_violation: float  # scaled: 0 when every constraint is within its tolerance
    max_residual: float  # scaled: largest |c| (1 is one tolerance)
    feasible: bool
    accepted: bool  # replaced the incumbent design
    iterations: int
    trajectories: int
    wall_time_s: float
    message: str

    def as_dict(self) -> dict[str, object]:
        return asdict(self)

    @property
    def standing(self) -> Standing:
        return Standing(self.payload_kg, self.max_violation, self.max_residual)

    @classmethod
    def reached(cls, name: str, standing: Standing, **counts: object) -> PhaseRecord:
        """The record of a phase that ended at a design of this standing."""
        return cls(
            name=name,
            payload_kg=standing.payload_kg,
            max_violation=standing.violation,
            max_residual=standing.residual,
            feasible=standing.violation <= 0.0,
            **counts,
        )


@dataclass
class OptimisationOutcome:
    x: NDArray  # best scaled design
    payload_kg: float
    max_violation: float
    max_residual: float
    phases: list[PhaseRecord]
    trajectories: int
    wall_time_s: float
    limit: str | None = None  # the wall-time limit that stopped a phase, naming its key

    @property
    def feasible(self) -> bool:
        return self.max_violation <= 0.0


@dataclass(frozen=True)
class Standing:
    """How good a design is: its payload and how far it is from the constraints.

    ``violation`` is the largest scaled violation (0 when every constraint is within
    its tolerance); ``residual`` the largest scaled residual, ``max |c_eq|`` and the
    path limits' shortfall (``<= 1`` is within tolerance, 0 is exact).
    """

    payload_kg: float
    violation: float
    residual: float

    def rank(self, converged_residual: float) -> tuple[int, float]:
        """Sort key, smaller is better: converged, then feasible, then infeasible.

        A design counts as converged when its residual is at most
        ``converged_residual`` (a fraction of the tolerances). Ranking converged
        designs first keeps a phase from being beaten by a design that merely sits
        at the favourable edge of the tolerance box, which would make the payload a
        noisy function of the target altitude.
        """
        if self.violation > 0.0:
            return 2, self.violation
        return (0 if self.residual <= converged_residual else 1), -self.payload_kg


def is_better(candidate: Standing, incumbent: Standing, converged_residual: float) -> bool:
    """Converged first, then feasible, then by payload (or, if infeasible, violation)."""
    return candidate.rank(converged_residual) < incumbent.rank(converged_residual)


class _Oracle:
    """Values and central-difference Jacobians of a LaunchProblem, one batch per point.

    The local methods see the path limits as the plain margins ``1 - q_max / q_limit``
    (``>= 0``), not divided by their small tolerance: values of a few hundred on the
    inactive load limit upset ``trust-constr``'s barrier. The tolerance enters only
    through the ranking of designs (:class:`Standing`).
    """

    def __init__(self, problem: LaunchProblem, step: float) -> None:
        self.problem = problem
        self.step = step
        self._margin = problem.target.path_limit_fraction
        self._key: bytes | None = None
        self._values: tuple[NDArray, NDArray] | None = None
        self._jac_key: bytes | None = None
        self._jacobians: tuple[NDArray, NDArray] | None = None

    def _evaluate_point(self, x: NDArray) -> None:
        key = np.asarray(x, dtype=float).tobytes()
        if key != self._key:
            ev = self.problem.evaluate(x)
            self._key = key
            self._values = (ev.equality[0], ev.inequality[0] * self._margin)

    def _evaluate_jacobian(self, x: NDArray) -> None:
        key = np.asarray(x, dtype=float).tobytes()
        if key == self._jac_key:
            return
        n = len(x)
        h = self.step
        rows = np.vstack([x, x + h * np.eye(n), x - h * np.eye(n)])
        ev = self.problem.evaluate(rows)
        self._key, self._values = key, (ev.equality[0], ev.inequality[0] * self._margin)
        self._jac_key = key
        self._jacobians = (
            ((ev.equality[1 : n + 1] - ev.equality[n + 1 :]) / (2 * h)).T,
            ((ev.inequality[1 : n + 1] - ev.inequality[n + 1 :]) * self._margin / (2 * h)).T,
        )

    @staticmethod
    def objective(x: NDArray) -> float:
        return -float(x[PAYLOAD_INDEX])

    @staticmethod
    def objective_gradient(x: NDArray) -> NDArray:
        g = np.zeros(len(x))
        g[PAYLOAD_INDEX] = -1.0
        return g

    def equality(self, x: NDArray) -> NDArray:
        self._evaluate_point(x)
        return self._values[0].copy()

    def inequality(self, x: NDArray) -> NDArray:
        self._evaluate_point(x)
        return self._values[1].copy()

    def equality_jacobian(self, x: NDArray) -> NDArray:
        self._evaluate_jacobian(x)
        return self._jacobians[0].copy()

    def inequality_jacobian(self, x: NDArray) -> NDArray:
        self._evaluate_jacobian(x)
        return self._jacobians[1].copy()


class _GeneticProblem(Problem):
    """pymoo view: minimise ``-x_payload`` with relaxed constraints ``G <= 0``."""

    def __init__(self, problem: LaunchProblem, relaxation: float) -> None:
        super().__init__(n_var=problem.dimension, n_obj=1, n_ieq_constr=6, xl=0.0, xu=1.0)
        self.problem = problem
        self.relaxation = relaxation

    def _evaluate(self, x: NDArray, out: dict, *args: object, **kwargs: object) -> None:
        ev = self.problem.evaluate(x)
        out["F"] = -x[:, PAYLOAD_INDEX : PAYLOAD_INDEX + 1]
        out["G"] = np.hstack(
            [np.abs(ev.equality) - self.relaxation, -ev.inequality - self.relaxation]
        )


def _evaluate_one(problem: LaunchProblem, x: NDArray) -> Standing:
    ev: Evaluation = problem.evaluate(x)
    return Standing(float(ev.payload_kg[0]), float(ev.violation[0]), float(ev.residual[0]))


def run_genetic(
    problem: LaunchProblem,
    settings: GeneticConfig,
    *,
    seed_x: NDArray | None = None,
    deadline: Deadline | None = None,
    on_progress: Progress | None = None,
) -> tuple[NDArray, PhaseRecord]:
    """Global search; returns the best design under the relaxed constraints.

    Stops after ``settings.generations`` or at ``deadline`` (default: the config's
    ``time_limit_s`` from now), whichever comes first; ``on_progress`` after each
    generation.
    """
    start, before = time.perf_counter(), problem.trajectories
    if deadline is None:
        deadline = Deadline(settings.time_limit_s, "launch.genetic.time_limit_s")
    algorithm = GA(pop_size=settings.population, eliminate_duplicates=True)
    if seed_x is not None:
        from pymoo.core.population import Population
        from pymoo.operators.sampling.lhs import LHS

        rng = np.random.default_rng(settings.seed)
        sample = (
            LHS()
            .do(_GeneticProblem(problem, 1.0), settings.population - 1, random_state=rng)
            .get("X")
        )
        algorithm = GA(
            pop_size=settings.population,
            sampling=Population.new("X", np.vstack([seed_x, sample])),
            eliminate_duplicates=True,
        )
    pymoo_problem = _GeneticProblem(problem, settings.constraint_relaxation)

    def generation_done(algorithm: object) -> None:  # reads only: the same search either way
        if on_progress is not None:
            total = settings.generations
            on_progress(min(int(algorithm.n_gen), total), total, "genetic")

    result = pymoo_minimize(
        pymoo_problem,
        algorithm,
        pymoo_termination(settings.generations, deadline),
        seed=settings.seed,
        verbose=False,
        callback=generation_done,
    )
    # pymoo counts the generation it would start next.
    generations = int(result.algorithm.n_gen) - 1 if deadline.reached else settings.generations
    population = result.pop
    cv = population.get("CV")[:, 0]
    f = population.get("F")[:, 0]
    best_index = int(np.lexsort((f, cv))[0])
    x = np.clip(population.get("X")[best_index], 0.0, 1.0)
    standing = _evaluate_one(problem, x)
    record = PhaseRecord.reached(
        "genetic",
        standing,
        accepted=True,
        iterations=generations,
        trajectories=problem.trajectories - before,
        wall_time_s=time.perf_counter() - start,
        message=f"pymoo GA, population {settings.population}, seed {settings.seed}; "
        f"relaxed constraint violation {float(cv[best_index]):.3g}"
        + (f"; stopped: {deadline.reason(generations, 'generations')}" if deadline.reached else ""),
    )
    return x, record


class _StallMonitor:
    """Stops a local method once it has stopped improving on the best design it has seen.

    The optimum is flat along some directions of the programme (e.g. alpha_2 against
    t_23), where SLSQP's step-length test never fires and its iterates drift along
    the flat valley while the payload has long converged; and ``trust-constr``
    started on a converged design wanders into the interior (its barrier pushes it
    off the active constraints) for its whole iteration budget. Both are cut off by
    one rule: ``stall_iterations`` consecutive iterations that bring no converged
    design (residual at most ``converged_residual`` of the tolerances, see
    :meth:`Standing.rank`) with a payload more than ``stall_payload_kg`` above the
    best such design so far (the start included) end the phase. The acceptance rule
    in :func:`optimise_launch` then keeps whichever design is better.
    """

    def __init__(
        self,
        problem: LaunchProblem,
        oracle: _Oracle,
        settings: LocalConfig,
        x0: NDArray,
        deadline: Deadline | None = None,
        on_progress: Callable[[int], None] | None = None,
    ) -> None:
        self.problem = problem
        self.on_progress = on_progress
        self.deadline = deadline or Deadline.unlimited()
        self.iterations = 0
        self.oracle = oracle
        self.window = settings.stall_iterations
        self.threshold = settings.stall_payload_kg
        self.converged_residual = settings.converged_residual
        self.reference = self._admissible_payload(np.asarray(x0, dtype=float))
        self.best_payload = self.reference
        self.best_x: NDArray | None = None  # best converged iterate (the start excluded)
        self.idle = 0
        self.stalled = False

    def _admissible_payload(self, x: NDArray) -> float:
        """Payload of ``x`` if it is converged (module notes), else -inf."""
        eq = self.oracle.equality(x)
        ineq = self.oracle.inequality(x) / self.problem.target.path_limit_fraction
        residual = max(float(np.max(np.abs(eq))), float(np.max(-ineq)), 0.0)
        if residual > self.converged_residual:
            return -np.inf
        return float(self.problem.to_config_units(x)[PAYLOAD_INDEX])

    def __call__(self, intermediate_result: object) -> None:
        self.iterations += 1
        if self.on_progress is not None:
            self.on_progress(self.iterations)
        x = np.asarray(getattr(intermediate_result, "x", intermediate_result), dtype=float)
        payload = self._admissible_payload(x)
        if payload > self.best_payload:
            self.best_payload, self.best_x = payload, x.copy()
        if payload > self.reference + self.threshold:
            self.reference, self.idle = payload, 0
        else:
            if np.isfinite(self.best_payload):
                self.idle += 1
            if self.idle >= self.window:
                self.stalled = True
                raise StopIteration
        self.deadline.stop_if_expired()

    def message(self, solver_message: str) -> str:
        if self.deadline.reached:
            return f"stopped: {self.deadline.reason(self.iterations)}"
        if self.stalled:
            return (
                f"stalled: {self.window} iterations without a converged design more than "
                f"{self.threshold:g} kg better (residual <= {self.converged_residual:g})"
            )
        return solver_message


def _local_outcome(
    name: str,
    problem: LaunchProblem,
    result: object,
    monitor: _StallMonitor,
    start: float,
    before: int,
    message: str,
) -> tuple[NDArray, PhaseRecord]:
    """A scipy local method's end point and its record (re-evaluated, not trusted).

    The end point is the solver's last iterate or, when it ranks better, the best
    converged iterate the phase visited: SLSQP on a flat optimum can walk from a
    converged design to one at the edge of the tolerances for a few grams.
    """
    x = np.clip(result.x, 0.0, 1.0)
    standing = _evaluate_one(problem, x)
    if monitor.best_x is not None:
        visited = np.clip(monitor.best_x, 0.0, 1.0)
        visited_standing = _evaluate_one(problem, visited)
        if is_better(visited_standing, standing, monitor.converged_residual):
            x, standing = visited, visited_standing
            message = f"{message}; best converged iterate kept"
    return x, PhaseRecord.reached(
        name,
        standing,
        accepted=False,
        iterations=int(result.nit),
        trajectories=problem.trajectories - before,
        wall_time_s=time.perf_counter() - start,
        message=message,
    )


def _local_deadline(settings: LocalConfig) -> Deadline:
    return Deadline(settings.time_limit_s, "launch.local.time_limit_s")


def _watched(
    problem: LaunchProblem,
    settings: LocalConfig,
    x0: NDArray,
    deadline: Deadline | None,
    on_iteration: Callable[[int], None] | None,
) -> tuple[_Oracle, _StallMonitor]:
    """A local phase's oracle and the monitor that stops it (stall, time limit, progress)."""
    oracle = _Oracle(problem, settings.finite_difference_step)
    monitor = _StallMonitor(
        problem, oracle, settings, x0, deadline or _local_deadline(settings), on_iteration
    )
    return oracle, monitor


def _iterations(
    on_progress: Progress | None, limit: int, name: str
) -> Callable[[int], None] | None:
    if on_progress is None:
        return None
    return lambda done: on_progress(min(done, limit), limit, name)


def run_slsqp(
    problem: LaunchProblem,
    x0: NDArray,
    settings: LocalConfig,
    deadline: Deadline | None = None,
    on_progress: Progress | None = None,
) -> tuple[NDArray, PhaseRecord]:
    start, before = time.perf_counter(), problem.trajectories
    oracle, monitor = _watched(
        problem,
        settings,
        x0,
        deadline,
        _iterations(on_progress, settings.slsqp_max_iterations, "slsqp"),
    )
    result = minimize(
        oracle.objective,
        x0,
        jac=oracle.objective_gradient,
        method="SLSQP",
        bounds=Bounds(0.0, 1.0),
        constraints=[
            {"type": "eq", "fun": oracle.equality, "jac": oracle.equality_jacobian},
            {"type": "ineq", "fun": oracle.inequality, "jac": oracle.inequality_jacobian},
        ],
        options={"maxiter": settings.slsqp_max_iterations, "ftol": settings.slsqp_ftol},
        callback=monitor,
    )
    return _local_outcome(
        "slsqp", problem, result, monitor, start, before, monitor.message(str(result.message))
    )


def run_trust_constr(
    problem: LaunchProblem,
    x0: NDArray,
    settings: LocalConfig,
    deadline: Deadline | None = None,
    on_progress: Progress | None = None,
) -> tuple[NDArray, PhaseRecord]:
    start, before = time.perf_counter(), problem.trajectories
    oracle, monitor = _watched(
        problem,
        settings,
        x0,
        deadline,
        _iterations(on_progress, settings.trust_constr_max_iterations, "trust-constr"),
    )
    n = len(x0)
    result = minimize(
        oracle.objective,
        x0,
        jac=oracle.objective_gradient,
        hess=lambda x: np.zeros((n, n)),
        method="trust-constr",
        bounds=Bounds(0.0, 1.0),
        constraints=[
            NonlinearConstraint(
                oracle.equality, 0.0, 0.0, jac=oracle.equality_jacobian, hess=BFGS()
            ),
            NonlinearConstraint(
                oracle.inequality, 0.0, np.inf, jac=oracle.inequality_jacobian, hess=BFGS()
            ),
        ],
        options={
            "maxiter": settings.trust_constr_max_iterations,
            "gtol": settings.trust_constr_gtol,
            "xtol": settings.trust_constr_xtol,
        },
        callback=monitor,
    )
    message = f"{monitor.message(str(result.message))} (method {result.method})"
    return _local_outcome("trust-constr", problem, result, monitor, start, before, message)


def optimise_launch(
    problem: LaunchProblem,
    genetic: GeneticConfig,
    local: LocalConfig,
    *,
    seed_x: NDArray | None = None,
    global_search: bool = True,
    on_progress: Progress | None = None,
) -> OptimisationOutcome:
    """GA (unless ``global_search`` is off and a seed is given) -> SLSQP -> trust-constr.

    ``on_progress(done, total, phase)`` after each generation or iteration; what each
    phase reached is logged (debug)."""
    start, before = time.perf_counter(), problem.trajectories
    phases: list[PhaseRecord] = []
    limit = None
    if global_search or seed_x is None:
        deadline = Deadline(genetic.time_limit_s, "launch.genetic.time_limit_s")
        x, record = run_genetic(
            problem, genetic, seed_x=seed_x, deadline=deadline, on_progress=on_progress
        )
        if deadline.reached:
            limit = f"genetic search stopped: {deadline.reason(record.iterations, 'generations')}"
    else:
        x = np.clip(np.asarray(seed_x, dtype=float), 0.0, 1.0)
        standing = _evaluate_one(problem, x)
        record = PhaseRecord.reached(
            "seed",
            standing,
            accepted=True,
            iterations=0,
            trajectories=1,
            wall_time_s=0.0,
            message="given start",
        )
    phases.append(record)
    _log_phase(record)
    best = record.standing
    converged = local.converged_residual
    for run in (run_slsqp, run_trust_constr):
        if limit is not None:
            break
        deadline = _local_deadline(local)
        x_new, record = run(problem, x, local, deadline, on_progress)
        accepted = is_better(record.standing, best, converged)
        phases.append(PhaseRecord(**(record.as_dict() | {"accepted": accepted})))
        _log_phase(phases[-1])
        if accepted:
            x, best = x_new, record.standing
        if deadline.reached:
            limit = f"{record.name} stopped: {deadline.reason(record.iterations)}"
    return OptimisationOutcome(
        x=x,
        payload_kg=best.payload_kg,
        max_violation=best.violation,
        max_residual=best.residual,
        phases=phases,
        trajectories=problem.trajectories - before,
        wall_time_s=time.perf_counter() - start,
        limit=limit,
    )


def _log_phase(record: PhaseRecord) -> None:
    logger.debug(
        f"launch {record.name}: payload {record.payload_kg:.2f} kg, residual "
        f"{record.max_residual:.3g}, {record.iterations} iterations, "
        f"{record.wall_time_s:.1f} s{'' if record.accepted else ' (not kept)'}"
    )
