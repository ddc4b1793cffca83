"""Finite-thrust correction of an impulse plan (seed 003 sec. 2), re-optimised by SLSQP.

1. **Conversion** (seed sec. 2.3). Each impulse becomes a constant-thrust burn along
   its dv whose duration is eq. 15, ``dt = m c / F (1 - exp(-|dv| / c))``, from the
   mass the previous burns left. A burn in the middle of the manoeuvre is centred on
   the impulse epoch (``t_c - dt/2`` to ``t_c + dt/2``); a burn at the start starts
   with the manoeuvre (t = 0) and a burn at the end ends with it (``t_f``), as the
   seed prescribes. Burns that would overlap are pushed back to start when the
   previous one ends (impulses a fraction of a second apart become one continuous
   burn with a change of direction).
2. **Re-optimisation.** The seed re-optimises the equivalent impulses with its IDE; a
   gradient method does it here, from the converted burns (already close to the
   optimum, and the flight is smooth in every variable): scipy's SLSQP (Kraft 1988) on
   the variables

   * each burn's duration, and its direction ``u = (u0 + a e1 + b e2) / |...|`` by two
     angles (``u0`` the impulse direction, ``e1``, ``e2`` normal to it: regular at
     the start, unlike spherical angles);
   * the start of every middle burn; the end of the manoeuvre ``t_f`` (the last burn of
     a rendezvous or transfer ends there, so its start is ``t_f - dt_n``);

   with the end condition as equality constraints (scaled residuals of
   :mod:`ovtraj.studies.maneuver.endpoint`), the burns in order without overlap and the total
   burning time within ``t_e`` (eq. 13) as linear inequalities, and the objective of
   the problem: ``t_f`` (minimum time) or the total burning time (minimum propellant,
   the finite form of minimum dv). The powered flight is integrated with the mass flow
   (:mod:`ovtraj.studies.maneuver.thrust`, eq. 12) under two-body or J2 gravity.
   Derivatives of the residuals are central differences (the flight is smooth in every
   variable; heyoka's tolerance is far below the difference step's effect).
   SLSQP is stopped once ``t_f`` (or the burning time) has not moved by more than
   ``stall_tolerance_s`` over ``stall_iterations`` iterations with every residual
   within its scale: it reaches the optimum quickly and then creeps along the
   constraints.
3. **Polish**: minimum-norm Gauss-Newton steps on the end-condition residuals, the
   active linear constraints held, while they reduce the residual.

SLSQP stops at ``max_iterations``, and SLSQP and the polish at ``time_limit_s`` (wall
time): either leaves the correction unconverged, with the limit in its message.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import OptimizeResult, minimize

from ovtraj.astro.propagation import OrbitPropagator, PropagationResult
from ovtraj.astro.rocket import burn_durations
from ovtraj.astro.vectors import cross
from ovtraj.deadline import Deadline
from ovtraj.studies.maneuver.endpoint import orbit_point, transfer_residuals
from ovtraj.studies.maneuver.problem import ManeuverProblem
from ovtraj.studies.maneuver.thrust import Burn, BurnFlight, Flight, fly

__all__ = ["FiniteBurnResult", "FiniteBurnSolver", "convert_impulses"]

# scipy's SLSQP status at ``maxiter``.
_SLSQP_ITERATION_LIMIT = 9


@dataclass(frozen=True)
class FiniteBurnResult:
    """The corrected burns and how well the end condition holds with them."""

    converged: bool
    message: str
    time_of_flight_s: float
    burns: tuple[BurnFlight, ...]
    final_state: NDArray[np.float64]  # stage at t_f, after the last burn
    goal_state: NDArray[np.float64]  # target (or target-orbit point) at t_f
    final_position_error_m: float
    final_velocity_error_mps: float | None  # None for an interception
    relative_speed_mps: float  # |v - v_goal| at t_f (an interception's impact speed)
    initial_position_error_m: float  # the seed's conversion (step 1), before SLSQP
    initial_velocity_error_mps: float | None
    total_burn_time_s: float
    iterations: int
    flights: int
    wall_time_s: float


def _basis(u0: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit vectors normal to ``u0`` and to each other."""
    helper = np.eye(3)[int(np.argmin(np.abs(u0)))]
    e1 = cross(u0, helper)
    e1 /= np.linalg.norm(e1)
    return e1, cross(u0, e1)


def convert_impulses(
    problem: ManeuverProblem, epochs: NDArray[np.float64], dv: NDArray[np.float64], tof: float
) -> list[Burn]:
    """Step 1 of the module notes: impulses (n,) epochs, (n, 3) ECI dv -> burns."""
    norms = np.linalg.norm(dv, axis=1)
    durations, _ = burn_durations(
        norms, problem.initial_mass_kg, problem.thrust_n, problem.isp_n_s_kg
    )
    n = len(epochs)
    tied_last = problem.end_condition != "interception"
    burns: list[Burn] = []
    previous_end = 0.0
    for k in range(n):
        direction = dv[k] / norms[k] if norms[k] > 0.0 else np.array([1.0, 0.0, 0.0])
        if k == 0:
            start = 0.0
        elif tied_last and k == n - 1:
            start = tof - durations[k]
        else:
            start = max(epochs[k] - 0.5 * durations[k], previous_end)
        burns.append(Burn(float(start), float(durations[k]), direction))
        previous_end = start + durations[k]
    return burns


class FiniteBurnSolver:
    """Re-optimises the burns of one impulse plan (module notes, step 2)."""

    def __init__(
        self,
        problem: ManeuverProblem,
        epochs: NDArray[np.float64],
        dv: NDArray[np.float64],
        tof: float,
    ) -> None:
        self.p = problem
        self.cfg = problem.finite
        self.j2 = self.cfg.dynamics == "j2"
        self.mu = problem.earth.mu
        self.n = len(epochs)
        self.tied_last = problem.end_condition != "interception"
        self.initial_burns = convert_impulses(problem, epochs, dv, tof)
        self.tof0 = float(tof)
        propagator = OrbitPropagator(problem.earth, tol=problem.integrator_tol, j2=self.j2)
        # The target over every t_f the optimiser may try.
        self.target_coast: PropagationResult = propagator.propagate(
            problem.target_state, 0.0, problem.tof_bounds_s[1], dense=True
        )
        self.u0 = [b.direction for b in self.initial_burns]
        self.bases = [_basis(u) for u in self.u0]
        # Variable layout: per burn [start?, duration, a, b], then t_f.
        self.start_index: list[int | None] = []
        self.duration_index: list[int] = []
        self.angle_index: list[int] = []
        i = 0
        for k in range(self.n):
            free_start = k > 0 and not (self.tied_last and k == self.n - 1)
            self.start_index.append(i if free_start else None)
            i += int(free_start)
            self.duration_index.append(i)
            self.angle_index.append(i + 1)
            i += 3
        self.tf_index = i
        self.n_vars = i + 1
        self.flights = 0
        self.deadline = Deadline.unlimited()  # solve() starts finite_burn.time_limit_s
        self._cache: dict[bytes, tuple[Flight, NDArray[np.float64], NDArray[np.float64]]] = {}

    # ------------------------------------------------------------------ variables
    def pack(self, burns: list[Burn], tof: float) -> NDArray[np.float64]:
        ts = self.cfg.time_scale_s
        z = np.zeros(self.n_vars)
        for k, burn in enumerate(burns):
            if self.start_index[k] is not None:
                z[self.start_index[k]] = burn.start_s / ts
            z[self.duration_index[k]] = burn.duration_s / ts
            # Directions are packed relative to the impulse's own direction: zero angles.
        z[self.tf_index] = tof / ts
        return z

    def unpack(self, z: NDArray[np.float64]) -> tuple[list[Burn], float]:
        ts, sa = self.cfg.time_scale_s, self.cfg.angle_scale_rad
        tof = float(z[self.tf_index] * ts)
        burns = []
        for k in range(self.n):
            duration = float(z[self.duration_index[k]] * ts)
            if k == 0:
                start = 0.0
            elif self.start_index[k] is None:
                start = tof - duration
            else:
                start = float(z[self.start_index[k]] * ts)
            e1, e2 = self.bases[k]
            j = self.angle_index[k]
            direction = self.u0[k] + sa * z[j] * e1 + sa * z[j + 1] * e2
            burns.append(Burn(start, duration, direction / np.linalg.norm(direction)))
        return burns, tof

    # ------------------------------------------------------------------ flight
    def _fly(self, z: NDArray[np.float64]) -> tuple[Flight, NDArray[np.float64], NDArray]:
        key = z.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        burns, tof = self.unpack(z)
        p = self.p
        flight = fly(
            p.chaser_state,
            p.initial_mass_kg,
            burns,
            tof,
            earth=p.earth,
            j2=self.j2,
            thrust_n=p.thrust_n,
            isp_n_s_kg=p.isp_n_s_kg,
            tol=p.integrator_tol,
        )
        self.flights += 1
        goal = self._goal(tof, flight.state)
        residuals = self._residuals(flight.state, goal, tof)
        if len(self._cache) > 256:
            self._cache.clear()
        self._cache[key] = (flight, goal, residuals)
        return flight, goal, residuals

    def _goal(self, tof: float, state: NDArray[np.float64]) -> NDArray[np.float64]:
        lo, hi = self.target_coast.t0, self.target_coast.t
        target = self.target_coast.state_at(min(max(tof, lo), hi))
        if self.p.end_condition == "transfer":
            return orbit_point(target, state[:3], self.mu)
        return target

    def _residuals(
        self, state: NDArray[np.float64], goal: NDArray[np.float64], tof: float
    ) -> NDArray[np.float64]:
        cfg = self.cfg
        if self.p.end_condition == "transfer":
            lo, hi = self.target_coast.t0, self.target_coast.t
            target = self.target_coast.state_at(min(max(tof, lo), hi))
            return transfer_residuals(state, target, self.mu) / cfg.position_scale_m
        dr = (state[:3] - goal[:3]) / cfg.position_scale_m
        if self.p.end_condition == "interception":
            return dr
        return np.r_[dr, (state[3:] - goal[3:]) / cfg.velocity_scale_mps]

    def residuals(self, z: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._fly(z)[2]

    def jacobian(self, z: NDArray[np.float64]) -> NDArray[np.float64]:
        h = self.cfg.difference_step
        cols = []
        for j in range(self.n_vars):
            step = np.zeros(self.n_vars)
            step[j] = h
            cols.append((self.residuals(z + step) - self.residuals(z - step)) / (2.0 * h))
        return np.array(cols).T

    # ------------------------------------------------------------------ constraints
    def linear_inequalities(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``G z + g >= 0``: burns in order, no overlap; total burning within t_e."""
        rows, consts = [], []

        def start_row(k: int) -> tuple[NDArray[np.float64], float]:
            row = np.zeros(self.n_vars)
            if k == 0:
                return row, 0.0
            if self.start_index[k] is None:
                row[self.tf_index] = 1.0
                row[self.duration_index[k]] = -1.0
                return row, 0.0
            row[self.start_index[k]] = 1.0
            return row, 0.0

        for k in range(self.n - 1):
            nxt, _ = start_row(k + 1)
            cur, _ = start_row(k)
            row = nxt - cur
            row[self.duration_index[k]] -= 1.0
            rows.append(row)
            consts.append(0.0)
        if not self.tied_last:
            cur, _ = start_row(self.n - 1)
            row = -cur
            row[self.tf_index] += 1.0
            row[self.duration_index[self.n - 1]] -= 1.0
            rows.append(row)
            consts.append(0.0)
        row = np.zeros(self.n_vars)
        row[self.duration_index] = -1.0
        rows.append(row)
        consts.append(self.p.max_burn_time_s / self.cfg.time_scale_s)
        return np.array(rows), np.array(consts)

    def bounds(self) -> list[tuple[float | None, float | None]]:
        ts = self.cfg.time_scale_s
        # Directions within 45 deg of the impulse's (tan = 1): far beyond any correction.
        angle = 1.0 / self.cfg.angle_scale_rad
        out: list[tuple[float | None, float | None]] = [(None, None)] * self.n_vars
        for k in range(self.n):
            if self.start_index[k] is not None:
                out[self.start_index[k]] = (0.0, self.p.tof_bounds_s[1] / ts)
            out[self.duration_index[k]] = (0.0, self.p.max_burn_time_s / ts)
            out[self.angle_index[k]] = (-angle, angle)
            out[self.angle_index[k] + 1] = (-angle, angle)
        out[self.tf_index] = (self.p.tof_bounds_s[0] / ts, self.p.tof_bounds_s[1] / ts)
        return out

    # ------------------------------------------------------------------ errors
    def errors(self, z: NDArray[np.float64]) -> tuple[float, float | None, float]:
        flight, goal, _ = self._fly(z)
        dr = float(np.linalg.norm(flight.state[:3] - goal[:3]))
        dv = float(np.linalg.norm(flight.state[3:] - goal[3:]))
        return dr, (None if self.p.end_condition == "interception" else dv), dv

    def _met(self, z: NDArray[np.float64]) -> bool:
        dr, dv, _ = self.errors(z)
        g, c = self.linear_inequalities()
        # Ordered and within t_e to a microsecond (the steps solve them to rounding).
        ordered = bool(np.all(g @ z + c >= -self.cfg.difference_step))
        ok = dr <= self.cfg.position_tolerance_m and ordered
        if dv is not None:
            ok = ok and dv <= self.cfg.velocity_tolerance_mps
        return ok and self._fly(z)[0].ok

    # ------------------------------------------------------------------ solve
    def _polish(
        self, z: NDArray[np.float64], g_mat: NDArray[np.float64], g_const: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], int]:
        """Minimum-norm Gauss-Newton steps on the end residuals (module notes, step 3).

        The linear inequalities that are active (or violated) are held as equalities, so
        the steps neither overlap burns nor exceed ``t_e``; steps continue while they
        reduce the residual.
        """
        steps = 0
        residual = self.residuals(z)
        for _ in range(self.cfg.polish_iterations):
            if self.deadline.expired():
                break
            slack = g_mat @ z + g_const
            # Active: within the step's own size of the boundary (scaled units).
            active = slack <= self.cfg.difference_step
            lhs = np.vstack([self.jacobian(z), g_mat[active]])
            rhs = np.r_[-residual, -slack[active]]
            trial = z + np.linalg.lstsq(lhs, rhs, rcond=None)[0]
            trial_residual = self.residuals(trial)
            if not np.linalg.norm(trial_residual) < np.linalg.norm(residual):
                break
            z, residual = trial, trial_residual
            steps += 1
        return z, steps

    def solve(self) -> FiniteBurnResult:
        """SLSQP from the converted burns, then the polish (module notes, steps 2-3)."""
        start_time = time.perf_counter()
        cfg = self.cfg
        self.deadline = Deadline(cfg.time_limit_s, "finite_burn.time_limit_s")
        z0 = self.pack(self.initial_burns, self.tof0)
        dr0, dv0, _ = self.errors(z0)
        g_mat, g_const = self.linear_inequalities()
        res = self._slsqp(z0, g_mat, g_const)
        z = np.asarray(res.x, dtype=float)
        message = str(res.message)
        iterations = int(res.nit)
        z, polished = self._polish(z, g_mat, g_const)
        iterations += polished
        flight, goal, _ = self._fly(z)
        dr, dv, rel = self.errors(z)
        limit = None
        if self.deadline.reached:
            limit = self.deadline.reason(iterations)
        elif res.status == _SLSQP_ITERATION_LIMIT:
            limit = f"finite_burn.max_iterations = {cfg.max_iterations} reached"
        converged = self._met(z) and limit is None
        if not converged:
            message = (
                (f"finite burns stopped: {limit}; " if limit else "")
                + f"finite burns miss the end condition by {dr:.3g} m"
                + (f", {dv:.3g} m/s" if dv is not None else "")
                + f" (SLSQP: {res.message})"
            )
        _, tof = self.unpack(z)
        return FiniteBurnResult(
            converged=converged,
            message=message if not converged else "",
            time_of_flight_s=tof,
            burns=flight.burns,
            final_state=flight.state,
            goal_state=goal,
            final_position_error_m=dr,
            final_velocity_error_mps=dv,
            relative_speed_mps=rel,
            initial_position_error_m=dr0,
            initial_velocity_error_mps=dv0,
            total_burn_time_s=float(sum(b.duration_s for b in flight.burns)),
            iterations=iterations,
            flights=self.flights,
            wall_time_s=time.perf_counter() - start_time,
        )

    def _objective_gradient(self) -> NDArray[np.float64]:
        """The (linear) objective's gradient: t_f for minimum time, else the total
        burning time."""
        if self.p.objective == "min_time":
            obj_grad = np.zeros(self.n_vars)
            obj_grad[self.tf_index] = 1.0
        else:
            obj_grad = np.zeros(self.n_vars)
            obj_grad[self.duration_index] = 1.0
        return obj_grad

    def _slsqp(
        self, z0: NDArray[np.float64], g_mat: NDArray[np.float64], g_const: NDArray[np.float64]
    ) -> OptimizeResult:
        """SLSQP on the end condition (equalities) and the linear inequalities, stopped at
        the deadline or once the objective has stalled (module notes, step 2)."""
        cfg = self.cfg
        obj_grad = self._objective_gradient()
        constraints = [
            {"type": "eq", "fun": self.residuals, "jac": self.jacobian},
            {
                "type": "ineq",
                "fun": lambda z: g_mat @ z + g_const,
                "jac": lambda z: g_mat,
            },
        ]
        history: list[tuple[float, float]] = []

        def stalled(z: NDArray[np.float64]) -> None:
            self.deadline.stop_if_expired()
            if cfg.stall_iterations <= 0:
                return
            # SLSQP reaches the optimal t_f within a few iterations and then creeps along
            # the constraints for many more; once the objective has stopped moving and the
            # end condition holds to a scaled unit, the Gauss-Newton polish finishes faster.
            history.append((float(obj_grad @ z), float(np.max(np.abs(self.residuals(z))))))
            recent = history[-cfg.stall_iterations - 1 :]
            if len(recent) > cfg.stall_iterations and recent[-1][1] <= 1.0:
                spread = max(h[0] for h in recent) - min(h[0] for h in recent)
                if spread * cfg.time_scale_s <= cfg.stall_tolerance_s:
                    raise StopIteration

        return minimize(
            lambda z: float(obj_grad @ z),
            z0,
            jac=lambda z: obj_grad,
            method="SLSQP",
            bounds=self.bounds(),
            constraints=constraints,
            options={"maxiter": cfg.max_iterations, "ftol": cfg.optimality_tolerance},
            callback=stalled,
        )
