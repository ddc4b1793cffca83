"""The plan's orbits flown under the high-fidelity force model.

:func:`force_terms` turns ``configs/force_model.yaml`` and the scenario's Earth into the
terms of :mod:`ovtraj.astro.forces`; :func:`check_span` refuses, in one line naming the
setting, a flight outside the Earth-orientation or space-weather data; and
:class:`HighFidelityOrbit` flies one spacecraft's arcs with the interface of the J2
replay's :class:`ovtraj.mission.replay_orbit.ReplayOrbit`, so the closed loop of
:mod:`ovtraj.mission.montecarlo` flies the same corrections under either model
(:class:`Truth`). The on-board solvers (rendezvous, transfer, deorbit, entry guidance)
keep the chain's J2 model: the high-fidelity model is the sky, not the planner.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ovtraj.astro.epoch import Epoch
from ovtraj.astro.forces.dynamics import ForceTerms
from ovtraj.astro.forces.earth_data import earth_orientation_span, space_weather_span
from ovtraj.astro.forces.propagator import HighFidelityPropagator
from ovtraj.astro.forces.terms import needed
from ovtraj.astro.forces.time_scales import day_of_year, tt_centuries
from ovtraj.config import Scenario
from ovtraj.config.body import BodyConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.errors import ConfigError
from ovtraj.mission.flight_report import ReplayFailed
from ovtraj.units import J2000_JD, S_PER_DAY, S_PER_HOUR

__all__ = [
    "FIDELITIES",
    "HighFidelityOrbit",
    "check_span",
    "fit_with_drag",
    "flight_span",
    "force_terms",
    "high_fidelity_settings",
    "spacecraft_factors",
    "target_sky",
]

FIDELITIES = ("j2", "high")
SOURCE = "configs/force_model.yaml"


def force_terms(settings: ForceModelSettings, scenario: Scenario) -> ForceTerms:
    """The terms ``settings`` switch on, with the scenario's Earth for the J2 field, the
    rotation of the atmosphere and the shadow's radius."""
    earth = scenario.earth
    weather, sun, moon = settings.space_weather, settings.sun, settings.moon
    srp = settings.solar_radiation_pressure
    jb = weather.jb08
    every = ForceTerms(
        gravity=settings.gravity.model,
        degree=settings.gravity.degree,
        order=settings.gravity.order,
        mu=earth.mu,
        radius=earth.radius,
        j2=earth.j2,
        omega=earth.omega,
        drag_model=settings.drag.model,
        weather=weather.source,
        f107=weather.f107_sfu,
        f107a=weather.f107a_sfu,
        ap=weather.ap,
        jb08_indices=(
            jb.s107_sfu,
            jb.s107a_sfu,
            jb.m107_sfu,
            jb.m107a_sfu,
            jb.y107_sfu,
            jb.y107a_sfu,
            jb.ddst_dt_nt_h,
        ),
        sun_mu=sun.mu_m3_s2,
        vsop_threshold=sun.vsop2013_threshold,
        moon_mu=moon.mu_m3_s2,
        elp_threshold=moon.elp2000_threshold,
        radiation=(
            srp.pressure_n_m2,
            srp.astronomical_unit_m,
            srp.sun_radius_m,
            srp.shadow_sharpness,
            srp.shadow_step_edge,
        ),
        astronomical_unit_m=srp.astronomical_unit_m,
        precession_threshold=settings.precession_nutation_threshold,
        eop_extrapolation_days=settings.earth_orientation.max_extrapolation_days,
        ellipsoid_radius_m=settings.ellipsoid.equatorial_radius_m,
        ellipsoid_ecc2=settings.ellipsoid.eccentricity_squared,
    )
    return every.only(*settings.switched_on())


def check_span(
    settings: ForceModelSettings, start: Epoch, end: Epoch, source: str = SOURCE
) -> None:
    """:class:`ConfigError` naming the setting when [start, end] lies outside the data the
    model reads (the Earth orientation always; the space weather with ``source: bundled``
    and a term on that reads it, :data:`ovtraj.astro.forces.terms.FORCE_TERMS`)."""
    first, last = earth_orientation_span(settings.earth_orientation.max_extrapolation_days)
    if start.jd < first or end.jd > last:
        raise ConfigError(
            [
                f"earth_orientation.max_extrapolation_days: the flight "
                f"{start.iso(0)} .. {end.iso(0)} lies outside the Earth orientation data "
                f"with its extrapolation ({_date(first)} .. {_date(last)})"
            ],
            source,
        )
    if settings.space_weather.source == "bundled" and needed(
        "space_weather", settings.switched_on()
    ):
        first, last = space_weather_span()
        # The 81-day mean is centred: the table ends 40 days after its last usable mean,
        # but heyoka's table already holds the centred mean per day, so its span is the
        # table's. F10.7 is the previous day's.
        if start.jd - 1.0 < first or end.jd > last:
            raise ConfigError(
                [
                    f"space_weather.source: the flight {start.iso(0)} .. {end.iso(0)} lies "
                    f"outside the bundled space weather ({_date(first)} .. {_date(last)}); "
                    "use source: constant with the expected indices"
                ],
                source,
            )


def flight_span(plan: Any, scenario: Scenario) -> tuple[Epoch, Epoch]:
    """The epochs a flight of ``plan`` may reach: from the earlier of the scenario's epoch
    (the target's origin) and the plan's day, to a day past its last planned impulse (the
    descent and the entry take a fraction of it)."""
    last = max(impulse.t_s for impulse in plan.impulses())
    start = scenario.epoch if scenario.epoch.jd < plan.day.jd else plan.day
    return start, plan.day.plus_seconds(last + S_PER_DAY)


def high_fidelity_settings(
    plan: Any, fidelity: str, path: str | Path | None = None
) -> ForceModelSettings | None:
    """The force model a flight of ``plan`` flies under: None for ``j2``; for ``high`` the
    settings (``path``, else the shipped file), checked against the plan's bodies and
    the data's span. :class:`ConfigError` (one line) for a bad fidelity, file or span."""
    if fidelity not in FIDELITIES:
        raise ConfigError([f"fidelity: {fidelity!r} is not one of {', '.join(FIDELITIES)}"])
    if fidelity == "j2":
        return None
    from ovtraj.config import scenario_from_dict
    from ovtraj.config.base import load_model
    from ovtraj.config.force_model import default_force_model

    settings = default_force_model() if path is None else load_model(ForceModelSettings, path)
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    spacecraft_factors(scenario, "vehicle")
    spacecraft_factors(scenario, "target")
    check_span(settings, *flight_span(plan, scenario), SOURCE if path is None else str(path))
    return settings


def _date(jd: float) -> str:
    from datetime import UTC, datetime, timedelta

    moment = datetime(2000, 1, 1, 12, tzinfo=UTC) + timedelta(days=jd - J2000_JD)
    return moment.date().isoformat()


@dataclass(frozen=True)
class SpacecraftFactors:
    """C_D A / m and C_R A / m [m^2/kg] of one spacecraft."""

    ballistic_m2_kg: float
    radiation_m2_kg: float


def spacecraft_factors(scenario: Scenario, which: str) -> SpacecraftFactors:
    """The ``vehicle``'s or the ``target``'s factors; :class:`ConfigError` naming the
    missing ``vehicle.body`` / ``target.body``."""
    if which == "vehicle":
        body: BodyConfig | None = scenario.vehicle.body
        mass = scenario.vehicle.mass_kg
    else:
        body = scenario.target.body
        mass = body.mass_kg if body is not None else 0.0
    if body is None:
        raise ConfigError(
            [
                f"{which}.body: the high-fidelity flight needs the {which}'s drag and "
                "radiation pressure figures (drag_area_m2, drag_coefficient, srp_area_m2, "
                f"reflectivity_coefficient{', mass_kg' if which == 'target' else ''})"
            ],
            "the scenario",
        )
    return SpacecraftFactors(body.ballistic_m2_kg(mass), body.radiation_m2_kg(mass))


class HighFidelityOrbit:
    """Arcs of one spacecraft under the high-fidelity model, t in s from ``origin``; the
    interface of :class:`ovtraj.mission.replay_orbit.ReplayOrbit` (``arc``)."""

    def __init__(
        self,
        scenario: Scenario,
        settings: ForceModelSettings,
        origin: Epoch,
        factors: SpacecraftFactors,
    ) -> None:
        self.earth = scenario.earth
        self.propagator = HighFidelityPropagator(
            force_terms(settings, scenario),
            origin_tt_centuries=tt_centuries(origin),
            origin_day_of_year=day_of_year(origin),
            ballistic_m2_kg=factors.ballistic_m2_kg,
            radiation_m2_kg=factors.radiation_m2_kg,
            tol=settings.integration.tolerance,
            max_arc_s=settings.integration.max_arc_days * S_PER_DAY,
        )

    def arc(
        self, state: np.ndarray, t0: float, t1: float, *, floor_m: float | None = None, **_: Any
    ) -> tuple[np.ndarray, float, bool, float]:
        """(state at the end, end time, stopped at ``floor_m``, lowest altitude at the
        integrator's steps), as :meth:`ovtraj.mission.replay_orbit.ReplayOrbit.arc`."""
        if t1 < t0:
            raise ReplayFailed(f"the plan's epochs run backwards ({t0:.3f} -> {t1:.3f} s)")
        floor_radius = 0.0 if floor_m is None else self.earth.radius + floor_m
        try:
            arc = self.propagator.arc(state, t0, t1, floor_radius_m=floor_radius)
        except (FloatingPointError, ValueError) as err:
            raise ReplayFailed(f"high-fidelity orbit: {err}") from None
        return arc.state, arc.t, arc.stopped, arc.lowest_radius_m - self.earth.radius


class TargetTrack:
    """The target's state at any time, flown forward from its last asked time (the closed
    loop asks in time order: a day of flight once, not once per question)."""

    def __init__(self, orbit: Any, state0: np.ndarray, offset_s: float) -> None:
        self.orbit, self.offset = orbit, offset_s
        self.origin = (0.0, np.asarray(state0, dtype=float))
        self.last = self.origin

    def __call__(self, time_s: float) -> np.ndarray:
        t = time_s + self.offset
        t_last, state_last = self.last if self.last[0] <= t else self.origin
        end, *_ = self.orbit.arc(state_last, t_last, t)
        self.last = (t, end)
        return end.copy()


@dataclass
class Truth:
    """The sky a closed-loop flight meets: the vehicle's arcs and the target's track."""

    vehicle: Any
    target_at: Any
    fidelity: str
    retarget_interval_s: float | None  # the phasing re-solved this often (None: never)


@dataclass(frozen=True)
class DragFit:
    """A TLE / OMM target fitted under the high-fidelity model: its state at the origin,
    its C_D A / m [m^2/kg] (fitted: the element set's drag, not the body's guess), and the
    position residuals [m] against SGP4 over the span."""

    state: np.ndarray
    ballistic_m2_kg: float
    rms_error_m: float
    max_error_m: float
    evaluations: int
    converged: bool
    reason: str | None


@dataclass(frozen=True)
class _FitReference:
    """What a drag fit matches: SGP4's positions [m] at ``times`` [s from the scenario's
    epoch], the state it starts from, the unknowns' scales and the starting C_D A / m."""

    times: np.ndarray
    r_ref: np.ndarray
    start: np.ndarray
    r_scale: float
    scale: np.ndarray
    ballistic0: float


def _fit_reference(
    orbit: HighFidelityOrbit, scenario: Scenario, settings: ForceModelSettings
) -> _FitReference:
    """SGP4's positions over the source settings' span, and the start of the fit: the
    element set's state, and the C_D A / m of its B* (the body's when B* is not positive)."""
    import math

    from ovtraj.element_sets.ephemeris import sgp4_eci

    target = scenario.target
    sources = target.source_settings
    if sources is None or not target.has_source:
        raise ConfigError(["target: a hand-typed orbit has no element set to fit"])
    limits = settings.target_fit
    span_s = sources.fit_span_h * S_PER_HOUR
    times = np.arange(math.floor(span_s / sources.fit_step_s) + 1) * sources.fit_step_s
    elements = target.elements()
    r_ref, v_ref = sgp4_eci(elements, scenario.epoch, times, omega=scenario.earth.omega)
    start = np.r_[r_ref[0], v_ref[0]]
    r_scale = float(np.linalg.norm(r_ref[0]))
    scale = np.r_[np.full(3, r_scale), np.full(3, np.linalg.norm(v_ref[0]))]
    bstar = float(elements.satrec.bstar)
    ballistic0 = (
        2.0 * bstar / limits.sgp4_reference_density
        if bstar > 0.0
        else float(orbit.propagator.parameters[2])
    )
    return _FitReference(times, r_ref, start, r_scale, scale, ballistic0)


def _fit_stopped(solution: Any, deadline: Any, max_evaluations: int) -> str | None:
    """The limit that stopped the least-squares fit, in words; None when it converged."""
    if deadline.reached:
        return deadline.reason(int(solution.nfev), "evaluations")
    if solution.status == 0:
        return f"target_fit.max_evaluations = {max_evaluations} reached"
    return None


def fit_with_drag(
    orbit: HighFidelityOrbit, scenario: Scenario, settings: ForceModelSettings
) -> DragFit:
    """The scenario's element set fitted under the high-fidelity model: the state and
    the ballistic coefficient that best match SGP4's positions over the source
    settings' span (least squares, as the J2 fit of :mod:`ovtraj.target_sources`), flown
    with the C_D A / m of the element set's B* (the body's when B* is not positive);
    with ``target_fit.fit_ballistic`` its log a seventh unknown, within
    ``ballistic_bounds``; within ``settings.target_fit``'s limits."""
    import math

    from scipy.optimize import least_squares

    from ovtraj.deadline import Deadline

    ref = _fit_reference(orbit, scenario, settings)
    limits = settings.target_fit
    times, r_ref, start, r_scale, scale = ref.times, ref.r_ref, ref.start, ref.r_scale, ref.scale
    ballistic0 = ref.ballistic0
    propagator = orbit.propagator
    tol = propagator.tol

    def positions(z: np.ndarray) -> np.ndarray:
        ballistic = ballistic0 * math.exp(z[6])
        states = propagator.grid(start + z[:6] * scale, 0.0, times, ballistic_m2_kg=ballistic)
        return states[:, :3]

    def residuals(z: np.ndarray) -> np.ndarray:
        try:
            return ((positions(z) - r_ref) / r_scale).ravel()
        except (FloatingPointError, ValueError):
            return np.full(3 * len(times), 1.0)  # a state that cannot fly: far off

    deadline = Deadline(limits.time_limit_s, "target_fit.time_limit_s of " + SOURCE)
    unknowns = 7 if limits.fit_ballistic else 6
    lower, upper = (math.log(bound) for bound in limits.ballistic_bounds)
    solution = least_squares(
        lambda z: residuals(np.r_[z, 0.0][:7]),
        np.zeros(unknowns),
        method="trf",
        diff_step=np.r_[np.full(6, math.sqrt(tol)), limits.log_ballistic_step][:unknowns],
        bounds=(
            np.r_[np.full(6, -np.inf), lower][:unknowns],
            np.r_[np.full(6, np.inf), upper][:unknowns],
        ),
        max_nfev=limits.max_evaluations,
        callback=lambda intermediate_result: deadline.stop_if_expired(),
    )
    z = np.r_[solution.x, 0.0][:7]
    reason = _fit_stopped(solution, deadline, limits.max_evaluations)
    errors = np.linalg.norm(positions(z) - r_ref, axis=1)
    return DragFit(
        state=start + z[:6] * scale,
        ballistic_m2_kg=ballistic0 * math.exp(float(z[6])),
        rms_error_m=float(np.sqrt(np.mean(errors**2))),
        max_error_m=float(errors.max()),
        evaluations=int(solution.nfev),
        converged=reason is None,
        reason=reason,
    )


_FITS: dict[str, DragFit] = {}


def target_sky(
    scenario: Scenario, settings: ForceModelSettings, state0: np.ndarray
) -> tuple[HighFidelityOrbit, np.ndarray]:
    """The target's orbit under the high-fidelity model and its state at the scenario's
    epoch: ``state0`` (the hand-typed elements) with the body's figures, or, for a TLE /
    OMM target, the element set fitted with drag (:func:`fit_with_drag`, once per
    process and input) with its fitted C_D A / m. :class:`ConfigError` when that fit
    stops at a limit (a target that depends on the machine's speed is not flown)."""
    factors = spacecraft_factors(scenario, "target")
    orbit = HighFidelityOrbit(scenario, settings, scenario.epoch, factors)
    if not scenario.target.has_source:
        return orbit, state0
    key = json.dumps(
        {"scenario": scenario.resolved(), "force_model": settings.model_dump(mode="json")},
        sort_keys=True,
    )
    fit = _FITS.get(key)
    if fit is None:
        fit = fit_with_drag(orbit, scenario, settings)
        if not fit.converged:
            raise ConfigError(
                [f"target: the high-fidelity fit to SGP4 stopped: {fit.reason}"], SOURCE
            )
        _FITS[key] = fit
    fitted = SpacecraftFactors(fit.ballistic_m2_kg, factors.radiation_m2_kg)
    return HighFidelityOrbit(scenario, settings, scenario.epoch, fitted), fit.state.copy()
