"""The closed loop's on-board corrections (:mod:`ovtraj.mission.montecarlo_flight`), each
by the stage's own method from the on-board estimate:

* the rendezvous' mid-course corrections: the velocity that reaches the target's arrival
  position under J2 (:func:`reaching_velocity`, differential correction);
* the deorbit burn cut off on line by the osculating-element entry prediction of seed 004
  (:func:`cut_off`; :func:`ovtraj.astro.entry_prediction.predict_entry`, strategy 1):
  along the actually pointed direction, the engine stops when the predicted entry argument
  of latitude reaches the one the nominal burn predicts from the same estimate, which
  absorbs the magnitude error;
* the reentry guidance re-solved in flight every ``closed_loop.guidance_interval_s`` from
  the current state (:func:`guided_entry`; :func:`ovtraj.reentry.solve_reentry`, the
  nominal model with its density and lift fitted to the measured accelerations), the truth
  flown between solves in the dispersed atmosphere with the guidance's heading-corridor
  reversals.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq

from ovtraj.astro.angles import wrap_to_pi
from ovtraj.astro.constants import EarthConstants
from ovtraj.astro.entry_prediction import predict_entry
from ovtraj.astro.frames import great_circle_distance
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.config import Scenario
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.mission.montecarlo_draw import DispersedFlight, scaled_entry_model
from ovtraj.mission.montecarlo_outcome import PATH_LIMITS, RunOutcome, StageFailed
from ovtraj.reentry import EntryState, reentry_input, solve_reentry
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry.model import EntryModel

__all__ = ["cut_off", "guided_entry", "reaching_velocity"]

_BANK = dyn.HISTORY_COLUMNS.index("bank_rad")


def reaching_velocity(
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


def cut_off(
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


def guided_entry(
    scenario: Scenario,
    epoch: Any,
    rel: dict[str, float],
    flight: DispersedFlight,
    config: DispersionsConfig,
    outcome: RunOutcome,
) -> None:
    """Fly the entry from the interface state ``rel`` at ``epoch``
    (:func:`ovtraj.mission.replay_entry.relative_entry`) in the dispersed atmosphere, the
    guidance re-solved every interval; the path maxima and the landing into ``outcome``.
    Raises :class:`StageFailed` (``reentry``)."""
    interval = config.closed_loop.guidance_interval_s
    limit_s = scenario.reentry.integration.max_time_s
    x = np.array(
        [
            scenario.earth.radius + rel["altitude_m"],
            rel["longitude_rad"],
            rel["latitude_rad"],
            rel["speed_mps"],
            rel["fpa_rad"],
            rel["heading_rad"],
        ]
    )
    sign, elapsed, calls = 1.0, 0.0, 0
    sigma = None
    maxima = dict.fromkeys(PATH_LIMITS, 0.0)
    while True:
        state_epoch = epoch.plus_seconds(elapsed)
        truth, sigma = _guidance_call(scenario, state_epoch, x, flight, config, calls, sigma)
        calls += 1
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
            raise StageFailed("reentry", dyn.STATUS_TEXT[leg.status])
        if elapsed >= limit_s:
            raise StageFailed("reentry", f"no terminal speed within {limit_s:g} s")
    _record_landing(outcome, x, maxima, scenario)


def _guidance_call(
    scenario: Scenario,
    epoch: Any,
    x: NDArray[np.float64],
    flight: DispersedFlight,
    config: DispersionsConfig,
    call: int,
    sigma: tuple[float, float] | None,
) -> tuple[EntryModel, tuple[float, float]]:
    """The ``call``-th guidance call from the state vector ``x`` at ``epoch``: the true
    (dispersed) model to fly the next leg in, and the bank profile (sigma0, sigma1) [rad]
    to fly, this call's, else the last call's ``sigma``; none at all fails the reentry."""
    entry = EntryState(
        epoch=epoch,
        latitude_rad=float(x[2]),
        longitude_rad=float(x[1]),
        altitude_m=float(x[0]) - scenario.earth.radius,
        speed_mps=float(x[3]),
        fpa_rad=float(x[4]),
        heading_rad=float(x[5]),
    )
    inp = reentry_input(scenario, entry=entry)
    nominal = EntryModel(inp)
    truth = flight.entry(nominal)
    error = flight.draw.measurement_error(call)
    guidance = solve_reentry(inp, model=_measured_model(nominal, truth, x, error, config))
    if guidance.sigma0_rad is not None and guidance.sigma1_rad is not None:
        sigma = (guidance.sigma0_rad, guidance.sigma1_rad)
    if sigma is None:
        raise StageFailed("reentry", f"the guidance finds no bank profile: {guidance.reason}")
    return truth, sigma


def _record_landing(
    outcome: RunOutcome, x: NDArray[np.float64], maxima: dict[str, float], scenario: Scenario
) -> None:
    """The path maxima, the landing point [deg] and its miss [m] from the landing site (on
    the spherical Earth) of an entry that ended at the terminal speed in state ``x``."""
    site = scenario.reentry.landing_site
    outcome.maxima = maxima
    outcome.landing_latitude_deg = math.degrees(float(x[2]))
    outcome.landing_longitude_deg = math.degrees(wrap_to_pi(float(x[1])))
    outcome.landing_miss_m = great_circle_distance(
        float(x[2]),
        float(x[1]),
        math.radians(site.latitude_deg),
        math.radians(site.longitude_deg),
        radius=scenario.earth.radius,
    )


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
    lift_t, drag_t, *_ = dyn.aero_accelerations(x, truth.params, truth.tables)
    lift_n, drag_n, *_ = dyn.aero_accelerations(x, nominal.params, nominal.tables)
    drag_measured = drag_t * (1.0 + error[1])
    if drag_measured < config.closed_loop.drag_estimate_threshold_mps2 or drag_n <= 0.0:
        return nominal
    drag_factor = drag_measured / drag_n
    lift_factor = lift_t * (1.0 + error[0]) / lift_n if lift_n > 0.0 else 1.0
    return scaled_entry_model(nominal, drag_factor, lift_factor / drag_factor, 1.0)
