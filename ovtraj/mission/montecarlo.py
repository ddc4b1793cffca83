"""Dispersed Monte Carlo of a mission plan, closed loop and open loop (issue 23).

Each run draws its errors from its own generator (``numpy.random.default_rng([seed, run])``,
so a run does not depend on how runs are batched), 1-sigma normal, from
``configs/dispersions.yaml``:

* the carrier's release (position, altitude, Mach, path angle) and each solid stage's
  delivered thrust and specific impulse (the mass flow follows: ``F / (Isp g0)``);
* the on-board state estimate before the rendezvous, the transfer and the deorbit burn
  (position and velocity, per axis);
* each impulse's execution (magnitude and two transverse pointing angles);
* the atmosphere's density and the vehicle's lift and drag (one factor each per run).

The same draw is flown twice (common random numbers):

**Open loop** (:func:`fly_open_loop`): the plan as stored, through the replay of
:mod:`ovtraj.mission.fly` with the errors applied (:class:`DispersedFlight`): the ascent
with the dispersed launcher and release, each planned impulse executed with its errors at
its planned epoch, the entry with the planned bank profile in the dispersed atmosphere.

**Closed loop** (:func:`fly_closed_loop`): the corrections a real mission makes, each
by the stage's own method from the on-board estimate:

1. the ascent as above (the programme is open loop in this model: no launch guidance);
2. rendezvous re-targeting: the rendezvous stage solved again from the estimated
   insertion state; its first impulse executed with errors; the second re-computed at
   its epoch to match the target's velocity from the estimate, executed with errors;
   docking when the arrival miss is within ``closed_loop.docking_capture_m`` (the
   proximity operations close it; the docked OV then moves with the target), a failure
   otherwise, and also when the arrival comes after the planned separation;
3. the transfer solved again at the planned separation from the estimate, executed
   with errors;
4. the deorbit solved again from the estimate at the end of the transfer; the burn is
   cut off on-line by the osculating-element entry prediction of seed 004
   (:func:`ovtraj.astro.entry_prediction.predict_entry`, strategy 1): along the
   actually pointed direction, the engine stops when the predicted entry argument of
   latitude reaches the one the nominal burn predicts from the same estimate, which
   absorbs the magnitude error;
5. the reentry guidance re-solved in flight every ``closed_loop.guidance_interval_s``
   from the current state (:func:`ovtraj.reentry.solve_reentry`, the nominal model),
   the truth flown between solves in the dispersed atmosphere with the guidance's
   heading-corridor reversals.

Every run ends with its landing point (geocentric latitude and longitude at the terminal
interface, on the spherical Earth the miss is measured on) and miss, whether it reached the
terminal speed, and the path maxima, reported against the limits as margins (limit minus
maximum). Nothing raises out of a run: a stage that fails ends it with the stage and the
reason.

Every run also records the dV it spent (:data:`MANOEUVRES`): the magnitude of each
impulse as executed, after its errors (the deorbit burn as cut off on line), under the
plan's name of the manoeuvre; the closed loop's mid-course corrections, which the plan
does not hold, as ``rendezvous corrections`` (their sum; the open loop flies none: 0). A
manoeuvre the run did not reach has no value, nor has the total.
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
from numpy.typing import NDArray
from scipy.optimize import brentq

from ovtraj.astro.angles import TWO_PI, wrap_to_pi
from ovtraj.astro.constants import EarthConstants
from ovtraj.astro.entry_prediction import predict_entry
from ovtraj.astro.frames import great_circle_distance
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.deorbit import deorbit_input, solve_deorbit
from ovtraj.environment import require_pinned_kernel
from ovtraj.launch.inputs import LaunchInput
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
from ovtraj.mission.perturbation import Perturbation
from ovtraj.mission.plan import MissionPlan
from ovtraj.mission.replay_ascent import fly_ascent
from ovtraj.mission.replay_entry import relative_entry
from ovtraj.mission.replay_orbit import ReplayOrbit
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads
from ovtraj.reentry import EntryState, reentry_input, solve_reentry
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry.model import EntryModel
from ovtraj.rendezvous.result import RendezvousInput, TransferInput
from ovtraj.rendezvous.stage import circular_transfer, solve_rendezvous
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, record_schema
from ovtraj.target_state import target_state

logger = logging.getLogger(__name__)

__all__ = [
    "MANOEUVRES",
    "RUN_SCHEMA",
    "STORED_RUN_SCHEMA",
    "DispersedFlight",
    "RunDraw",
    "RunOutcome",
    "draw_run",
    "dv_statistics",
    "fly_closed_loop",
    "fly_open_loop",
    "loop_summaries",
    "monte_carlo",
    "monte_carlo_report",
    "outcome_summaries",
    "outcomes_of",
    "path_limits",
    "planned_dv",
    "simulate_batch",
    "summarise",
]

# Where the on-board estimate is drawn: before each corrected phase.
NAVIGATION_POINTS = ("rendezvous", "arrival", "transfer", "deorbit")
PATH_LIMITS = ("max_heat_rate_w_m2", "max_load_g", "max_dynamic_pressure_pa")
# Every manoeuvre whose dV a run records, in time order, and its stored column: the plan's
# impulses under the plan's names, and the closed loop's mid-course corrections (not planned).
CORRECTIONS = "rendezvous corrections"
MANOEUVRES = {
    "rendezvous burn 1": "dv_rendezvous_1_mps",
    CORRECTIONS: "dv_rendezvous_corrections_mps",
    "rendezvous burn 2": "dv_rendezvous_2_mps",
    "transfer burn 1": "dv_transfer_1_mps",
    "transfer burn 2": "dv_transfer_2_mps",
    "deorbit burn": "dv_deorbit_mps",
}
# The plan's impulses in the order of MissionPlan.impulses() (the index of Perturbation.burn).
IMPULSES = tuple(name for name in MANOEUVRES if name != CORRECTIONS)

RUN_SCHEMA = record_schema(
    [
        ("run", INT),
        ("loop", TEXT),
        ("landed", BOOL),
        ("failed_stage", TEXT),
        ("reason", TEXT),
        ("landing_miss_m", FLOAT),
        ("landing_latitude_deg", FLOAT),
        ("landing_longitude_deg", FLOAT),
        ("arrival_miss_m", FLOAT),
        *[(column, FLOAT) for column in MANOEUVRES.values()],
        ("dv_total_mps", FLOAT),
        *[(name, FLOAT) for name in PATH_LIMITS],
        ("wall_time_s", FLOAT),
    ],
    required=("run", "loop", "landed"),
)
"""One flown run of one loop (``closed``/``open``); ``wall_time_s`` is timing only. The
``dv_*_mps`` columns: the dV each manoeuvre spent (:data:`MANOEUVRES`) and their sum, null
for a manoeuvre the run did not reach (and then for the total)."""
STORED_RUN_SCHEMA = pa.schema([f for f in RUN_SCHEMA if f.name != "wall_time_s"])
"""The stored rows (the wall times go to the batch markers)."""


@dataclass(frozen=True)
class RunDraw:
    """One run's errors (see the module notes); angles in rad, scales as factors."""

    run: int
    drop_north_m: float
    drop_east_m: float
    drop_altitude_m: float
    drop_mach: float
    drop_fpa_rad: float
    thrust_scale: tuple[float, float, float]
    isp_scale: tuple[float, float, float]
    navigation: dict[str, NDArray[np.float64]]  # (6,) position [m], velocity [m/s]
    burn_scale: tuple[float, ...]  # one per planned impulse
    burn_pointing_rad: tuple[tuple[float, float], ...]
    # The mid-course corrections: the estimate before each and its execution.
    correction_navigation: tuple[NDArray[np.float64], ...]
    correction_scale: tuple[float, ...]
    correction_pointing_rad: tuple[tuple[float, float], ...]
    density_scale: float
    lift_scale: float
    drag_scale: float
    seed: int = 0
    accelerometer_fraction: float = 0.0
    navigation_sigma: tuple[float, float] = (0.0, 0.0)  # position [m], velocity [m/s]

    def retarget_navigation(self, k: int) -> NDArray[np.float64]:
        """The estimate's error (6,) at the ``k``-th re-targeting of the phasing (the
        high-fidelity sky's), drawn from the run's own stream for it."""
        rng = np.random.default_rng([self.seed, self.run, 2, k])
        position, velocity = self.navigation_sigma
        return np.r_[rng.normal(0.0, position, 3), rng.normal(0.0, velocity, 3)]

    def measurement_error(self, call: int) -> NDArray[np.float64]:
        """Relative errors of the measured (lift, drag) at the ``call``-th entry guidance
        call: drawn from the run's own stream for that call, as many calls as the entry
        takes."""
        rng = np.random.default_rng([self.seed, self.run, 1, call])
        return rng.normal(0.0, self.accelerometer_fraction, 2)


def draw_run(config: DispersionsConfig, seed: int, run: int, impulses: int = 5) -> RunDraw:
    """The errors of run ``run`` of the Monte Carlo seeded ``seed`` (1-sigma normal)."""
    rng = np.random.default_rng([seed, run])
    drop, stages, nav = config.drop, config.stages, config.navigation
    burns, entry = config.burns, config.entry
    corrections = len(config.closed_loop.rendezvous_corrections)

    def normal(sigma: float, size: int | None = None) -> Any:
        return rng.normal(0.0, sigma, size)

    return RunDraw(
        run=run,
        drop_north_m=float(normal(drop.position_m)),
        drop_east_m=float(normal(drop.position_m)),
        drop_altitude_m=float(normal(drop.altitude_m)),
        drop_mach=float(normal(drop.mach)),
        drop_fpa_rad=math.radians(float(normal(drop.fpa_deg))),
        thrust_scale=tuple(1.0 + normal(stages.thrust_fraction, 3)),
        isp_scale=tuple(1.0 + normal(stages.isp_fraction, 3)),
        navigation={
            point: np.r_[normal(nav.position_m, 3), normal(nav.velocity_mps, 3)]
            for point in NAVIGATION_POINTS
        },
        burn_scale=tuple(1.0 + normal(burns.magnitude_fraction, impulses)),
        burn_pointing_rad=tuple(
            (float(a), float(b)) for a, b in np.radians(normal(burns.pointing_deg, (impulses, 2)))
        ),
        correction_navigation=tuple(
            np.r_[normal(nav.position_m, 3), normal(nav.velocity_mps, 3)]
            for _ in range(corrections)
        ),
        correction_scale=tuple(1.0 + normal(burns.magnitude_fraction, corrections)),
        correction_pointing_rad=tuple(
            (float(a), float(b))
            for a, b in np.radians(normal(burns.pointing_deg, (corrections, 2)))
        ),
        density_scale=float(max(1.0 + normal(entry.density_fraction), entry.minimum_factor)),
        lift_scale=float(max(1.0 + normal(entry.lift_fraction), entry.minimum_factor)),
        drag_scale=float(max(1.0 + normal(entry.drag_fraction), entry.minimum_factor)),
        seed=int(seed),
        accelerometer_fraction=config.closed_loop.accelerometer_fraction,
        navigation_sigma=(nav.position_m, nav.velocity_mps),
    )


def _pointed(dv: NDArray[np.float64], angles: tuple[float, float]) -> NDArray[np.float64]:
    """``dv``'s direction turned by two small angles about two axes normal to it."""
    norm = float(np.linalg.norm(dv))
    if norm == 0.0 or angles == (0.0, 0.0):
        # Unturned exactly: a renormalised copy differs in the last bits, and the replay's
        # adaptive steps turn that into ~0.1 m at the landing (a plan of issue 43).
        return dv.copy()
    u = dv / norm
    helper = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    turned = u + math.tan(angles[0]) * e1 + math.tan(angles[1]) * e2
    return norm * turned / np.linalg.norm(turned)


class DispersedFlight(Perturbation):
    """The errors of one draw applied to the replay (:func:`ovtraj.mission.fly.fly_plan`)."""

    def __init__(self, draw: RunDraw) -> None:
        self.draw = draw

    def ascent(self, inp: LaunchInput) -> LaunchInput:
        d = self.draw
        stages = []
        for stage, k_thrust, k_isp in zip(
            inp.launcher.stages, d.thrust_scale, d.isp_scale, strict=True
        ):
            # The propellant burns in m_p Isp g0 / F: the action time follows.
            stages.append(
                stage.model_copy(
                    update={
                        "vacuum_thrust_n": stage.vacuum_thrust_n * k_thrust,
                        "vacuum_isp_s": stage.vacuum_isp_s * k_isp,
                        "burn_time_s": stage.burn_time_s * k_isp / k_thrust,
                    }
                )
            )
        launcher = inp.launcher.model_copy(update={"stages": tuple(stages)})
        radius = inp.earth.radius
        latitude = math.radians(inp.drop.latitude_deg)
        drop = inp.drop.model_copy(
            update={
                "latitude_deg": inp.drop.latitude_deg + math.degrees(d.drop_north_m / radius),
                "longitude_deg": inp.drop.longitude_deg
                + math.degrees(d.drop_east_m / (radius * math.cos(latitude))),
                "altitude_km": inp.drop.altitude_km + d.drop_altitude_m / 1e3,
                "mach": inp.drop.mach + d.drop_mach,
                "flight_path_angle_deg": inp.drop.flight_path_angle_deg
                + math.degrees(d.drop_fpa_rad),
            }
        )
        return replace(inp, launcher=launcher, drop=drop)

    def burn(self, index: int, dv_eci_mps: NDArray[np.float64]) -> NDArray[np.float64]:
        d = self.draw
        return d.burn_scale[index] * _pointed(np.asarray(dv_eci_mps), d.burn_pointing_rad[index])

    def entry(self, model: EntryModel) -> EntryModel:
        d = self.draw
        return scaled_entry_model(model, d.density_scale, d.lift_scale, d.drag_scale)


def scaled_entry_model(model: EntryModel, density: float, lift: float, drag: float) -> EntryModel:
    """A copy of ``model`` with its density, lift and drag coefficients scaled."""
    scaled = copy.copy(model)
    scaled.cl = model.cl * lift
    scaled.cd = model.cd * drag
    scaled.log_rho = model.log_rho + math.log(density)
    scaled.params = model.params.copy()
    scaled.params[dyn.P_RHO0] *= density
    scaled.tables = (
        scaled.cl,
        scaled.cd,
        model.mach_nodes,
        model.alpha_nodes,
        scaled.log_rho,
        model.sound,
    )
    return scaled


@dataclass
class RunOutcome:
    """One run flown: reached the terminal speed or not, where (the miss from the landing
    site and the point itself), and the path maxima.

    ``dv_mps``: the dV [m/s] each manoeuvre the run executed spent (keys of
    :data:`MANOEUVRES`); ``dv_total_mps``: their sum once it executed all of them."""

    run: int
    loop: str  # "closed" or "open"
    landed: bool
    failed_stage: str | None = None
    reason: str | None = None
    landing_miss_m: float | None = None
    maxima: dict[str, float] = field(default_factory=dict)
    arrival_miss_m: float | None = None
    dv_total_mps: float | None = None
    dv_mps: dict[str, float] = field(default_factory=dict)
    # Where the run reached the terminal interface [deg] (geocentric: the miss's sphere).
    landing_latitude_deg: float | None = None
    landing_longitude_deg: float | None = None

    def spend(self, manoeuvre: str, *executed: NDArray[np.float64]) -> None:
        """Record ``manoeuvre`` as flown: the sum of its executed impulses' magnitudes
        [m/s] (none: 0); the total once every manoeuvre is recorded."""
        self.dv_mps[manoeuvre] = float(sum(np.linalg.norm(dv) for dv in executed))
        if set(MANOEUVRES) <= set(self.dv_mps):
            self.dv_total_mps = sum(self.dv_mps[name] for name in MANOEUVRES)


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


class _Failed(Exception):
    def __init__(self, stage: str, reason: str) -> None:
        super().__init__(reason)
        self.stage, self.reason = stage, reason


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
            _closed_loop(plan, scenario, draw, config, outcome, truth)
        outcome.landed = True
    except _Failed as failure:
        outcome.failed_stage, outcome.reason = failure.stage, failure.reason
    except ReplayFailed as failure:
        outcome.failed_stage, outcome.reason = "flight", str(failure)
    except (ArithmeticError, ValueError) as err:
        outcome.failed_stage = "flight"
        outcome.reason = f"numerical failure: {type(err).__name__}: {err}"
    return outcome


def _closed_loop(
    plan: MissionPlan,
    scenario: Scenario,
    draw: RunDraw,
    config: DispersionsConfig,
    outcome: RunOutcome,
    truth: Truth,
) -> None:
    earth = scenario.earth
    day = plan.day
    orbit = truth.vehicle
    propagator = OrbitPropagator(earth, tol=scenario.tolerances.integrator)
    flight = DispersedFlight(draw)
    entry_altitude_m = scenario.deorbit.entry.altitude_km * 1e3

    def estimate(point: str, truth: NDArray[np.float64]) -> NDArray[np.float64]:
        return truth + draw.navigation[point]

    def coast(state: NDArray, t0: float, t1: float, stage: str) -> NDArray:
        end, t_end, entered, _ = orbit.arc(state, t0, t1, floor_m=entry_altitude_m)
        if entered:
            raise _Failed(stage, f"the OV falls through the entry interface at {t_end:.0f} s")
        return end

    # 1. the ascent, dispersed
    scratch = FlightReport(ok=False, reason=None, landed_within_stated_miss=False, stated_miss_m=0)
    state, t = fly_ascent(plan, scenario, scratch, flight)
    # 2. rendezvous re-targeted from the estimated insertion
    target_at = truth.target_at
    common = rendezvous_settings(scenario)
    rdv = solve_rendezvous(
        RendezvousInput(
            epoch=day,
            t0_s=t,
            chaser_state=estimate("rendezvous", state),
            target_state=target_at(t),
            **common,
        )
    )
    if not rdv.feasible:
        raise _Failed("rendezvous", f"re-targeting failed: {rdv.reason}")
    if truth.retarget_interval_s is not None:
        # The sky is not the planner's J2: the phasing drifts (drag, the field's higher
        # terms), so the rendezvous is solved again from the estimate while it waits.
        k = 0
        while rdv.burn1.t_s - t > truth.retarget_interval_s:
            t_fix = t + truth.retarget_interval_s
            if t_fix > plan.stay.separation_t_s:
                # A re-solve may put the burn later each time: the stay bounds the loop.
                raise _Failed(
                    "rendezvous",
                    f"still phasing at the planned separation {plan.stay.separation_t_s:.0f} s",
                )
            state, t = coast(state, t, t_fix, "rendezvous"), t_fix
            rdv = solve_rendezvous(
                RendezvousInput(
                    epoch=day,
                    t0_s=t,
                    chaser_state=state + draw.retarget_navigation(k),
                    target_state=target_at(t),
                    **common,
                )
            )
            if not rdv.feasible:
                raise _Failed("rendezvous", f"re-targeting at {t:.0f} s failed: {rdv.reason}")
            k += 1
    state = coast(state, t, rdv.burn1.t_s, "rendezvous")
    dv = flight.burn(0, np.asarray(rdv.burn1.eci_mps))
    state, t = state + np.r_[0.0, 0.0, 0.0, dv], rdv.burn1.t_s
    outcome.spend("rendezvous burn 1", dv)
    t_arrival = rdv.burn2.t_s
    target = target_at(t_arrival)
    # Mid-course corrections: from the estimate, the velocity that reaches the target's
    # arrival position (differential correction under J2), executed with errors.
    t_burn1 = t
    corrections = []
    for k, fraction in enumerate(config.closed_loop.rendezvous_corrections):
        t_fix = t_burn1 + fraction * (t_arrival - t_burn1)
        state = coast(state, t, t_fix, "rendezvous")
        t = t_fix
        estimated = state + draw.correction_navigation[k]
        wanted = _reaching_velocity(
            propagator, estimated, t, t_arrival, target[:3], config.closed_loop
        )
        dv = draw.correction_scale[k] * _pointed(
            wanted - estimated[3:], draw.correction_pointing_rad[k]
        )
        state = state + np.r_[0.0, 0.0, 0.0, dv]
        corrections.append(dv)
    outcome.spend(CORRECTIONS, *corrections)
    state = coast(state, t, t_arrival, "rendezvous")
    # The second impulse matches the target's velocity, as the chaser estimates its own.
    matched = target[3:] - estimate("arrival", state)[3:]
    dv = flight.burn(1, matched)
    state = state + np.r_[0.0, 0.0, 0.0, dv]
    outcome.spend("rendezvous burn 2", dv)
    outcome.arrival_miss_m = float(np.linalg.norm(state[:3] - target[:3]))
    capture = config.closed_loop.docking_capture_m
    if outcome.arrival_miss_m > capture:
        raise _Failed(
            "rendezvous",
            f"arrives {outcome.arrival_miss_m:.0f} m from the target (capture {capture:g} m)",
        )
    t_sep = plan.stay.separation_t_s
    if t_arrival > t_sep:
        raise _Failed(
            "rendezvous", f"docks at {t_arrival:.0f} s, after the planned separation {t_sep:.0f} s"
        )
    # Docked: the OV moves with the target until the planned separation.
    state, t = target_at(t_sep), t_sep
    # 3. the transfer, solved again from the estimate at separation
    transfer = circular_transfer(
        TransferInput(
            epoch=day,
            t0_s=t,
            chaser_state=estimate("transfer", state),
            target_altitude_m=plan.transfer.preparation_altitude_m,
            burn_time_s=t,
            **common,
        )
    )
    if not transfer.feasible:
        raise _Failed("transfer", f"re-solving failed: {transfer.reason}")
    for k, burn in ((2, transfer.burn1), (3, transfer.burn2)):
        state = coast(state, t, burn.t_s, "transfer")
        dv = flight.burn(k, np.asarray(burn.eci_mps))
        state, t = state + np.r_[0.0, 0.0, 0.0, dv], burn.t_s
        outcome.spend(IMPULSES[k], dv)
    t_prep = transfer.arrival_time_s
    state = coast(state, t, t_prep, "transfer")
    t = t_prep
    # 4. the deorbit, solved again; the burn cut off by the entry prediction
    deorbit = solve_deorbit(
        deorbit_input(scenario, state0=estimate("deorbit", state), epoch=day.plus_seconds(t))
    )
    if not deorbit.feasible:
        raise _Failed("deorbit", f"re-solving failed: {deorbit.reason}")
    t_burn = t + deorbit.burn_t_s
    state = coast(state, t, t_burn, "deorbit")
    dv = _cut_off(
        estimate("deorbit", state),
        np.asarray(deorbit.dv_eci_mps, dtype=float),
        flight.burn(4, np.asarray(deorbit.dv_eci_mps, dtype=float)),
        scenario,
        config,
    )
    state, t = state + np.r_[0.0, 0.0, 0.0, dv], t_burn
    outcome.spend("deorbit burn", dv)
    # descent to the entry interface
    r0 = float(np.linalg.norm(state[:3]))
    horizon = scenario.deorbit.max_descent_revolutions * TWO_PI * math.sqrt(r0**3 / earth.mu)
    state, t_entry, entered, _ = orbit.arc(state, t, t + horizon, floor_m=entry_altitude_m)
    if not entered:
        raise _Failed("deorbit", "the descent does not reach the entry interface")
    theta = day.gmst_rad() + earth.omega * t_entry
    rel = relative_entry(state, theta, earth.omega, earth.radius)
    # 5. the entry, guidance re-solved in flight
    _guided_entry(plan, scenario, day.plus_seconds(t_entry), rel, flight, config, outcome)


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
        retarget_interval_s=force_model.closed_loop.phasing_retarget_interval_h * 3600.0,
    )


def _reaching_velocity(
    propagator: OrbitPropagator,
    state: NDArray[np.float64],
    t0: float,
    t1: float,
    target_position: NDArray[np.float64],
    settings: Any,
) -> NDArray[np.float64]:
    """The velocity at ``t0`` that coasts from ``state``'s position to ``target_position``
    at ``t1`` under J2: Newton on the velocity with the state-transition matrix's
    position-velocity block (differential correction; Vallado, 4th ed., sec. 7.5)."""
    velocity = state[3:].copy()
    for _ in range(settings.correction_iterations):
        end, stm = propagator.propagate_with_stm(np.r_[state[:3], velocity], t0, t1)
        miss = target_position - end[:3]
        if float(np.linalg.norm(miss)) <= settings.correction_tolerance_m:
            break
        velocity = velocity + np.linalg.solve(stm[:3, 3:6], miss)
    return velocity


def _cut_off(
    estimate: NDArray[np.float64],
    nominal_dv: NDArray[np.float64],
    executed_dv: NDArray[np.float64],
    scenario: Scenario,
    config: DispersionsConfig,
) -> NDArray[np.float64]:
    """The executed deorbit impulse, cut when the predicted entry argument of latitude from
    the estimate reaches the nominal burn's (seed 004 strategy 1); the direction stays the
    executed one."""
    earth = scenario.earth
    constants = EarthConstants(earth.mu, earth.radius, earth.j2, earth.g0_m_s2)
    entry_radius = earth.radius + scenario.deorbit.entry.altitude_km * 1e3
    iterations = config.closed_loop.prediction_iterations

    def entry_u(dv: NDArray[np.float64]) -> float:
        prediction = predict_entry(
            estimate[None, :3],
            (estimate[3:] + dv)[None, :],
            earth=constants,
            entry_radius=entry_radius,
            iterations=iterations,
        )
        return float(prediction.u_rad[0])

    target = entry_u(nominal_dv)
    direction = executed_dv / float(np.linalg.norm(executed_dv))
    magnitude = float(np.linalg.norm(nominal_dv))

    def gap(scale: float) -> float:
        u = entry_u(scale * magnitude * direction)
        return wrap_to_pi(u - target)

    lo, hi = config.closed_loop.cutoff_scale_bounds
    if not (math.isfinite(gap(lo)) and math.isfinite(gap(hi))) or gap(lo) * gap(hi) > 0.0:
        return executed_dv  # the prediction cannot bracket the cut-off: burn as executed
    return brentq(gap, lo, hi, xtol=1e-10) * magnitude * direction


def _guided_entry(
    plan: MissionPlan,
    scenario: Scenario,
    epoch: Any,
    rel: dict[str, float],
    flight: DispersedFlight,
    config: DispersionsConfig,
    outcome: RunOutcome,
) -> None:
    """Fly the entry in the dispersed atmosphere, the guidance re-solved every interval."""
    earth = scenario.earth
    interval = config.closed_loop.guidance_interval_s
    settings = scenario.reentry
    x = np.array(
        [
            earth.radius + rel["altitude_m"],
            rel["longitude_rad"],
            rel["latitude_rad"],
            rel["speed_mps"],
            rel["fpa_rad"],
            rel["heading_rad"],
        ]
    )
    sign, elapsed, calls = 1.0, 0.0, 0
    draw = flight.draw
    sigma = None
    maxima = dict.fromkeys(PATH_LIMITS, 0.0)
    limit_s = settings.integration.max_time_s
    while True:
        entry = EntryState(
            epoch=epoch.plus_seconds(elapsed),
            latitude_rad=float(x[2]),
            longitude_rad=float(x[1]),
            altitude_m=float(x[0]) - earth.radius,
            speed_mps=float(x[3]),
            fpa_rad=float(x[4]),
            heading_rad=float(x[5]),
        )
        inp = reentry_input(scenario, entry=entry)
        nominal = EntryModel(inp)
        truth = flight.entry(nominal)
        predictor = _measured_model(nominal, truth, x, draw.measurement_error(calls), config)
        calls += 1
        guidance = solve_reentry(inp, model=predictor)
        if guidance.sigma0_rad is not None and guidance.sigma1_rad is not None:
            sigma = (guidance.sigma0_rad, guidance.sigma1_rad)
        if sigma is None:
            raise _Failed("reentry", f"the guidance finds no bank profile: {guidance.reason}")
        truth.params[dyn.P_MAX_TIME] = min(interval, limit_s - elapsed)
        leg = truth.fly(sigma[0], sigma[1], record=True, bank_sign=sign)
        for name, value in (
            ("max_heat_rate_w_m2", leg.max_heat_rate_w_m2),
            ("max_load_g", leg.max_load_g),
            ("max_dynamic_pressure_pa", leg.max_dynamic_pressure_pa),
        ):
            maxima[name] = max(maxima[name], value)
        elapsed += leg.time_s
        x = leg.state
        if leg.history is not None and len(leg.history):
            sign = -1.0 if np.signbit(leg.history[-1, _BANK]) else 1.0
        if leg.status == dyn.TERMINAL:
            break
        if leg.status in (dyn.CRASHED, dyn.SKIPPED):
            raise _Failed("reentry", dyn.STATUS_TEXT[leg.status])
        if elapsed >= limit_s:
            raise _Failed("reentry", f"no terminal speed within {limit_s:g} s")
    outcome.maxima = maxima
    outcome.landing_latitude_deg = math.degrees(float(x[2]))
    outcome.landing_longitude_deg = math.degrees(wrap_to_pi(float(x[1])))
    site = settings.landing_site
    outcome.landing_miss_m = great_circle_distance(
        float(x[2]),
        float(x[1]),
        math.radians(site.latitude_deg),
        math.radians(site.longitude_deg),
        radius=earth.radius,
    )


_BANK = dyn.HISTORY_COLUMNS.index("bank_rad")


def _measured_model(
    nominal: EntryModel,
    truth: EntryModel,
    x: NDArray[np.float64],
    error: NDArray[np.float64],
    config: DispersionsConfig,
) -> EntryModel:
    """The guidance's predictor: the nominal model with its density scaled to the measured
    drag and its lift coefficient to the measured lift-to-drag ratio, once the drag is
    measurable (the density filter of predictor-corrector entry guidance); the measured
    accelerations carry the draw's relative errors."""
    lift_t, drag_t, *_ = dyn._aero(x, truth.params, truth.tables)
    lift_n, drag_n, *_ = dyn._aero(x, nominal.params, nominal.tables)
    drag_measured = drag_t * (1.0 + error[1])
    if drag_measured < config.closed_loop.drag_estimate_threshold_mps2 or drag_n <= 0.0:
        return nominal
    drag_factor = drag_measured / drag_n
    lift_factor = lift_t * (1.0 + error[0]) / lift_n if lift_n > 0.0 else 1.0
    return scaled_entry_model(nominal, drag_factor, lift_factor / drag_factor, 1.0)


def monte_carlo(
    plan: MissionPlan,
    config: DispersionsConfig,
    runs: int,
    seed: int,
    *,
    progress: Any = None,
    force_model: ForceModelSettings | None = None,
) -> list[tuple[RunOutcome, RunOutcome]]:
    """``runs`` draws, each flown closed and open loop (serially, in this process);
    ``progress(done, total)`` after each run (and a debug log line). With ``force_model``
    the closed loop flies under the high-fidelity sky; the open loop is the J2 replay."""
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    pairs = []
    for run in range(runs):
        draw = draw_run(config, seed, run, len(plan.impulses()))
        pairs.append(
            (
                fly_closed_loop(plan, draw, config, scenario, force_model),
                fly_open_loop(plan, draw),
            )
        )
        logger.debug(
            "run %d/%d: closed loop %s, open loop %s",
            run + 1,
            runs,
            *("landed" if o.landed else f"failed ({o.failed_stage})" for o in pairs[-1]),
        )
        if progress is not None:
            progress(run + 1, runs)
    return pairs


def path_limits(plan: MissionPlan) -> dict[str, float]:
    """The entry's path limits of the plan's scenario, in the units of ``PATH_LIMITS``."""
    limits = plan.scenario["reentry"]["limits"]
    return {
        "max_heat_rate_w_m2": limits["max_heat_rate_kw_m2"] * 1e3,
        "max_load_g": limits["max_load_g"],
        "max_dynamic_pressure_pa": limits["max_dynamic_pressure_kpa"] * 1e3,
    }


def planned_dv(plan: MissionPlan) -> dict[str, float]:
    """The dV [m/s] the plan spends on each manoeuvre of :data:`MANOEUVRES` (its impulses'
    magnitudes; no mid-course correction: 0) and ``total``, their sum."""
    planned = dict.fromkeys(MANOEUVRES, 0.0)
    planned.update(
        {name: impulse.dv_mps for name, impulse in zip(IMPULSES, plan.impulses(), strict=True)}
    )
    return {"total": sum(planned.values()), **planned}


def outcome_summaries(
    plan: MissionPlan, closed: list[RunOutcome], opened: list[RunOutcome]
) -> dict[str, dict[str, Any]]:
    """:func:`summarise` of each loop's runs (``closed``, ``open``) against the plan's
    limits, stated miss and dV."""
    limits, stated, planned = path_limits(plan), plan.terminal.stated_miss_m, planned_dv(plan)
    return {
        loop: summarise(outcomes, limits, stated, planned)
        for loop, outcomes in (("closed", closed), ("open", opened))
    }


def loop_summaries(plan: MissionPlan, frame: pd.DataFrame) -> dict[str, dict[str, Any]]:
    """:func:`outcome_summaries` of the stored rows of each loop (``closed``, ``open``)."""
    return outcome_summaries(plan, outcomes_of(frame, "closed"), outcomes_of(frame, "open"))


def monte_carlo_report(
    closed: dict[str, Any], opened: dict[str, Any], seed: int, stated_miss_m: float
) -> dict[str, Any]:
    """The Monte Carlo as reported: the closed loop's figures (``runs``, ``landing_miss_m``,
    ``feasible_fraction``, ``dv_mps``, ...) with ``open_loop``'s beside them."""
    return {
        "loop": "closed",
        "seed": int(seed),
        "stated_miss_m": stated_miss_m,
        **closed,
        "open_loop": opened,
    }


def summarise(
    outcomes: list[RunOutcome],
    limits: dict[str, float],
    stated_miss_m: float,
    planned: dict[str, float] | None = None,
) -> dict[str, Any]:
    """The landing-miss percentiles over every run, a run that did not land counting as a
    miss beyond any distance (a percentile that falls on one is ``None``); the landed
    fraction, the fraction within the stated miss, the failures by stage, the smallest
    margin of each path limit over the runs that flew the entry, and the dV spent
    (:func:`dv_statistics` against ``planned``, the plan's: :func:`planned_dv`)."""
    landed = [o for o in outcomes if o.landed and o.landing_miss_m is not None]
    misses = np.array([o.landing_miss_m if o in landed else np.inf for o in outcomes], dtype=float)
    summary: dict[str, Any] = {
        "runs": len(outcomes),
        "landed": len(landed),
        "feasible_fraction": len(landed) / len(outcomes) if outcomes else 0.0,
        "within_stated_miss_fraction": (
            float(np.sum(misses <= stated_miss_m)) / len(outcomes) if outcomes else 0.0
        ),
        "landing_miss_m": _percentiles(misses) if landed else None,
        "failures": _failures(outcomes),
    }
    margins = {}
    for name in PATH_LIMITS:
        values = [o.maxima[name] for o in outcomes if name in o.maxima]
        margins[name] = (
            {"limit": limits[name], "smallest_margin": limits[name] - max(values)}
            if values
            else None
        )
    summary["path_limit_margins"] = margins
    summary["dv_mps"] = dv_statistics(outcomes, planned or {})
    return summary


def _percentiles(values: NDArray[np.float64]) -> dict[str, float | None]:
    """``p50``, ``p95`` and ``max`` of ``values`` (non-empty), each one of the values
    (numpy's ``higher`` method); a non-finite one (a run counted beyond any value) is
    ``None``."""

    def percentile(q: float) -> float | None:
        value = float(np.percentile(values, q, method="higher"))
        return value if math.isfinite(value) else None

    return {"p50": percentile(50), "p95": percentile(95), "max": percentile(100)}


def dv_statistics(
    outcomes: list[RunOutcome], planned: dict[str, float]
) -> dict[str, dict[str, Any]]:
    """The dV spent [m/s], ``total`` and each manoeuvre of :data:`MANOEUVRES`: ``runs``
    (how many executed it; for the total, all of them), ``p50``, ``p95`` and ``max`` over
    those runs (``None`` when none did), ``planned`` (``planned``'s value, ``None`` if it
    has none) and ``p95_minus_planned``, the margin beyond the plan a tank sized at p95
    carries."""
    section = {}
    for name in ("total", *MANOEUVRES):
        flown = [o.dv_total_mps if name == "total" else o.dv_mps.get(name) for o in outcomes]
        values = np.array([v for v in flown if v is not None and math.isfinite(v)], dtype=float)
        stats = _percentiles(values) if len(values) else dict.fromkeys(("p50", "p95", "max"))
        plan = planned.get(name)
        section[name] = {
            "runs": len(values),
            **stats,
            "planned": plan,
            "p95_minus_planned": (
                None if stats["p95"] is None or plan is None else stats["p95"] - plan
            ),
        }
    return section


def _failures(outcomes: list[RunOutcome]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for o in outcomes:
        if not o.landed:
            key = o.failed_stage or "unknown"
            counts[key] = counts.get(key, 0) + 1
    return counts


def simulate_batch(
    plan: MissionPlan,
    config: DispersionsConfig,
    runs: list[int],
    seed: int,
    force_model: ForceModelSettings | None = None,
    on_run: Callable[[], None] | None = None,
) -> pd.DataFrame:
    """Rows of ``RUN_SCHEMA``: each run flown closed and open loop (timed per row); the
    closed loop under ``force_model``'s sky when given (:func:`monte_carlo`);
    ``on_run()`` after each run (a progress bar's step)."""
    import time

    require_pinned_kernel()  # stored rows: the pinned OpenBLAS kernel only (ovtraj.environment)
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    rows = []
    for run in runs:
        draw = draw_run(config, seed, run, len(plan.impulses()))
        for fly in (
            lambda d=draw: fly_closed_loop(plan, d, config, scenario, force_model),
            lambda d=draw: fly_open_loop(plan, d),
        ):
            start = time.perf_counter()
            outcome = fly()
            rows.append(
                {
                    "run": run,
                    "loop": outcome.loop,
                    "landed": outcome.landed,
                    "failed_stage": outcome.failed_stage,
                    "reason": outcome.reason,
                    "landing_miss_m": outcome.landing_miss_m,
                    "landing_latitude_deg": outcome.landing_latitude_deg,
                    "landing_longitude_deg": outcome.landing_longitude_deg,
                    "arrival_miss_m": outcome.arrival_miss_m,
                    **{c: outcome.dv_mps.get(name) for name, c in MANOEUVRES.items()},
                    "dv_total_mps": outcome.dv_total_mps,
                    **{name: outcome.maxima.get(name) for name in PATH_LIMITS},
                    "wall_time_s": time.perf_counter() - start,
                }
            )
        if on_run is not None:
            on_run()
    return pd.DataFrame(rows, columns=RUN_SCHEMA.names)


def outcomes_of(frame: pd.DataFrame, loop: str) -> list[RunOutcome]:
    """The stored rows of one loop as outcomes (for :func:`summarise`)."""

    def value(row: Any, name: str) -> Any:
        item = row[name]
        return None if item is None or (isinstance(item, float) and math.isnan(item)) else item

    outcomes = []
    for _, row in frame[frame["loop"] == loop].iterrows():
        outcomes.append(
            RunOutcome(
                run=int(row["run"]),
                loop=loop,
                landed=bool(row["landed"]),
                failed_stage=value(row, "failed_stage"),
                reason=value(row, "reason"),
                landing_miss_m=value(row, "landing_miss_m"),
                landing_latitude_deg=value(row, "landing_latitude_deg"),
                landing_longitude_deg=value(row, "landing_longitude_deg"),
                maxima={n: float(row[n]) for n in PATH_LIMITS if value(row, n) is not None},
                arrival_miss_m=value(row, "arrival_miss_m"),
                dv_total_mps=value(row, "dv_total_mps"),
                dv_mps={
                    name: float(row[column])
                    for name, column in MANOEUVRES.items()
                    if value(row, column) is not None
                },
            )
        )
    return outcomes
