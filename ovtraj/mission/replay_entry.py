"""The entry leg of a plan's replay (:mod:`ovtraj.mission.fly`): at the entry interface,
the conversion to the Earth-relative entry state (written here: GMST rotation, relative
velocity, heading and path angle), then the reentry, open-loop: the plan's bank magnitude
law and its sign schedule (initial sign and reversal times), through the reentry's own
equations of motion, aerodynamics and atmosphere (``ovtraj.reentry.dynamics``, the same
physical model) but integrated with adaptive DOP853 between the reversal times instead of
the chain's fixed-step RK4 with its heading-corridor feedback; it stops at the terminal
speed, as the reentry stage does. The terminal state, the misses and the path maxima
against their limits go into the :class:`~ovtraj.mission.flight_report.FlightReport`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ovtraj.astro.angles import wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.frames import ecef_to_eci_state, great_circle_distance, spherical_to_ecef_state
from ovtraj.config import Scenario
from ovtraj.mission.ephemeris import EphemerisRecorder
from ovtraj.mission.flight_report import FlightReport, LimitCheck, ReplayFailed
from ovtraj.mission.perturbation import NOMINAL, Perturbation
from ovtraj.mission.plan import MissionPlan
from ovtraj.reentry import EntryState, reentry_input
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry.model import EntryModel


def relative_entry(state: np.ndarray, theta: float, omega: float, radius: float) -> dict:
    """Geocentric position and Earth-relative velocity of an ECI state (spherical Earth).

    ``state`` (6,) [m, m/s], ``theta`` the Earth rotation angle [rad], ``omega`` its rate
    [rad/s], ``radius`` the Earth's [m]. Keys: latitude, longitude in [-pi, pi), flight-path
    angle, heading from north in [0, 2 pi) and the inertial flight-path angle [rad],
    altitude [m], relative and inertial speed [m/s]. The replay's entry state and the
    Monte Carlo's (:mod:`ovtraj.mission.montecarlo`).
    """
    r, v = state[:3], state[3:]
    x, y, z = (float(c) for c in r)
    rn = float(np.linalg.norm(r))
    lat = math.atan2(z, math.hypot(x, y))
    lon_inertial = math.atan2(y, x)
    lon = wrap_to_pi(lon_inertial - theta)
    v_rel = v - omega * np.array([-y, x, 0.0])
    speed = float(np.linalg.norm(v_rel))
    fpa = math.asin(float(r @ v_rel) / (rn * speed))
    north = np.array(
        [
            -math.sin(lat) * math.cos(lon_inertial),
            -math.sin(lat) * math.sin(lon_inertial),
            math.cos(lat),
        ]
    )
    east = np.array([-math.sin(lon_inertial), math.cos(lon_inertial), 0.0])
    heading = wrap_to_two_pi(math.atan2(float(v_rel @ east), float(v_rel @ north)))
    inertial_fpa = math.asin(float(r @ v) / (rn * float(np.linalg.norm(v))))
    return {
        "latitude_rad": lat,
        "longitude_rad": lon,
        "altitude_m": rn - radius,
        "speed_mps": speed,
        "fpa_rad": fpa,
        "heading_rad": heading,
        "inertial_speed_mps": float(np.linalg.norm(v)),
        "inertial_fpa_rad": inertial_fpa,
    }


@dataclass
class EntryFlight:
    """The open-loop reentry as flown: how it ended, its time from the entry interface [s],
    its last state (the reentry's state vector) and its path maxima."""

    status: str
    reached: bool
    time_s: float
    state: np.ndarray
    max_heat_rate_w_m2: float
    max_load_g: float
    max_dynamic_pressure_pa: float


# The reentry's stopping events in the order of fly_entry's event list.
_EVENT_NAMES = ("terminal", "crashed", "skipped")


def fly_entry(
    plan: MissionPlan,
    scenario: Scenario,
    entry: EntryState,
    record: tuple[EphemerisRecorder, Any] | None = None,
    perturbation: Perturbation = NOMINAL,
) -> EntryFlight:
    """The open-loop reentry from ``entry`` with the plan's bank profile (DOP853).

    ``record``: a recorder and a function of (seconds from the entry interface, rows of
    the entry state) returning the times from the launch day, ECI positions and
    velocities; every interval between reversals is sampled into its own segment.
    """
    profile = plan.reentry.bank_profile
    settings = scenario.mission.plan
    model, p, packed = _bank_model(plan, scenario, entry, perturbation)
    events = _entry_events(p)
    t_max = p[dyn.P_MAX_TIME]
    times = [r.t_from_entry_s for r in profile.reversals]
    bounds = [0.0, *(t for t in times if 0.0 < t < t_max), t_max]
    x = model.x0.copy()
    maxima = np.zeros(3)
    status = "time limit reached before the terminal speed"
    reached = False
    t_end = 0.0
    for t0, t1 in itertools.pairwise(bounds):
        if t1 <= t0:
            continue
        sign = profile.sign_at(t0)
        sol, hit, t_end, x = _fly_interval(_entry_rhs(sign, packed), events, x, t0, t1, settings)
        if record is not None:
            _record_interval(record, sol, sign, t0, t_end, x)
        step = settings.path_sample_step_s
        maxima = _path_maxima(sol, packed, maxima, t0, t_end, x, step)
        if hit is not None:
            reached = hit == 0
            status = _end_status(hit)
            break
    return EntryFlight(
        status=status,
        reached=reached,
        time_s=t_end,
        state=x,
        max_heat_rate_w_m2=float(maxima[0]),
        max_load_g=float(maxima[1]),
        max_dynamic_pressure_pa=float(maxima[2]),
    )


def _bank_model(
    plan: MissionPlan, scenario: Scenario, entry: EntryState, perturbation: Perturbation
) -> tuple[EntryModel, np.ndarray, Any]:
    """The entry model flown (the perturbation's truth), its parameters with the plan's
    bank law and their packed form for the right-hand side."""
    profile = plan.reentry.bank_profile
    model = perturbation.entry(EntryModel(reentry_input(scenario, entry=entry)))
    p = model.params.copy()
    p[dyn.P_SIGMA0] = math.radians(profile.sigma0_deg)
    p[dyn.P_SIGMA1] = math.radians(profile.sigma1_deg)
    p[dyn.P_V_START] = profile.speed_start_mps
    p[dyn.P_V_END] = profile.speed_end_mps
    p[dyn.P_SIGMA_MAX] = math.radians(profile.max_bank_deg)
    packed = dyn.pack(p, model.tables)  # once: the right-hand side runs thousands of times
    return model, p, packed


def _entry_rhs(sign: float, packed: Any) -> Any:
    """The reentry's equations of motion with the bank sign held at ``sign``."""

    def rhs(_t: float, x: np.ndarray) -> np.ndarray:
        return np.array(dyn.derivatives_packed(np.ascontiguousarray(x, dtype=float), sign, packed))

    return rhs


def _entry_events(p: np.ndarray) -> list[Any]:
    """The terminal events in :data:`_EVENT_NAMES` order: the terminal speed reached
    (falling), the ground reached, the skip-out radius passed (rising)."""
    radius = p[dyn.P_RADIUS]

    def terminal_speed(_t: float, x: np.ndarray) -> float:
        return float(x[3]) - p[dyn.P_V_END]

    def ground(_t: float, x: np.ndarray) -> float:
        return float(x[0]) - radius

    def skip(_t: float, x: np.ndarray) -> float:
        return float(x[0]) - p[dyn.P_SKIP_RADIUS]

    for event, direction in ((terminal_speed, -1.0), (ground, -1.0), (skip, 1.0)):
        event.terminal = True
        event.direction = direction
    return [terminal_speed, ground, skip]


def _fly_interval(
    rhs: Any, events: list[Any], x: np.ndarray, t0: float, t1: float, settings: Any
) -> tuple[Any, int | None, float, np.ndarray]:
    """One interval between bank reversals from ``x`` at ``t0`` to ``t1`` [s from the entry
    interface]: the solution, the index of the event that stopped it (or None), the end
    time and state."""
    sol = solve_ivp(
        rhs,
        (t0, t1),
        x,
        method="DOP853",
        rtol=settings.entry_rtol,
        atol=settings.entry_atol,
        events=events,
        dense_output=True,
    )
    if sol.status < 0 or not np.all(np.isfinite(sol.y)):
        raise ReplayFailed(f"entry integration failed at {t0:.1f} s: {sol.message}")
    t_end = float(sol.t[-1])
    hit = next((k for k, times in enumerate(sol.t_events) if len(times)), None)
    if hit is not None:
        t_end = float(sol.t_events[hit][0])
        x = sol.y_events[hit][0].copy()
    else:
        x = sol.y[:, -1].copy()
    return sol, hit, t_end, x


def _record_interval(
    record: tuple[EphemerisRecorder, Any],
    sol: Any,
    sign: float,
    t0: float,
    t_end: float,
    x: np.ndarray,
) -> None:
    """The interval sampled into its own segment, ending exactly at ``x``."""
    recorder, to_eci = record
    times = recorder.times(t0, t_end, recorder.entry_step_s)
    states = sol.sol(times).T
    states[-1] = x
    recorder.add(
        f"entry, bank sign {sign:+.0f} ({t0:.1f} to {t_end:.1f} s from the interface)",
        *to_eci(times, states),
    )


def _path_maxima(
    sol: Any,
    packed: Any,
    maxima: np.ndarray,
    t0: float,
    t_end: float,
    x: np.ndarray,
    step: float,
) -> np.ndarray:
    """``maxima`` (heat rate, load, dynamic pressure) raised by the interval's samples
    every ``step`` [s] and at its end."""
    samples = np.unique(np.r_[np.arange(t0, t_end, step), t_end])
    for t in samples:
        state = x if t == t_end else sol.sol(t)
        _, _, _, heat, load, qdyn = dyn.path_packed(
            np.ascontiguousarray(state, dtype=float), packed
        )
        maxima = np.maximum(maxima, (heat, load, qdyn))
    return maxima


def _end_status(hit: int) -> str:
    """How the reentry ended at the ``hit``-th event."""
    reached = hit == 0
    status = (
        "reached the terminal speed"
        if reached
        else dyn.STATUS_TEXT[dyn.CRASHED if hit == 1 else dyn.SKIPPED]
    )
    if not reached:
        status = f"{_EVENT_NAMES[hit]}: {status}"
    return status


def entry_interface(
    plan: MissionPlan, scenario: Scenario, report: FlightReport, state: np.ndarray, t_entry: float
) -> tuple[EntryState, float]:
    """The Earth-relative entry state of the ECI ``state`` (6,) [m, m/s] reached at
    ``t_entry`` [s, the plan's clock], and the Earth rotation angle there [rad]; the entry,
    its difference from the plan's and the entry-angle check go into ``report``."""
    earth = scenario.earth
    day = plan.day
    theta = day.gmst_rad() + earth.omega * t_entry
    rel = relative_entry(state, theta, earth.omega, earth.radius)
    planned = plan.reentry.entry
    report.entry_time_difference_s = t_entry - planned.t_s
    report.entry_position_difference_m = float(
        np.linalg.norm(state[:3] - np.asarray(planned.r_eci_m))
    )
    entry_epoch = day.plus_seconds(t_entry)
    report.entry = {
        "epoch_utc": entry_epoch.iso(),
        "t_s": t_entry,
        "latitude_deg": math.degrees(rel["latitude_rad"]),
        "longitude_deg": math.degrees(rel["longitude_rad"]),
        "altitude_m": rel["altitude_m"],
        "speed_mps": rel["speed_mps"],
        "fpa_deg": math.degrees(rel["fpa_rad"]),
        "heading_deg": math.degrees(rel["heading_rad"]),
        "inertial_speed_mps": rel["inertial_speed_mps"],
        "inertial_fpa_deg": math.degrees(rel["inertial_fpa_rad"]),
    }
    limits = scenario.deorbit.entry
    slack = scenario.mission.plan.entry_fpa_tolerance_deg
    fpa = report.entry["inertial_fpa_deg"]
    report.checks["entry_fpa_deg"] = LimitCheck(
        fpa,
        limits.fpa_max_deg,
        f"deg (inertial; allowed [{limits.fpa_min_deg:g}, {limits.fpa_max_deg:g}] +- {slack:g})",
        limits.fpa_min_deg - slack <= fpa <= limits.fpa_max_deg + slack,
    )
    entry = EntryState(
        epoch=entry_epoch,
        latitude_rad=rel["latitude_rad"],
        longitude_rad=rel["longitude_rad"],
        altitude_m=rel["altitude_m"],
        speed_mps=rel["speed_mps"],
        fpa_rad=rel["fpa_rad"],
        heading_rad=rel["heading_rad"],
    )
    return entry, theta


def entry_to_eci(earth: EarthModel, theta: float, t_entry: float) -> Any:
    """The function of (seconds from the entry interface (N,), reentry states (N, 6)) that
    gives the times from the launch day [s] and ECI positions [m] and velocities [m/s]:
    ``theta`` is the Earth rotation angle [rad] at the interface, ``t_entry`` its time."""

    def to_eci(t_from_entry: NDArray, x: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        r_ecef, v_ecef = spherical_to_ecef_state(
            x[:, 2],
            x[:, 1],
            x[:, 0] - earth.radius,
            x[:, 3],
            x[:, 4],
            x[:, 5],
            radius=earth.radius,
        )
        angle = theta + earth.omega * t_from_entry
        return (
            t_entry + t_from_entry,
            *ecef_to_eci_state(r_ecef, v_ecef, angle, omega=earth.omega),
        )

    return to_eci


def report_terminal(
    plan: MissionPlan,
    scenario: Scenario,
    report: FlightReport,
    flight: EntryFlight,
    entry_epoch: Epoch,
    t_entry: float,
) -> None:
    """The reentry's path maxima, terminal state and misses into ``report``; fails when it
    did not reach the terminal speed or left a non-finite value."""
    earth = scenario.earth
    _path_checks(scenario, report, flight)
    x = flight.state
    report.flight_time_s = flight.time_s
    report.terminal_status = flight.status
    altitude = float(x[0]) - earth.radius
    report.terminal = {
        "epoch_utc": entry_epoch.plus_seconds(flight.time_s).iso(),
        "t_s": t_entry + flight.time_s,
        "latitude_deg": math.degrees(float(x[2])),
        "longitude_deg": math.degrees(wrap_to_pi(float(x[1]))),
        "altitude_m": altitude,
        "speed_mps": float(x[3]),
        "fpa_deg": math.degrees(float(x[4])),
        "heading_deg": math.degrees(float(x[5])) % 360.0,
    }
    terminal = scenario.reentry.terminal
    report.checks["terminal_altitude_m"] = LimitCheck(
        altitude,
        terminal.altitude_km * 1e3,
        f"m (+- {terminal.altitude_tolerance_km * 1e3:g})",
        abs(altitude - terminal.altitude_km * 1e3) <= terminal.altitude_tolerance_km * 1e3,
    )
    _misses(plan, scenario, report, x)
    if not flight.reached:
        raise ReplayFailed(
            f"the replayed reentry did not reach the terminal speed: {flight.status}"
        )
    values = [report.miss_distance_m, report.prediction_distance_m, *x]
    if not all(math.isfinite(v) for v in values):
        raise ReplayFailed("the replay produced non-finite values")


def _path_checks(scenario: Scenario, report: FlightReport, flight: EntryFlight) -> None:
    """The reentry's heat rate, load and dynamic pressure maxima against their limits."""
    path = scenario.reentry.limits
    for name, value, limit, unit in (
        ("max_heat_rate_w_m2", flight.max_heat_rate_w_m2, path.max_heat_rate_kw_m2 * 1e3, "W/m^2"),
        ("max_load_g", flight.max_load_g, path.max_load_g, "g"),
        (
            "max_dynamic_pressure_pa",
            flight.max_dynamic_pressure_pa,
            path.max_dynamic_pressure_kpa * 1e3,
            "Pa",
        ),
    ):
        report.checks[name] = LimitCheck(value, limit, unit, value <= limit)


def _misses(plan: MissionPlan, scenario: Scenario, report: FlightReport, x: np.ndarray) -> None:
    """The terminal state ``x``'s distances [m] from the landing site and from the plan's
    predicted terminal point, and whether the latter is within the prediction tolerance."""
    earth = scenario.earth
    site = scenario.reentry.landing_site
    lat, lon = float(x[2]), float(x[1])
    report.miss_distance_m = great_circle_distance(
        lat,
        lon,
        math.radians(site.latitude_deg),
        math.radians(site.longitude_deg),
        radius=earth.radius,
    )
    predicted = plan.terminal
    report.prediction_distance_m = great_circle_distance(
        lat,
        lon,
        math.radians(predicted.latitude_deg),
        math.radians(predicted.longitude_deg),
        radius=earth.radius,
    )
    report.matches_prediction = report.prediction_distance_m <= predicted.prediction_tolerance_m
