"""One dispersed run of a plan flown twice, on the same draw (common random numbers).

**Open loop** (:func:`fly_open_loop`): the plan as stored, through the replay of
:func:`ovtraj.mission.fly.fly_plan` with the errors applied
(:class:`~ovtraj.mission.montecarlo_draw.DispersedFlight`): the ascent with the dispersed
launcher and release, each planned impulse executed with its errors at its planned epoch,
the entry with the planned bank profile in the dispersed atmosphere.

**Closed loop** (:func:`fly_closed_loop`): the corrections a real mission makes, each
by the stage's own method from the on-board estimate (:mod:`.montecarlo_guidance`):

1. the ascent as above (the programme is open loop in this model: no launch guidance);
2. rendezvous re-targeting: the rendezvous stage solved again from the estimated
   insertion state; its first impulse executed with errors; the mid-course corrections;
   the second re-computed at its epoch to match the target's velocity from the estimate,
   executed with errors; docking when the arrival miss is within
   ``closed_loop.docking_capture_m`` (the proximity operations close it; the docked OV
   then moves with the target), a failure otherwise, and also when the arrival comes
   after the planned separation;
3. the transfer solved again at the planned separation from the estimate, executed
   with errors;
4. the deorbit solved again from the estimate at the end of the transfer, the burn cut
   off on line by the entry prediction;
5. the reentry guidance re-solved in flight.

Either ends with a :class:`~ovtraj.mission.montecarlo_outcome.RunOutcome`; nothing
raises out of a run.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.elements import orbital_period
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.deorbit import deorbit_input, solve_deorbit
from ovtraj.mission.chain import rendezvous_settings
from ovtraj.mission.flight_report import FlightReport, ReplayFailed
from ovtraj.mission.fly import fly_plan
from ovtraj.mission.high_fidelity import (
    HighFidelityOrbit,
    TargetTrack,
    Truth,
    spacecraft_factors,
    target_sky,
)
from ovtraj.mission.montecarlo_draw import DispersedFlight, RunDraw, pointed
from ovtraj.mission.montecarlo_guidance import cut_off, guided_entry, reaching_velocity
from ovtraj.mission.montecarlo_outcome import (
    CORRECTIONS,
    IMPULSES,
    PATH_LIMITS,
    RunOutcome,
    StageFailed,
)
from ovtraj.mission.plan import MissionPlan
from ovtraj.mission.replay_ascent import fly_ascent
from ovtraj.mission.replay_entry import relative_entry
from ovtraj.mission.replay_orbit import ReplayOrbit
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads
from ovtraj.rendezvous.result import RendezvousInput, TransferInput
from ovtraj.rendezvous.stage import circular_transfer, solve_rendezvous
from ovtraj.target_state import target_state
from ovtraj.units import S_PER_HOUR

__all__ = ["fly_closed_loop", "fly_open_loop", "sky"]


def fly_open_loop(plan: MissionPlan, draw: RunDraw) -> RunOutcome:
    """The plan flown as stored with the draw's errors (the replay, no correction)."""
    flight = DispersedFlight(draw)
    with blas_threads(EVALUATION_BLAS_THREADS):
        report: FlightReport = fly_plan(plan, perturbation=flight)
    maxima = {
        name: float(report.checks[name].value)
        for name in PATH_LIMITS
        if name in report.checks and report.checks[name].value is not None
    }
    outcome = RunOutcome(
        run=draw.run,
        loop="open",
        landed=bool(report.ok),
        failed_stage=None if report.ok else "replay",
        reason=report.reason,
        landing_miss_m=report.miss_distance_m,
        maxima=maxima,
        arrival_miss_m=report.rendezvous_arrival_miss_m,
    )
    if report.terminal is not None:
        outcome.landing_latitude_deg = report.terminal["latitude_deg"]
        outcome.landing_longitude_deg = report.terminal["longitude_deg"]
    # The replay executes the k-th planned impulse as flight.burn(k, planned) once it has
    # reported it; no correction between the rendezvous burns.
    for k, planned in enumerate(plan.impulses()[: len(report.burns)]):
        if IMPULSES[k] == "rendezvous burn 2":
            outcome.spend(CORRECTIONS)
        outcome.spend(IMPULSES[k], flight.burn(k, planned.eci))
    return outcome


def fly_closed_loop(
    plan: MissionPlan,
    draw: RunDraw,
    config: DispersionsConfig,
    scenario: Scenario | None = None,
    force_model: ForceModelSettings | None = None,
) -> RunOutcome:
    """The draw flown with the mission's corrections (module notes). Never raises.

    With ``force_model`` the orbits (the vehicle's and the target's) are flown under the
    high-fidelity model (:mod:`ovtraj.mission.high_fidelity`); the corrections still solve
    the chain's J2 problems, as an on-board planner would.

    On one BLAS thread, as every stored evaluation (:data:`EVALUATION_BLAS_THREADS`): the
    closed loop amplifies the last digits of a multi-threaded sum to millimetres at
    landing, and a run must land in the same place in any process and runner."""
    outcome = RunOutcome(run=draw.run, loop="closed", landed=False)
    scenario = scenario or scenario_from_dict(plan.scenario, "the plan's scenario")
    truth = sky(plan, scenario, force_model)  # a missing body is the caller's ConfigError
    try:
        with (
            np.errstate(all="ignore"),
            blas_threads(EVALUATION_BLAS_THREADS),
        ):
            _ClosedLoop(plan, scenario, draw, config, outcome, truth).fly()
        outcome.landed = True
    except StageFailed as failure:
        outcome.failed_stage, outcome.reason = failure.stage, failure.reason
    except ReplayFailed as failure:
        outcome.failed_stage, outcome.reason = "flight", str(failure)
    except (ArithmeticError, ValueError) as err:
        outcome.failed_stage = "flight"
        outcome.reason = f"numerical failure: {type(err).__name__}: {err}"
    return outcome


class _ClosedLoop:
    """One closed-loop flight: the true state [m, m/s] and time [s from the plan's day]
    carried from stage to stage, each stage's failure a :class:`StageFailed`."""

    def __init__(
        self,
        plan: MissionPlan,
        scenario: Scenario,
        draw: RunDraw,
        config: DispersionsConfig,
        outcome: RunOutcome,
        truth: Truth,
    ) -> None:
        self.plan, self.scenario, self.draw, self.config = plan, scenario, draw, config
        self.outcome, self.truth, self.orbit = outcome, truth, truth.vehicle
        self.propagator = OrbitPropagator(scenario.earth, tol=scenario.tolerances.integrator)
        self.flight = DispersedFlight(draw)
        self.entry_altitude_m = scenario.deorbit.entry.altitude_km * 1e3
        self.common = rendezvous_settings(scenario)
        self.state: NDArray[np.float64] = np.zeros(6)
        self.t = 0.0

    def fly(self) -> None:
        """The stages in order (module notes)."""
        scratch = FlightReport(
            ok=False, reason=None, landed_within_stated_miss=False, stated_miss_m=0
        )
        self.state, self.t = fly_ascent(self.plan, self.scenario, scratch, self.flight)
        self.rendezvous(self.retarget())
        self.transfer()
        rel, t_entry = self.deorbit()
        day = self.plan.day
        guided_entry(
            self.scenario, day.plus_seconds(t_entry), rel, self.flight, self.config, self.outcome
        )

    def estimate(self, point: str, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """The on-board estimate of ``state`` at a navigation point (the draw's error)."""
        return state + self.draw.navigation[point]

    def coast_to(self, t1: float, stage: str) -> None:
        """Coast the true state to ``t1``; falling through the entry interface fails
        ``stage``."""
        end, t_end, entered, _ = self.orbit.arc(
            self.state, self.t, t1, floor_m=self.entry_altitude_m
        )
        if entered:
            raise StageFailed(stage, f"the OV falls through the entry interface at {t_end:.0f} s")
        self.state, self.t = end, t1

    def burn(self, manoeuvre: str, dv: NDArray[np.float64]) -> None:
        """The executed impulse ``dv`` [m/s] added to the true velocity and spent."""
        self.state = self.state + np.r_[0.0, 0.0, 0.0, dv]
        self.outcome.spend(manoeuvre, dv)

    def solve_rendezvous(self, estimate: NDArray[np.float64]) -> Any:
        """The rendezvous stage solved now from ``estimate`` (the chaser's state)."""
        return solve_rendezvous(
            RendezvousInput(
                epoch=self.plan.day,
                t0_s=self.t,
                chaser_state=estimate,
                target_state=self.truth.target_at(self.t),
                **self.common,
            )
        )

    def retarget(self) -> Any:
        """The rendezvous re-targeted from the estimated insertion; under a sky that is
        not the planner's J2 the phasing drifts (drag, the field's higher terms), so it is
        solved again from the estimate every ``retarget_interval_s`` while the OV waits."""
        rdv = self.solve_rendezvous(self.estimate("rendezvous", self.state))
        if not rdv.feasible:
            raise StageFailed("rendezvous", f"re-targeting failed: {rdv.reason}")
        interval = self.truth.retarget_interval_s
        if interval is None:
            return rdv
        k = 0
        while rdv.burn1.t_s - self.t > interval:
            t_fix = self.t + interval
            t_sep = self.plan.stay.separation_t_s
            if t_fix > t_sep:
                # A re-solve may put the burn later each time: the stay bounds the loop.
                raise StageFailed(
                    "rendezvous", f"still phasing at the planned separation {t_sep:.0f} s"
                )
            self.coast_to(t_fix, "rendezvous")
            rdv = self.solve_rendezvous(self.state + self.draw.retarget_navigation(k))
            if not rdv.feasible:
                raise StageFailed(
                    "rendezvous", f"re-targeting at {self.t:.0f} s failed: {rdv.reason}"
                )
            k += 1
        return rdv

    def rendezvous(self, rdv: Any) -> None:
        """The first impulse executed with errors, the mid-course corrections, the second
        re-computed at its epoch to match the target's velocity as the chaser estimates its
        own, executed with errors; then docked (:meth:`dock`)."""
        self.coast_to(rdv.burn1.t_s, "rendezvous")
        self.burn("rendezvous burn 1", self.flight.burn(0, np.asarray(rdv.burn1.eci_mps)))
        t_arrival = rdv.burn2.t_s
        target = self.truth.target_at(t_arrival)
        self.correct(t_arrival, target[:3])
        self.coast_to(t_arrival, "rendezvous")
        matched = target[3:] - self.estimate("arrival", self.state)[3:]
        self.burn("rendezvous burn 2", self.flight.burn(1, matched))
        self.dock(t_arrival, target)

    def correct(self, t_arrival: float, target_position: NDArray[np.float64]) -> None:
        """The mid-course corrections (``closed_loop.rendezvous_corrections``: fractions of
        the coast from the first impulse to the arrival): from the estimate, the velocity
        that reaches the target's arrival position (differential correction under J2),
        executed with errors."""
        draw, settings = self.draw, self.config.closed_loop
        t_burn1 = self.t
        corrections = []
        for k, fraction in enumerate(settings.rendezvous_corrections):
            self.coast_to(t_burn1 + fraction * (t_arrival - t_burn1), "rendezvous")
            estimated = self.state + draw.correction_navigation[k]
            wanted = reaching_velocity(
                self.propagator, estimated, self.t, t_arrival, target_position, settings
            )
            dv = draw.correction_scale[k] * pointed(
                wanted - estimated[3:], draw.correction_pointing_rad[k]
            )
            self.state = self.state + np.r_[0.0, 0.0, 0.0, dv]
            corrections.append(dv)
        self.outcome.spend(CORRECTIONS, *corrections)

    def dock(self, t_arrival: float, target: NDArray[np.float64]) -> None:
        """Docked when the arrival miss is within the capture distance and the arrival
        before the planned separation; the OV then moves with the target until it."""
        outcome = self.outcome
        outcome.arrival_miss_m = float(np.linalg.norm(self.state[:3] - target[:3]))
        capture = self.config.closed_loop.docking_capture_m
        if outcome.arrival_miss_m > capture:
            raise StageFailed(
                "rendezvous",
                f"arrives {outcome.arrival_miss_m:.0f} m from the target (capture {capture:g} m)",
            )
        t_sep = self.plan.stay.separation_t_s
        if t_arrival > t_sep:
            raise StageFailed(
                "rendezvous",
                f"docks at {t_arrival:.0f} s, after the planned separation {t_sep:.0f} s",
            )
        self.state, self.t = self.truth.target_at(t_sep), t_sep

    def transfer(self) -> None:
        """The transfer solved again from the estimate at separation, its two impulses
        executed with errors, coasted to the preparation orbit's arrival."""
        t = self.t
        transfer = circular_transfer(
            TransferInput(
                epoch=self.plan.day,
                t0_s=t,
                chaser_state=self.estimate("transfer", self.state),
                target_altitude_m=self.plan.transfer.preparation_altitude_m,
                burn_time_s=t,
                **self.common,
            )
        )
        if not transfer.feasible:
            raise StageFailed("transfer", f"re-solving failed: {transfer.reason}")
        for k, burn in ((2, transfer.burn1), (3, transfer.burn2)):
            self.coast_to(burn.t_s, "transfer")
            self.burn(IMPULSES[k], self.flight.burn(k, np.asarray(burn.eci_mps)))
        self.coast_to(transfer.arrival_time_s, "transfer")

    def deorbit(self) -> tuple[dict[str, float], float]:
        """The deorbit solved again from the estimate, the burn cut off by the entry
        prediction, the descent to the entry interface: the state there relative to the
        rotating Earth (:func:`~ovtraj.mission.replay_entry.relative_entry`) and its time [s]."""
        scenario, earth = self.scenario, self.scenario.earth
        deorbit = solve_deorbit(
            deorbit_input(
                scenario,
                state0=self.estimate("deorbit", self.state),
                epoch=self.plan.day.plus_seconds(self.t),
            )
        )
        if not deorbit.feasible:
            raise StageFailed("deorbit", f"re-solving failed: {deorbit.reason}")
        self.coast_to(self.t + deorbit.burn_t_s, "deorbit")
        nominal = np.asarray(deorbit.dv_eci_mps, dtype=float)
        executed = self.flight.burn(4, np.asarray(deorbit.dv_eci_mps, dtype=float))
        dv = cut_off(self.estimate("deorbit", self.state), nominal, executed, scenario, self.config)
        self.burn("deorbit burn", dv)
        r0 = float(np.linalg.norm(self.state[:3]))
        horizon = scenario.deorbit.max_descent_revolutions * float(orbital_period(r0, mu=earth.mu))
        state, t_entry, entered, _ = self.orbit.arc(
            self.state, self.t, self.t + horizon, floor_m=self.entry_altitude_m
        )
        if not entered:
            raise StageFailed("deorbit", "the descent does not reach the entry interface")
        theta = self.plan.day.gmst_rad() + earth.omega * t_entry
        return relative_entry(state, theta, earth.omega, earth.radius), t_entry


def sky(plan: MissionPlan, scenario: Scenario, force_model: ForceModelSettings | None) -> Truth:
    """The orbits a closed-loop flight meets: the replay's J2 (``force_model`` None) or the
    high-fidelity model, the vehicle's arcs timed from the plan's day and the target's
    state at any such time."""
    offset = plan.day.seconds_since(scenario.epoch)
    target0 = target_state(scenario.target.orbit, scenario)
    if force_model is None:
        orbit = ReplayOrbit(scenario)
        return Truth(
            vehicle=orbit,
            target_at=lambda time_s: orbit.arc(target0, 0.0, time_s + offset)[0],
            fidelity="j2",
            retarget_interval_s=None,
        )
    vehicle = HighFidelityOrbit(
        scenario, force_model, plan.day, spacecraft_factors(scenario, "vehicle")
    )
    target, target0 = target_sky(scenario, force_model, target0)
    return Truth(
        vehicle=vehicle,
        target_at=TargetTrack(target, target0, offset),
        fidelity="high",
        retarget_interval_s=force_model.closed_loop.phasing_retarget_interval_h * S_PER_HOUR,
    )
