"""Impulse plans: decode decision vectors, fly them, measure the constraints; vectorised.

A whole population of decision vectors (:mod:`ovtraj.studies.maneuver.problem`) is evaluated at
once: every coast arc of every individual goes through one heyoka batch propagation
(two-body or J2, :meth:`OrbitPropagator.propagate_batch`), and every last leg through
one vectorised Lambert solve. Under J2 the Lambert arc (two-body) misses; its aim point
is moved by the miss and the arc solved again until the J2-propagated arc ends within
``lambert.j2_position_tolerance_m`` of the target (a fixed-point iteration that gains
about three digits per step at these distances).

Constraints (each a normalised value, <= 0 when met):

* ``dv``: ``(sum |dv_i| - dv_limit) / dv_limit`` (seed eq. 4; the limit is eq. 14 or
  the rocket equation, as configured);
* ``burn_time``: ``(sum dt_i - t_e) / t_e`` with ``dt_i`` from eq. 15, each from the
  mass the previous impulses left (seed eq. 13), when configured;
* ``perigee``: ``(r_min_allowed - r_min) / r_min_allowed`` with ``r_min`` the lowest
  radius of the coast arcs (two-body: the periapsis when the arc passes it);
* ``failure``: a large value where an arc could not be solved (no Lambert solution, a
  J2 aim point that does not converge, a propagation error).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.angles import TWO_PI, wrap_to_two_pi
from ovtraj.astro.elements import mean_motion, perigee_radius_from_semi_latus_rectum
from ovtraj.astro.frames import rsw_to_eci
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.astro.rocket import burn_durations
from ovtraj.astro.vectors import cross
from ovtraj.studies.maneuver.endpoint import orbit_point_at_latitude
from ovtraj.studies.maneuver.lambert import lambert
from ovtraj.studies.maneuver.problem import ManeuverProblem

__all__ = ["CONSTRAINT_NAMES", "ImpulsiveModel", "PlanBatch"]

CONSTRAINT_NAMES = ("dv", "burn_time", "perigee", "failure")
# Violation of an individual whose trajectory could not be computed: worse than any
# finite violation of the other constraints, so the feasibility rules rank it last.
_FAILURE = 1.0e3


@dataclass(frozen=True)
class PlanBatch:
    """Evaluated impulse plans (S individuals); SI units, ECI axes, t in s from t = 0."""

    x: NDArray[np.float64]  # (S, d) decision vectors
    time_of_flight: NDArray[np.float64]  # (S,)
    epochs: NDArray[np.float64]  # (S, n)
    dv: NDArray[np.float64]  # (S, n, 3) ECI impulses
    total_dv: NDArray[np.float64]  # (S,)
    burn_time: NDArray[np.float64]  # (S,) eq. 15 durations, summed
    min_radius: NDArray[np.float64]  # (S,)
    constraints: NDArray[np.float64]  # (S, 4) normalised, <= 0 when met
    objective: NDArray[np.float64]  # (S,) inf where the plan failed
    ok: NDArray[np.bool_]  # (S,) the trajectory could be computed
    arrival: NDArray[np.float64]  # (S, 6) stage at t_f before a final impulse
    goal: NDArray[np.float64]  # (S, 6) the target (or target-orbit point) at t_f

    @property
    def violation(self) -> NDArray[np.float64]:
        """Sum of the positive parts of the constraints (0 for a feasible plan)."""
        return np.sum(np.maximum(self.constraints, 0.0), axis=1)


def _periapsis_if_passed(
    state: NDArray[np.float64], duration: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """Periapsis radius [m] of two-body arcs that pass periapsis, +inf for the others.

    ``state`` (S, 6) starts each arc, ``duration`` (S,) [s] its length. An elliptic arc
    passes periapsis when its mean anomaly, taken in [0, 2 pi), crosses 2 pi; a
    hyperbolic one when its mean anomaly crosses 0. Anomalies from r and r.v:
    e cos E = 1 - r / a, e sin E = r.v / sqrt(mu a); e sinh H = r.v / sqrt(-mu a)
    (Vallado, 4th ed., sec. 2.2-2.3).
    """
    r_vec, v_vec = state[:, :3], state[:, 3:]
    r = np.linalg.norm(r_vec, axis=1)
    rv = np.einsum("ij,ij->i", r_vec, v_vec)
    energy = 0.5 * np.einsum("ij,ij->i", v_vec, v_vec) - mu / r
    a = -mu / (2.0 * energy)
    h = np.linalg.norm(cross(r_vec, v_vec), axis=1)
    p = h * h / mu
    e = np.sqrt(np.maximum(0.0, 1.0 - p / a))
    periapsis = perigee_radius_from_semi_latus_rectum(p, e)
    a_abs = np.abs(a)
    n = mean_motion(a, mu=mu)
    elliptic = a > 0.0
    root = rv / np.sqrt(mu * a_abs)
    big_e = np.arctan2(root, 1.0 - r / a)
    m_ell = wrap_to_two_pi(big_e - root)
    big_h = np.arcsinh(root / np.maximum(e, 1e-300))
    m_hyp = root - big_h
    m_end = np.where(elliptic, m_ell, m_hyp) + n * duration
    passes = np.where(elliptic, m_end >= TWO_PI, (m_hyp < 0.0) & (m_end > 0.0))
    return np.where(passes, periapsis, np.inf)


class ImpulsiveModel:
    """Evaluates impulse plans of one problem; built once, reused for every generation."""

    def __init__(self, problem: ManeuverProblem) -> None:
        self.p = problem
        self.mu = problem.earth.mu
        self.propagator = OrbitPropagator(problem.earth, tol=problem.integrator_tol, j2=problem.j2)
        t_max = problem.tof_bounds_s[1]
        self.target_coast = self.propagator.propagate(problem.target_state, 0.0, t_max, dense=True)
        if not self.target_coast.ok:
            raise RuntimeError(f"target propagation failed: {self.target_coast.message}")
        self.evaluations = 0

    # ------------------------------------------------------------------ helpers
    def goal_states(self, tof: NDArray[np.float64], u_f: NDArray[np.float64] | None) -> NDArray:
        """The target at ``tof`` (S, 6) or, for a transfer, its orbit's point at ``u_f``."""
        target = np.atleast_2d(self.target_coast.dense(tof))
        if u_f is None:
            return target
        return orbit_point_at_latitude(target, u_f, self.mu)

    def _coast(
        self, states: NDArray[np.float64], t0: NDArray[np.float64], t1: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Propagate the finite rows; rows already NaN stay NaN."""
        out = np.full_like(states, np.nan)
        rows = np.all(np.isfinite(states), axis=1)
        if np.any(rows):
            out[rows] = self.propagator.propagate_batch(states[rows], t0[rows], t1[rows])
        return out

    def _arc_min_radius(
        self, start: NDArray[np.float64], end: NDArray[np.float64], duration: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        with np.errstate(invalid="ignore", divide="ignore"):
            low = _periapsis_if_passed(start, duration, self.mu)
        ends = np.minimum(np.linalg.norm(start[:, :3], axis=1), np.linalg.norm(end[:, :3], axis=1))
        return np.where(np.isfinite(ends), np.minimum(low, ends), np.nan)

    def _last_leg(
        self,
        depart: NDArray[np.float64],
        t_dep: NDArray[np.float64],
        tof: NDArray[np.float64],
        goal_r: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """Departure velocity and arrival state of the exact last leg; rows that failed."""
        p = self.p
        dt = tof - t_dep
        h_ref = cross(depart[:, :3], depart[:, 3:])
        aim = goal_r.copy()
        sol = lambert(
            depart[:, :3], aim, dt, mu=self.mu, h_ref=h_ref, rtol=p.lambert.time_tolerance
        )
        if not p.j2:
            arrival = np.hstack([goal_r, sol.v2])
            return sol.v1, arrival, sol.ok
        ok = sol.ok
        v1 = sol.v1
        arrival = np.full((len(tof), 6), np.nan)
        for _ in range(p.lambert.j2_iterations):
            arrival = self._coast(np.hstack([depart[:, :3], v1]), t_dep, tof)
            miss = goal_r - arrival[:, :3]
            miss_norm = np.linalg.norm(miss, axis=1)
            if not np.any(ok & ~(miss_norm <= p.lambert.j2_position_tolerance_m)):
                break
            aim = aim + np.nan_to_num(miss)
            sol = lambert(
                depart[:, :3], aim, dt, mu=self.mu, h_ref=h_ref, rtol=p.lambert.time_tolerance
            )
            ok = ok & sol.ok
            v1 = sol.v1
        else:
            arrival = self._coast(np.hstack([depart[:, :3], v1]), t_dep, tof)
        miss_norm = np.linalg.norm(goal_r - arrival[:, :3], axis=1)
        ok = ok & (miss_norm <= p.lambert.j2_position_tolerance_m)
        return v1, arrival, ok

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, x: NDArray[np.float64]) -> PlanBatch:
        """Fly the plans of the rows of ``x`` (S, d); see the module notes."""
        p = self.p
        x = np.atleast_2d(np.asarray(x, dtype=float))
        s = len(x)
        self.evaluations += s
        m, n = p.n_free_impulses, p.n_impulses
        tof = x[:, p.tof_index]
        u_f = x[:, -1] if p.has_final_latitude else None
        epochs = self._epochs(x, tof)
        dv = np.zeros((s, n, 3))
        state, min_radius = self._free_impulses(x, epochs, dv)
        t_dep = epochs[:, m]
        goal = self.goal_states(tof, u_f)
        v1, arrival, ok = self._last_leg(state, t_dep, tof, goal[:, :3])
        dv[:, m] = v1 - state[:, 3:]
        leg_start = np.hstack([state[:, :3], v1])
        min_radius = np.fmin(min_radius, self._arc_min_radius(leg_start, arrival, tof - t_dep))
        if p.end_condition != "interception":
            dv[:, n - 1] = goal[:, 3:] - arrival[:, 3:]

        ok = ok & np.all(np.isfinite(dv), axis=(1, 2)) & np.isfinite(min_radius)
        dv = np.where(ok[:, None, None], dv, np.nan)
        norms = np.linalg.norm(dv, axis=2)
        total = np.sum(norms, axis=1)
        durations, _ = burn_durations(norms, p.initial_mass_kg, p.thrust_n, p.isp_n_s_kg)
        burn_time = np.sum(durations, axis=1)
        constraints = self._constraints(total, burn_time, min_radius, ok)
        if p.objective == "min_time":
            objective = tof.copy()
        else:
            objective = total.copy()
        objective[~ok] = np.inf
        return PlanBatch(
            x=x,
            time_of_flight=tof,
            epochs=epochs,
            dv=dv,
            total_dv=total,
            burn_time=burn_time,
            min_radius=min_radius,
            constraints=constraints,
            objective=objective,
            ok=ok,
            arrival=arrival,
            goal=goal,
        )

    def _epochs(self, x: NDArray[np.float64], tof: NDArray[np.float64]) -> NDArray[np.float64]:
        """(S, n) impulse epochs: the first at 0, the middle ones at their (sorted)
        fractions of the time of flight, the last at t_f unless the end is an
        interception."""
        p = self.p
        k, n = p.n_fractions, p.n_impulses
        m = p.n_free_impulses
        fractions = np.sort(x[:, 3 * m : 3 * m + k], axis=1)
        epochs = np.zeros((len(x), n))
        epochs[:, 1 : 1 + k] = fractions * tof[:, None]
        if p.end_condition != "interception":
            epochs[:, n - 1] = tof
        return epochs

    def _free_impulses(
        self, x: NDArray[np.float64], epochs: NDArray[np.float64], dv: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Fly the free impulses (written into ``dv``) and the coasts between them up to
        the departure of the last leg (impulse m, the (m+1)-th): the state there and the
        lowest radius so far."""
        p = self.p
        s, m = len(x), p.n_free_impulses
        free = x[:, : 3 * m].reshape(s, m, 3)
        state = np.tile(p.chaser_state, (s, 1))
        min_radius = np.linalg.norm(state[:, :3], axis=1)
        for j in range(m):
            if j > 0:
                start = state
                state = self._coast(start, epochs[:, j - 1], epochs[:, j])
                duration = epochs[:, j] - epochs[:, j - 1]
                min_radius = np.fmin(min_radius, self._arc_min_radius(start, state, duration))
            impulse = free[:, j]
            if p.impulse_frame == "rsw":
                impulse = rsw_to_eci(impulse, state[:, :3], state[:, 3:])
            dv[:, j] = impulse
            state = state.copy()
            state[:, 3:] += impulse
        if m > 0:
            start = state
            state = self._coast(start, epochs[:, m - 1], epochs[:, m])
            duration = epochs[:, m] - epochs[:, m - 1]
            min_radius = np.fmin(min_radius, self._arc_min_radius(start, state, duration))
        return state, min_radius

    def _constraints(
        self,
        total: NDArray[np.float64],
        burn_time: NDArray[np.float64],
        min_radius: NDArray[np.float64],
        ok: NDArray[np.bool_],
    ) -> NDArray[np.float64]:
        """(S, 4) normalised constraints of :data:`CONSTRAINT_NAMES` (module notes)."""
        p = self.p
        constraints = np.zeros((len(total), len(CONSTRAINT_NAMES)))
        constraints[:, 0] = (total - p.dv_limit_mps) / p.dv_limit_mps
        if p.burn_time_limit:
            constraints[:, 1] = (burn_time - p.max_burn_time_s) / p.max_burn_time_s
        else:
            constraints[:, 1] = -1.0
        constraints[:, 2] = (p.min_radius_m - min_radius) / p.min_radius_m
        constraints[:, 3] = -1.0
        constraints[~ok] = [-1.0, -1.0, -1.0, _FAILURE]
        return constraints
