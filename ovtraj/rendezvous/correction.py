"""Interior-point correction of the first impulse and the transfer time under J2.

Patent step 102: the two-body Hohmann impulse and transfer time are the
starting point; under J2 they are corrected until the chaser arrives within
``epsilon_dis`` of the target. We pose it as the NLP

    minimise   |dv1| + |dv2|,   dv2 = v_target(t_a) - v_chaser(t_a)
    subject to r_chaser(t_a) - r_target(t_a) = 0
               T in [T_lo, T_hi],  burn-epoch shift in [-w, w]

with variables dv1 (ECI, 3), the transfer time T and, for a rendezvous, a shift
of the burn epoch (so the phasing itself is corrected under J2 and the actual
lead angle is an output, not an input). The trust-region interior-point
(barrier) method of :mod:`.interior_point` solves it because the problem has
bounds; it is scipy ``trust-constr``'s algorithm written for this 4-5-variable
dense problem, and takes 5-20 iterations where trust-constr took 10-20 at about
three times the cost each (docs/rendezvous.md).

Derivatives: first derivatives are exact (state-transition matrix from the
variational equations); the Hessians are forward differences of those exact
gradients, which is what brings the interior point from hundreds of quasi-Newton
iterations down to a handful.

Start: a transfer angle of exactly 180 deg cannot remove an out-of-plane miss
(the cross-track column of the STM vanishes there), so with the small plane
difference J2 creates during phasing the optimum sits on either side of the
Hohmann time. A few Newton shots of dv1 on the miss at fixed transfer times
(a J2 Lambert solve, 2-3 propagations each) give feasible candidates; the
cheapest one starts the interior-point solve. With a plane difference the NLP
has several local optima (transfer-time fractions near 0.65, 1.0 and 1.25 on
the default scenario) and the cheapest shot is often not in the best one's
basin, so ``solve_every_start`` runs the interior point from every shot and
keeps the cheapest optimum (docs/rendezvous.md, "Local optima").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ovtraj.astro.propagation import OrbitPropagator, PropagationResult
from ovtraj.astro.propagation.gravity import two_body_j2_acceleration_compiled
from ovtraj.deadline import Deadline
from ovtraj.rendezvous.interior_point import (
    ITERATION_LIMIT,
    InteriorPointResult,
    minimize_interior_point,
)

# Newton shots of the start: each step gains digits quadratically; a shot that
# needs more than this is in a bad region and is dropped.
_START_NEWTON_STEPS = 8
# A shot whose impulse grows beyond this multiple of the Hohmann impulse is near
# the 180-degree singularity (or worse) and is not a useful start.
_START_MAX_IMPULSE_RATIO = 10.0


@dataclass(frozen=True)
class CorrectionProblem:
    """Everything the correction needs; times in s from the scenario epoch, SI units."""

    propagator: OrbitPropagator
    chaser_coast: PropagationResult  # dense, covers the burn window
    target_coast: PropagationResult  # dense, covers every possible arrival time
    burn_time_s: float
    hohmann_time_s: float
    dv_guess_eci: np.ndarray
    miss_tolerance_m: float
    transfer_time_bounds: tuple[float, float]  # fractions of hohmann_time_s
    start_fractions: tuple[float, ...]  # transfer-time fractions tried for the start
    burn_window_s: float  # 0 keeps the burn epoch fixed
    max_iterations: int
    optimality_tol: float
    initial_barrier_parameter: float
    initial_trust_radius: float
    # Wall-time limit of the whole solve (started by the stage); none by default.
    deadline: Deadline = field(default_factory=Deadline.unlimited)
    # Config key of max_iterations, for the reason when the limit stops the solver.
    iterations_key: str = "max_iterations"
    # True: the interior point runs from every start shot (a failed shot: from the
    # Hohmann guess) and the cheapest converged optimum is kept; False: from the
    # cheapest shot only.
    solve_every_start: bool = False


@dataclass(frozen=True)
class CorrectionResult:
    converged: bool
    burn_time_s: float
    transfer_time_s: float
    dv1_eci: np.ndarray
    dv2_eci: np.ndarray
    miss_distance_m: float
    initial_miss_distance_m: float
    chaser_at_burn: np.ndarray  # before the first impulse
    chaser_at_arrival: np.ndarray  # before the second impulse
    target_at_arrival: np.ndarray
    iterations: int
    evaluations: int
    message: str
    # The limit (iterations or wall time) that stopped the solve, naming its config key.
    limit: str | None = None


@dataclass(frozen=True)
class _Point:
    """One candidate transfer with its exact first derivatives (scaled variables)."""

    x: np.ndarray
    cost: float
    grad: np.ndarray
    miss: np.ndarray
    d_miss: np.ndarray
    dv1: np.ndarray
    dv2: np.ndarray
    chaser: np.ndarray
    final: np.ndarray
    target: np.ndarray
    burn_time: float
    transfer_time: float


@dataclass(frozen=True)
class _Candidates:
    """Several candidates: every field of :class:`_Point` as an array, one row per lane."""

    columns: dict[str, np.ndarray]

    def point(self, k: int) -> _Point:
        return _Point(
            **{
                name: float(column[k]) if name in _POINT_SCALARS else column[k]
                for name, column in self.columns.items()
            }
        )


# The float fields of _Point (the others are arrays).
_POINT_SCALARS = ("cost", "burn_time", "transfer_time")


class _Transfer:
    """Evaluates candidate transfers; caches the last point and the last Hessians."""

    def __init__(self, problem: CorrectionProblem) -> None:
        self.p = problem
        self.dv_scale = max(float(np.linalg.norm(problem.dv_guess_eci)), 1.0)
        self.free_epoch = problem.burn_window_s > 0.0
        self.n = 5 if self.free_epoch else 4
        self.evaluations = 0
        self._point: _Point | None = None
        self._hessians: tuple[bytes, np.ndarray, np.ndarray] | None = None
        earth = problem.propagator.earth
        j2 = earth.j2 if problem.propagator.j2 else 0.0
        self._gravity = (earth.mu, earth.radius, j2)
        # Forward-difference step for Hessians of exact gradients: sqrt of their noise.
        self._fd_step = math.sqrt(problem.propagator.tol)
        self._to_scaled = np.array([self.dv_scale] * 3 + [problem.hohmann_time_s] * 2)[: self.n]
        # Miss scaled by the displacement one scaled impulse produces, r dv / v, so the
        # constraint Jacobian is O(1); scaling by epsilon_dis instead makes the barrier
        # subproblems stiff (90+ iterations instead of ~12).
        chaser = problem.chaser_coast.state_at(problem.burn_time_s)
        self.miss_scale = (
            float(np.linalg.norm(chaser[:3])) * self.dv_scale / float(np.linalg.norm(chaser[3:]))
        )

    def x_at(self, dv: np.ndarray, fraction: float) -> np.ndarray:
        x = np.zeros(self.n)
        x[:3] = dv / self.dv_scale
        x[3] = fraction
        return x

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the scaled variables (infinite: none)."""
        lo, hi = self.p.transfer_time_bounds
        lower, upper = [-np.inf] * 3 + [lo], [np.inf] * 3 + [hi]
        if self.free_epoch:
            w = self.p.burn_window_s / self.p.hohmann_time_s
            lower.append(-w)
            upper.append(w)
        return np.array(lower), np.array(upper)

    def at(self, x: np.ndarray) -> _Point:
        x = np.asarray(x, dtype=float)
        if self._point is not None and np.array_equal(x, self._point.x):
            return self._point
        self._point = self._evaluate(x.copy())
        return self._point

    def _evaluate(self, x: np.ndarray) -> _Point:
        self.evaluations += 1
        burn_time, arrival, chaser, after_burn = self._departure(x)
        final, stm = self.p.propagator.propagate_with_stm(after_burn, burn_time, arrival)
        return self._candidates(x[None, :], chaser[None, :], final[None, :], stm[None]).point(0)

    def _evaluate_many(self, xs: list[np.ndarray]) -> _Candidates:
        """:meth:`_evaluate` of several points, their arcs in one batch propagation."""
        self.evaluations += len(xs)
        x = np.array(xs, dtype=float)
        burn_time, arrival = self._epochs(x)
        chaser = self.p.chaser_coast.states_at(burn_time)
        after_burn = chaser.copy()
        after_burn[:, 3:] += x[:, :3] * self.dv_scale
        finals, stms = self.p.propagator.propagate_with_stm_batch(after_burn, burn_time, arrival)
        return self._candidates(x, chaser, finals, stms)

    def _epochs(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Burn and arrival epochs [s] of points x (m, n)."""
        p = self.p
        shift = x[..., 4] if self.free_epoch else np.zeros_like(x[..., 3])
        burn_time = p.burn_time_s + shift * p.hohmann_time_s
        return burn_time, burn_time + x[..., 3] * p.hohmann_time_s

    def _departure(self, x: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
        """Burn epoch, arrival epoch, chaser state before and after the first impulse."""
        burn_time, arrival = (float(t) for t in self._epochs(x))
        chaser = self.p.chaser_coast.state_at(burn_time)
        after_burn = chaser.copy()
        after_burn[3:] += x[:3] * self.dv_scale
        return burn_time, arrival, chaser, after_burn

    def _candidates(
        self, x: np.ndarray, chaser: np.ndarray, final: np.ndarray, stm: np.ndarray
    ) -> _Candidates:
        """The candidates at points x (m, n) from their arcs' end states (m, 6) and
        state-transition matrices (m, 6, 6), all lanes in one pass of array arithmetic
        (a Hessian's columns are ~5 candidates per iteration)."""
        p = self.p
        burn_time, arrival = self._epochs(x)
        target = p.target_coast.states_at(arrival)
        cost, grad, d_miss, dv, dv2 = _transfer_terms(
            x, final, stm, target, self.dv_scale, self._to_scaled, *self._gravity
        )
        return _Candidates(
            {
                "x": x,
                "cost": cost,
                "grad": grad,
                "miss": final[:, :3] - target[:, :3],
                "d_miss": d_miss,
                "dv1": dv,
                "dv2": dv2,
                "chaser": chaser,
                "final": final,
                "target": target,
                "burn_time": burn_time,
                "transfer_time": x[:, 3] * p.hohmann_time_s,
            }
        )

    def hessians(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Objective Hessian (n, n) and constraint Hessians (3, n, n), forward differences."""
        key = np.asarray(x, dtype=float).tobytes()
        if self._hessians is None or self._hessians[0] != key:
            base = self.at(x)
            # The columns' arcs are independent: one batch propagation, for speed.
            self._store_hessians(base, self._evaluate_many(self._columns(base.x)), 0)
        return self._hessians[1], self._hessians[2]

    def at_with_hessians(self, x: np.ndarray) -> _Point:
        """:meth:`at`, the Hessians' columns propagated in the same batch.

        The interior point's trial points: it needs their Hessians whenever it accepts
        one, and a batch of n + 1 lanes costs about what n cost (heyoka's SIMD lanes), so
        the point itself comes almost free; a rejected trial wastes ~0.4 of a propagation.
        """
        x = np.array(x, dtype=float)
        if self._hessians is not None and self._hessians[0] == x.tobytes():
            return self.at(x)
        lanes = self._evaluate_many([x, *self._columns(x)])
        base = lanes.point(0)
        self._point = base
        self._store_hessians(base, lanes, 1)
        return base

    def _columns(self, x: np.ndarray) -> list[np.ndarray]:
        return [x + self._fd_step * e for e in np.eye(self.n)]

    def _store_hessians(self, base: _Point, lanes: _Candidates, first: int) -> None:
        """Forward-difference Hessians from the gradients of ``lanes`` ``first`` on (the
        columns, in order) and of ``base``."""
        columns = slice(first, first + self.n)
        grad, d_miss = lanes.columns["grad"][columns], lanes.columns["d_miss"][columns]
        h_obj = ((grad - base.grad) / self._fd_step).T
        h_con = ((d_miss - base.d_miss) / self._fd_step).transpose(1, 2, 0)
        h_obj = 0.5 * (h_obj + h_obj.T)
        h_con = 0.5 * (h_con + h_con.transpose(0, 2, 1))
        self._hessians = (base.x.tobytes(), h_obj, h_con)

    def newton_shots(self, fractions: tuple[float, ...]) -> list[_Point | None]:
        """dv1 that meets the target at each fixed transfer time (J2 Lambert by Newton).

        The shots run in lockstep, each step's arcs in one batch propagation (for speed);
        a shot is dropped (None) when it needs more than ``_START_NEWTON_STEPS`` steps,
        its impulse grows past ``_START_MAX_IMPULSE_RATIO`` or its arc cannot be flown.
        """
        xs = [self.x_at(self.p.dv_guess_eci, f) for f in fractions]
        shots: list[_Point | None] = [None] * len(xs)
        active = list(range(len(xs)))
        for _ in range(_START_NEWTON_STEPS):
            if not active or self.p.deadline.expired():
                break
            try:
                lanes = self._evaluate_many([xs[k] for k in active])
                points: list[_Point | None] = [lanes.point(i) for i in range(len(active))]
            except FloatingPointError:
                points = [self._flown(xs[k]) for k in active]
            still = []
            for k, point in zip(active, points, strict=True):
                if point is None:
                    continue
                if np.linalg.norm(point.miss) <= self.p.miss_tolerance_m:
                    shots[k] = point
                    continue
                # Least squares: at 180 deg the cross-track column is (nearly) zero.
                x = xs[k].copy()
                x[:3] -= np.linalg.lstsq(point.d_miss[:, :3], point.miss, rcond=1e-10)[0]
                if np.linalg.norm(x[:3]) <= _START_MAX_IMPULSE_RATIO:
                    xs[k] = x
                    still.append(k)
            active = still
        return shots

    def _flown(self, x: np.ndarray) -> _Point | None:
        try:
            return self._evaluate(x)
        except FloatingPointError:
            return None


# |v| is kept differentiable at a zero impulse (a legitimate point) by this square [m^2/s^2].
_NORM_FLOOR = 1e-12


@njit(cache=True)
def _derivative(state: np.ndarray, out: np.ndarray, mu: float, radius: float, j2: float) -> None:
    """The J2 flow's time derivative of a Cartesian state, into ``out``."""
    ax, ay, az = two_body_j2_acceleration_compiled(state[0], state[1], state[2], mu, radius, j2)
    out[0], out[1], out[2], out[3], out[4], out[5] = state[3], state[4], state[5], ax, ay, az


@njit(cache=True)
def _transfer_terms(
    x: np.ndarray,
    final: np.ndarray,
    stm: np.ndarray,
    target: np.ndarray,
    dv_scale: float,
    to_scaled: np.ndarray,
    mu: float,
    radius: float,
    j2: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cost, its gradient and the miss's Jacobian of each lane (scaled variables).

    Lane k: the point ``x[k]`` (n,), the arc's end state ``final[k]`` and its
    state-transition matrix ``stm[k]`` (6, 6), the target ``target[k]`` at arrival; the
    states' time derivatives f come from the J2 field (``mu``, ``radius``, ``j2``).
    With dv1 = x[:3] dv_scale and dv2 = v_target - v_final the cost is
    (|dv1| + |dv2|) / dv_scale. d(final) / d(dv1, T, burn epoch): the STM's velocity
    columns, f(final), and (the flow is autonomous) for the burn epoch with T fixed
    f(final) + Phi (f(x_c) - f(x_c + dv1)) = f(final) - Phi_r dv1; the target moves by
    f(target) with either epoch. Compiled: ~35 lanes a mission evaluation.
    """
    m, n = x.shape
    cost = np.empty(m)
    grad = np.empty((m, n))
    d_miss = np.empty((m, 3, n))
    dv = np.empty((m, 3))
    dv2 = np.empty((m, 3))
    d_final = np.empty((6, 5))
    f_final, f_target = np.empty(6), np.empty(6)
    for k in range(m):
        _derivative(final[k], f_final, mu, radius, j2)
        _derivative(target[k], f_target, mu, radius, j2)
        for i in range(3):
            dv[k, i] = x[k, i] * dv_scale
            dv2[k, i] = target[k, 3 + i] - final[k, 3 + i]
        for i in range(6):
            for j in range(3):
                d_final[i, j] = stm[k, i, 3 + j]
            d_final[i, 3] = f_final[i]
            d_final[i, 4] = f_final[i]
            for j in range(3):
                d_final[i, 4] -= stm[k, i, j] * dv[k, j]
        n1 = math.sqrt(dv[k, 0] ** 2 + dv[k, 1] ** 2 + dv[k, 2] ** 2 + _NORM_FLOOR)
        n2 = math.sqrt(dv2[k, 0] ** 2 + dv2[k, 1] ** 2 + dv2[k, 2] ** 2 + _NORM_FLOOR)
        for j in range(n):
            target_moves = j >= 3
            along = 0.0
            for i in range(3):
                d_target_r = f_target[i] if target_moves else 0.0
                d_target_v = f_target[3 + i] if target_moves else 0.0
                d_miss[k, i, j] = (d_final[i, j] - d_target_r) * to_scaled[j]
                along += dv2[k, i] * (d_target_v - d_final[3 + i, j]) * to_scaled[j]
            grad[k, j] = along / n2
            if j < 3:
                grad[k, j] += dv[k, j] / n1 * dv_scale
            grad[k, j] /= dv_scale
        cost[k] = (n1 + n2) / dv_scale
    return cost, grad, d_miss, dv, dv2


def _interior_point(
    transfer: _Transfer, start: _Point, problem: CorrectionProblem
) -> InteriorPointResult:
    scale = transfer.miss_scale

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        point = transfer.at_with_hessians(x)
        return point.cost, point.grad, point.miss / scale, point.d_miss / scale

    def lagrangian_hessian(x: np.ndarray, multipliers: np.ndarray) -> np.ndarray:
        h_obj, h_con = transfer.hessians(x)
        return h_obj + np.einsum("i,ijk->jk", multipliers, h_con) / scale

    lower, upper = transfer.bounds()
    return minimize_interior_point(
        evaluate,
        lagrangian_hessian,
        start.x,
        lower,
        upper,
        tol=problem.optimality_tol,
        max_iterations=problem.max_iterations,
        barrier_parameter=problem.initial_barrier_parameter,
        trust_radius=problem.initial_trust_radius,
        deadline=problem.deadline,
    )


def _solve_from(
    transfer: _Transfer, start: _Point, guess: _Point, problem: CorrectionProblem
) -> tuple[_Point, InteriorPointResult]:
    """The interior point from ``start``: its optimum (or the start, if that is better)."""
    try:
        solution = _interior_point(transfer, start, problem)
    except FloatingPointError as err:
        # The start itself lies where the J2 flow cannot be integrated (trial steps that
        # do are rejected inside the solver).
        solution = InteriorPointResult(start.x, np.zeros(3), 0, f"stopped: {err}", math.inf)
    best = transfer.at(solution.x)
    # The interior-point iterate is accepted only if it is at least as good as its start.
    tol = problem.miss_tolerance_m
    if start is not guess and not (np.linalg.norm(best.miss) <= tol and best.cost <= start.cost):
        best = start
    return best, solution


def _rank(point: _Point, tolerance_m: float) -> tuple[bool, float]:
    """Order of the solves' optima: within the miss tolerance first, then the cheapest."""
    miss = float(np.linalg.norm(point.miss))
    return (not (np.isfinite(miss) and miss <= tolerance_m), point.cost)


def _distinct(points: list[_Point]) -> list[_Point]:
    """``points`` without repeats (two failed shots both fall back to the guess)."""
    kept: list[_Point] = []
    for point in points:
        if not any(point is other for other in kept):
            kept.append(point)
    return kept


def correct_transfer(problem: CorrectionProblem) -> CorrectionResult:
    """Solve the J2 correction NLP; never raises on non-convergence (``converged`` says).

    It stops at ``max_iterations`` (per interior-point solve) or at ``problem.deadline``
    (all of them); either makes the result unconverged, with ``limit`` naming the limit.
    """
    transfer = _Transfer(problem)
    guess = transfer.at(transfer.x_at(problem.dv_guess_eci, 1.0))
    initial_miss = float(np.linalg.norm(guess.miss))
    shots = transfer.newton_shots(problem.start_fractions)
    feasible = [s for s in shots if s is not None]
    if problem.solve_every_start:
        starts = _distinct([guess if s is None else s for s in shots])
    else:
        starts = [min(feasible, key=lambda s: s.cost) if feasible else guess]
    solves = []
    for start in starts:
        solves.append(_solve_from(transfer, start, guess, problem))
        if problem.deadline.expired():
            break
    best, solution = min(solves, key=lambda s: _rank(s[0], problem.miss_tolerance_m))
    miss = float(np.linalg.norm(best.miss))
    iterations = solution.iterations
    limit = None
    if problem.deadline.expired():
        limit = problem.deadline.reason(iterations)
    elif solution.status == ITERATION_LIMIT:
        limit = f"{problem.iterations_key} = {problem.max_iterations} reached"
    return CorrectionResult(
        converged=bool(np.isfinite(miss) and miss <= problem.miss_tolerance_m) and limit is None,
        burn_time_s=best.burn_time,
        transfer_time_s=best.transfer_time,
        dv1_eci=best.dv1,
        dv2_eci=best.dv2,
        miss_distance_m=miss,
        initial_miss_distance_m=initial_miss,
        chaser_at_burn=best.chaser,
        chaser_at_arrival=best.final,
        target_at_arrival=best.target,
        iterations=iterations,
        evaluations=transfer.evaluations,
        message=solution.message,
        limit=limit,
    )
