"""Solve a deorbit burn: transfer orbit, impulsive start, iteration on u_open, final flight.

1. Entry requirements -> transfer orbit (seed sec. 1, :mod:`.requirements`); the single-burn
   condition (seed eqs. 4, 6) is checked on the mean elements: when the waiting orbit does not
   meet the transfer orbit the result says so (``converged=False``, ``reason``), nothing is
   raised.
2. Impulsive burn point, size and angle from the mean elements (seed sec. 2.1, eqs. 6-10,
   :mod:`.intersection`); the finite burn starts half a burn (rocket equation) before the
   impulsive point, which the seed recommends ("u_open at the centre of the burn arc"). A
   burn angle given by the caller or the config replaces eq. 10's; the start is then the
   two-body impulse at that angle that meets the entry fpa and u.
3. Iteration on u_open with the fpa cut-off (seed eq. 27, :mod:`.iteration`).
4. The final flight with the requested cut-off strategy from the converged u_open (for
   strategy 2 it is the last iteration itself).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ovtraj.astro.angles import wrap_to_pi
from ovtraj.astro.elements import NonsingularElements
from ovtraj.astro.j2_elements import osculating_to_mean
from ovtraj.deadline import Deadline
from ovtraj.studies.deorbit_burn.flight import FlightOutcome, FlightSimulator, initial_state
from ovtraj.studies.deorbit_burn.intersection import (
    ImpulsiveBurn,
    impulsive_burn,
    impulsive_burn_at_angle,
    in_plane_elements,
)
from ovtraj.studies.deorbit_burn.iteration import IterationOutcome, iterate_burn_start
from ovtraj.studies.deorbit_burn.powered import ThrustSettings
from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem
from ovtraj.studies.deorbit_burn.requirements import mean_transfer_orbit, transfer_orbit
from ovtraj.studies.deorbit_burn.result import DeorbitBurnResult

__all__ = ["BurnSolver", "solve_deorbit_burn"]


class BurnSolver:
    """What every solve of one problem shares: transfer orbit, impulsive burn, simulator."""

    def __init__(self, problem: DeorbitBurnProblem) -> None:
        self.problem = problem
        earth, entry = problem.earth, problem.entry
        self.simulator = FlightSimulator(problem)
        self.transfer = transfer_orbit(entry, earth.mu)
        self.waiting_mean = self.mean_elements(problem.waiting)
        self.transfer_mean = mean_transfer_orbit(
            self.transfer, entry, float(problem.waiting.i), float(problem.waiting.raan), earth
        )
        # Seed eqs. 6-10; None when the orbits do not meet (no single-burn solution).
        self.impulsive = impulsive_burn(
            in_plane_elements(self.waiting_mean),
            in_plane_elements(self.transfer_mean),
            entry.u_rad,
            earth.mu,
        )

    def mean_elements(self, waiting: NonsingularElements) -> NonsingularElements:
        """Mean elements of a waiting orbit given as the problem states it (mean or osculating)."""
        if self.problem.waiting_is_mean:
            return waiting
        earth = self.problem.earth
        return osculating_to_mean(waiting, mu=earth.mu, radius=earth.radius, j2=earth.j2)

    def mean_apoapsis(self) -> float:
        """Apoapsis radius [m] of the mean transfer orbit (the single-burn condition's)."""
        a, ex, ey = in_plane_elements(self.transfer_mean)
        return a * (1.0 + math.hypot(ex, ey))

    def single_burn_reason(self) -> str:
        a0, e0x, e0y = in_plane_elements(self.waiting_mean)
        e0 = math.hypot(e0x, e0y)
        radius = self.problem.earth.radius
        apo = self.mean_apoapsis()
        return (
            "no single-burn solution: the waiting orbit (mean radius "
            f"{a0 * (1 - e0) / 1e3:.1f}-{a0 * (1 + e0) / 1e3:.1f} km) does not meet the "
            f"transfer orbit the entry requires (mean apoapsis {apo / 1e3:.1f} km, altitude "
            f"{(apo - radius) / 1e3:.1f} km; seed eqs. 4 and 6)"
        )

    def nominal_thrust(self, burn_angle_rad: float) -> ThrustSettings:
        vehicle = self.problem.vehicle
        return ThrustSettings(
            thrust_n=vehicle.thrust_n,
            mass_flow_kg_s=vehicle.mass_flow(self.problem.earth.g0),
            burn_angle_rad=burn_angle_rad,
        )

    def burn_angle(self, burn_angle_deg: float | None = None) -> float | None:
        """The burn angle [rad]: the caller's, the config's, or eq. 10's (None if no solution)."""
        if burn_angle_deg is None:
            burn_angle_deg = self.problem.config.guidance.burn_angle_deg
        if burn_angle_deg is not None:
            return math.radians(burn_angle_deg)
        return None if self.impulsive is None else self.impulsive.burn_angle_rad

    def impulse_at(
        self, waiting: NonsingularElements, burn_angle_rad: float
    ) -> ImpulsiveBurn | None:
        """The impulsive burn at this angle: eq. 6-10's when the angle is eq. 10's."""
        nominal = waiting is self.waiting_mean
        if nominal and self.impulsive and burn_angle_rad == self.impulsive.burn_angle_rad:
            return self.impulsive
        return impulsive_burn_at_angle(
            in_plane_elements(waiting), burn_angle_rad, self.problem.entry, self.problem.earth.mu
        )

    def start_guess(self, impulse: ImpulsiveBurn, thrust: ThrustSettings, mass_kg: float) -> float:
        """u_open [rad] centring the finite burn on the impulsive point (seed sec. 2.1).

        Burn time from the rocket equation, t_b = m0 (1 - exp(-dv / (Isp g0))) / mdot, swept
        at the local angular rate v_t / r.
        """
        isp_g0 = thrust.thrust_n / thrust.mass_flow_kg_s
        burn_time = mass_kg * (1.0 - math.exp(-impulse.dv_mps / isp_g0)) / thrust.mass_flow_kg_s
        return impulse.u_rad - 0.5 * burn_time * impulse.v0t / impulse.radius_m

    def plan(
        self,
        state0: np.ndarray,
        u_open0: float,
        thrust: ThrustSettings,
        mass_kg: float,
        deadline: Deadline | None = None,
    ) -> IterationOutcome:
        guidance = self.problem.config.guidance
        return iterate_burn_start(
            self.simulator,
            state0,
            mass_kg,
            thrust,
            u_open0,
            gain=guidance.gain_ku,
            tolerance_rad=math.radians(guidance.u_tolerance_deg),
            max_iterations=guidance.max_iterations,
            deadline=deadline,
        )

    def solve(
        self, strategy: int | None = None, burn_angle_deg: float | None = None
    ) -> DeorbitBurnResult:
        """See :func:`solve_deorbit_burn`."""
        start = time.perf_counter()
        problem = self.problem
        deadline = Deadline(problem.config.guidance.time_limit_s, "guidance.time_limit_s")
        strategy = problem.config.guidance.strategy if strategy is None else int(strategy)
        if strategy not in (1, 2):
            raise ValueError(f"strategy must be 1 or 2, got {strategy}")
        if self.impulsive is None:
            return self._result(strategy, None, None, None, self.single_burn_reason(), start)
        theta = self.burn_angle(burn_angle_deg)
        assert theta is not None
        impulse = self.impulse_at(self.waiting_mean, theta)
        if impulse is None:
            reason = (
                f"no two-body impulse at burn angle {math.degrees(theta):g} deg meets the entry "
                "flight-path angle and argument of latitude"
            )
            return self._result(strategy, theta, None, None, reason, start)
        thrust = self.nominal_thrust(theta)
        mass = problem.vehicle.mass_kg
        state0 = initial_state(problem, problem.waiting)
        outcome = self.plan(state0, self.start_guess(impulse, thrust, mass), thrust, mass, deadline)
        flight = outcome.flight
        if outcome.converged and strategy != 2:
            flight = self.simulator.fly(state0, mass, flight.u_open_rad, thrust, strategy)
        reason = outcome.reason or flight.reason
        return self._result(strategy, theta, impulse, outcome, reason, start, flight)

    def _result(
        self,
        strategy: int,
        theta: float | None,
        impulse: ImpulsiveBurn | None,
        outcome: IterationOutcome | None,
        reason: str | None,
        start: float,
        flight: FlightOutcome | None = None,
    ) -> DeorbitBurnResult:
        problem = self.problem
        nan = math.nan
        f = flight
        r_e = problem.entry.radius_m

        def deg(x: float | None) -> float:
            return nan if x is None else math.degrees(x)

        transfer = self.transfer
        return DeorbitBurnResult(
            name=problem.name,
            strategy=strategy,
            converged=reason is None,
            reason=reason,
            single_burn_feasible=self.impulsive is not None,
            iterations=0 if outcome is None else outcome.iterations,
            u_open_deg=nan if f is None else math.degrees(f.u_open_rad) % 360.0,
            burn_duration_s=nan if f is None else f.burn_duration_s,
            dv_mps=nan if f is None else f.dv_mps,
            burn_angle_deg=deg(theta),
            entry_u_deg=nan if f is None else math.degrees(f.entry_u_rad) % 360.0,
            entry_fpa_deg=nan if f is None else math.degrees(f.entry_fpa_rad),
            entry_speed_mps=nan if f is None else f.entry_speed_mps,
            entry_u_error_deg=nan if f is None else math.degrees(f.u_error_rad),
            entry_fpa_error_deg=nan if f is None else math.degrees(f.fpa_error_rad),
            entry_speed_error_mps=nan if f is None else f.speed_error_mps,
            along_track_error_km=nan if f is None else f.u_error_rad * r_e / 1e3,
            prediction_u_error_deg=(
                nan if f is None else math.degrees(wrap_to_pi(f.predicted_u_rad - f.entry_u_rad))
            ),
            prediction_fpa_error_deg=(
                nan if f is None else math.degrees(f.predicted_fpa_rad - f.entry_fpa_rad)
            ),
            prediction_speed_error_mps=(
                nan if f is None else f.predicted_speed_mps - f.entry_speed_mps
            ),
            impulsive_u_deg=nan if impulse is None else math.degrees(impulse.u_rad) % 360.0,
            impulsive_dv_mps=nan if impulse is None else impulse.dv_mps,
            impulsive_burn_angle_deg=nan
            if impulse is None
            else math.degrees(impulse.burn_angle_rad),
            transfer_a_km=transfer.a / 1e3,
            transfer_e=transfer.e,
            transfer_argp_deg=math.degrees(transfer.argp) % 360.0,
            transfer_apoapsis_altitude_km=(transfer.apoapsis_radius - problem.earth.radius) / 1e3,
            transfer_mean_apoapsis_altitude_km=(self.mean_apoapsis() - problem.earth.radius) / 1e3,
            waiting_altitude_km=(float(self.waiting_mean.a) - problem.earth.radius) / 1e3,
            solve_time_s=time.perf_counter() - start,
            history=() if outcome is None else outcome.history,
        )


def solve_deorbit_burn(
    problem: DeorbitBurnProblem,
    *,
    strategy: int | None = None,
    burn_angle_deg: float | None = None,
) -> DeorbitBurnResult:
    """Solve the finite-thrust deorbit burn of ``problem`` (seed 004, see the module notes).

    ``strategy`` (1: cut-off on the predicted entry u, 2: on the predicted entry fpa) and
    ``burn_angle_deg`` [deg from -v, positive away from the Earth] default to the config
    (the config's ``null`` angle is seed eq. 10's). Never raises on a problem without a
    solution: ``converged`` is False and ``reason`` says why (no single-burn solution, no
    cut-off within the longest burn, no convergence within ``max_iterations``).
    """
    return BurnSolver(problem).solve(strategy=strategy, burn_angle_deg=burn_angle_deg)
