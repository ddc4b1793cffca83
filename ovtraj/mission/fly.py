"""Replay of a mission plan through the dynamics, independently of the solvers (SPEC step 6).

:func:`fly_plan` starts at the carrier's drop and flies every planned manoeuvre
open-loop, with nothing but the plan (its resolved scenario included):

0. the ascent from the drop to insertion: the plan's ten programme variables through
   the launch stage's own 3-DOF model and fixed-step RK4 (``ovtraj.launch.ascent``,
   whose scheme ``tests/test_launch_dynamics.py`` checks against DOP853), timed from
   the plan's drop epoch; the insertion it reaches is compared with the plan's, and
   the orbital phase continues from the flown insertion, not the planned one;
1. orbital arcs under point-mass + J2 gravity, integrated with scipy's DOP853 on a
   right-hand side written here (the chain uses heyoka's Taylor integrator and the
   shared gravity module); each planned ECI impulse is added at its epoch
   (rendezvous 1 and 2, transfer 1 and 2, deorbit);
2. the arrival miss at the target after the rendezvous: the target is propagated
   the same way from the scenario's elements;
3. after the deorbit burn, the descent to the entry interface altitude (an
   integration event), then the conversion to the Earth-relative entry state
   (written here too: GMST rotation, relative velocity, heading and path angle);
4. the reentry, open-loop: the plan's bank magnitude law and its sign schedule
   (initial sign and reversal times), through the reentry's own equations of
   motion, aerodynamics and atmosphere (``ovtraj.reentry.dynamics``, the same
   physical model) but integrated with adaptive DOP853 between the reversal times
   instead of the chain's fixed-step RK4 with its heading-corridor feedback; it
   stops at the terminal speed, as the reentry stage does.

:func:`replay_ephemeris` flies the same replay and also samples it: one
:class:`EphemerisSegment` per continuous arc (split at every impulse, at the entry
interface and at every bank reversal), in the project's ECI (TEME, docs/conventions.md),
the source of the CCSDS export (:mod:`ovtraj.mission.ccsds`).

The :class:`FlightReport` holds the terminal state, the miss from the landing site
and from the plan's predicted terminal point, the rendezvous arrival miss, the path
maxima against their limits, the perigee and entry-angle checks and
``landed_within_stated_miss``. A replay that cannot be flown is a report marked
failed with the reason: nothing raises out of :func:`fly_plan`, and no value in the
report is NaN (values not reached are ``None``).
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from ovtraj.astro.angles import TWO_PI, wrap_to_pi
from ovtraj.astro.elements import eccentricity_vector_from_dots, perigee_radius
from ovtraj.astro.frames import (
    ecef_to_eci,
    ecef_to_eci_state,
    great_circle_distance,
    spherical_to_ecef_state,
)
from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.formatting import duration, number, utc
from ovtraj.launch.ascent import simulate
from ovtraj.launch.frame import launch_frame_axes, launch_to_ecef
from ovtraj.launch.inputs import launch_input
from ovtraj.launch.result import trajectory_table
from ovtraj.launch.stage import ascent_model, launch_problem
from ovtraj.mission.plan import MissionPlan, PlannedImpulse
from ovtraj.reentry import EntryState, reentry_input
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry.model import EntryModel
from ovtraj.store.records import plain
from ovtraj.target_state import target_state
from ovtraj.version import code_version

INTEGRATORS = (
    "ascent: the launch stage's 3-DOF model and fixed-step RK4 (ovtraj.launch.ascent) from "
    "the drop with the plan's programme; "
    "orbit: scipy DOP853 on this module's J2 right-hand side (chain: heyoka Taylor); "
    "entry: scipy DOP853 between the planned bank reversals, open-loop (chain: fixed-step "
    "RK4 with the heading-corridor reversal logic)"
)


class ReplayFailed(Exception):
    """Raised inside the replay to stop with a reason; never escapes :func:`fly_plan`."""


class Perturbation:
    """What a dispersed flight changes in the replay (``ovtraj.mission.montecarlo``); this
    base class changes nothing (the nominal replay)."""

    def ascent(self, inp: Any) -> Any:
        """The launch input the ascent is flown with (its launcher and drop)."""
        return inp

    def burn(self, index: int, dv_eci_mps: np.ndarray) -> np.ndarray:
        """The impulse executed for the ``index``-th planned one (time order)."""
        return dv_eci_mps

    def entry(self, model: EntryModel) -> EntryModel:
        """The entry model the truth is flown with (atmosphere and aerodynamics)."""
        return model


NOMINAL = Perturbation()


@dataclass
class LimitCheck:
    """A replayed maximum (or minimum) against its limit."""

    value: float | None
    limit: float
    unit: str
    ok: bool


@dataclass
class BurnReplay:
    """A planned impulse as the replay applied it."""

    name: str
    t_s: float
    dv_mps: float
    # RSW components of the planned ECI impulse at the replay's state, minus the plan's.
    local_frame_difference_mps: float


@dataclass
class FlightReport:
    """Outcome of :func:`fly_plan`; SI units in the names, angles in degrees."""

    ok: bool  # the replay reached the terminal interface
    reason: str | None
    landed_within_stated_miss: bool
    stated_miss_m: float | None
    start: str = "drop"  # where the replay starts: the carrier's drop
    miss_distance_m: float | None = None  # from the landing site
    predicted_miss_distance_m: float | None = None  # the plan's
    prediction_distance_m: float | None = None  # from the plan's predicted terminal point
    prediction_tolerance_m: float | None = None
    matches_prediction: bool = False
    terminal_status: str | None = None
    terminal: dict[str, Any] | None = None
    # The flown ascent's insertion against the plan's (position, velocity, time, altitude,
    # speed): what the open-loop orbital phase inherits.
    insertion: dict[str, Any] | None = None
    entry: dict[str, Any] | None = None
    entry_time_difference_s: float | None = None  # replay minus plan
    entry_position_difference_m: float | None = None
    rendezvous_arrival_miss_m: float | None = None
    planned_arrival_miss_m: float | None = None
    arrival_miss_tolerance_m: float | None = None
    checks: dict[str, LimitCheck] = field(default_factory=dict)
    burns: list[BurnReplay] = field(default_factory=list)
    flight_time_s: float | None = None
    passed: bool = False  # landed within the stated miss, matches the prediction, checks hold
    plan_code_version: str | None = None
    replay_code_version: str = ""
    integrators: str = INTEGRATORS
    wall_time_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly; a non-finite number (never expected) becomes ``None``."""
        return plain(asdict(self))


@dataclass(frozen=True)
class EphemerisSegment:
    """One continuous arc of the replayed trajectory in the project's ECI (TEME).

    ``t_s``: (N,) seconds from the plan's launch day 0 h UTC, increasing, the arc's two
    ends included; ``r_eci_m`` [m] and ``v_eci_mps`` [m/s]: (N, 3).
    """

    name: str
    t_s: NDArray[np.float64]
    r_eci_m: NDArray[np.float64]
    v_eci_mps: NDArray[np.float64]


class _Recorder:
    """Samples the replay's arcs every ``orbit_step_s`` (orbits) and ``entry_step_s``."""

    def __init__(self, orbit_step_s: float, entry_step_s: float) -> None:
        self.orbit_step_s = orbit_step_s
        self.entry_step_s = entry_step_s
        self.segments: list[EphemerisSegment] = []

    @staticmethod
    def times(t0: float, t1: float, step: float) -> NDArray[np.float64]:
        """Every ``step`` from ``t0``, and ``t1`` (the entry's arcs)."""
        return np.unique(np.r_[np.arange(t0, t1, step), t1])

    @staticmethod
    def even_times(t0: float, t1: float, step: float) -> NDArray[np.float64]:
        """``t0`` to ``t1`` in equal intervals of at most ``step`` (the orbital arcs): a last
        interval of a few seconds beside 60 s ones makes the file's degree-7 Hermite fit of
        the arc before it ill-conditioned (0.33 m mid-interval against ~2 mm elsewhere, a
        2.3 s last interval measured 2026-12-04, docs/export.md)."""
        intervals = max(1, math.ceil((t1 - t0) / step - 1e-9))
        return np.linspace(t0, t1, intervals + 1)

    def add(self, name: str, t: NDArray, r: NDArray, v: NDArray) -> None:
        if len(t) >= 2:  # a zero-length arc (e.g. no stay) is no segment
            self.segments.append(EphemerisSegment(name, t, r, v))


# --- orbital arcs ------------------------------------------------------------------------


def _j2_rhs(mu: float, radius: float, j2: float) -> Any:
    """d/dt (r, v) under point mass + J2 (Vallado, 4th ed., eq. 8-30), Python floats."""
    k = 1.5 * j2 * mu * radius * radius

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        x, yy, z = float(y[0]), float(y[1]), float(y[2])
        r2 = x * x + yy * yy + z * z
        r = math.sqrt(r2)
        central = mu / (r2 * r)
        zonal = k / (r2 * r2 * r)
        s = 5.0 * z * z / r2
        return np.array(
            [
                y[3],
                y[4],
                y[5],
                -central * x - zonal * x * (1.0 - s),
                -central * yy - zonal * yy * (1.0 - s),
                -central * z - zonal * z * (3.0 - s),
            ]
        )

    return rhs


class ReplayOrbit:
    """DOP853 arcs of one spacecraft with the replay's tolerances."""

    def __init__(self, scenario: Scenario) -> None:
        earth = scenario.earth
        self.earth = earth
        self.rhs = _j2_rhs(earth.mu, earth.radius, earth.j2)
        self.rtol = scenario.mission.plan.orbit_rtol
        self.atol = scenario.mission.plan.orbit_atol

    def arc(
        self,
        state: np.ndarray,
        t0: float,
        t1: float,
        *,
        floor_m: float | None = None,
        record: tuple[_Recorder, str] | None = None,
    ) -> tuple[np.ndarray, float, bool, float]:
        """(state at the end, end time, stopped at ``floor_m``, lowest altitude on the way).

        With ``floor_m`` the arc stops where the altitude first falls through it. With
        ``record`` (a recorder and the arc's name) the arc is sampled into the recorder.
        """
        events = None
        if floor_m is not None:
            floor_r = self.earth.radius + floor_m

            def crossing(_t: float, y: np.ndarray) -> float:
                return math.sqrt(float(y[0] ** 2 + y[1] ** 2 + y[2] ** 2)) - floor_r

            crossing.terminal = True
            crossing.direction = -1.0
            events = [crossing]
        if t1 <= t0:
            if t1 < t0:
                raise ReplayFailed(f"the plan's epochs run backwards ({t0:.3f} -> {t1:.3f} s)")
            return state.copy(), t0, False, _altitude(state, self.earth.radius)
        sol = solve_ivp(
            self.rhs,
            (t0, t1),
            state,
            method="DOP853",
            rtol=self.rtol,
            atol=self.atol,
            events=events,
            dense_output=record is not None,
        )
        if sol.status < 0 or not np.all(np.isfinite(sol.y)):
            raise ReplayFailed(f"orbit integration failed from {t0:.1f} s: {sol.message}")
        lowest = float(np.min(np.linalg.norm(sol.y[:3], axis=0))) - self.earth.radius
        if sol.status == 1 and floor_m is not None and len(sol.t_events[0]):
            end, t_end, stopped = sol.y_events[0][0].copy(), float(sol.t_events[0][0]), True
        else:
            end, t_end, stopped = sol.y[:, -1].copy(), float(sol.t[-1]), False
        if record is not None:
            recorder, name = record
            times = recorder.even_times(t0, t_end, recorder.orbit_step_s)
            states = sol.sol(times).T
            states[-1] = end  # the arc's end exactly (an event's root, not the interpolant)
            recorder.add(name, times, states[:, :3], states[:, 3:])
        return end, t_end, stopped, lowest


def _altitude(state: np.ndarray, radius: float) -> float:
    return float(np.linalg.norm(state[:3])) - radius


def _rsw(dv: np.ndarray, state: np.ndarray) -> np.ndarray:
    """RSW components (radial, along-track, cross-track) of ``dv`` at ``state``."""
    r, v = state[:3], state[3:]
    radial = r / np.linalg.norm(r)
    h = np.cross(r, v)
    cross_track = h / np.linalg.norm(h)
    along = np.cross(cross_track, radial)
    return np.array([dv @ radial, dv @ along, dv @ cross_track])


def _perigee_altitude(state: np.ndarray, mu: float, radius: float) -> float:
    """Osculating two-body perigee altitude [m] of a Cartesian state."""
    r, v = state[:3], state[3:]
    rn = float(np.linalg.norm(r))
    v_sq = float(v @ v)
    energy = 0.5 * v_sq - mu / rn
    a = -mu / (2.0 * energy)
    e_vec = eccentricity_vector_from_dots(r, v, rn, v_sq, float(r @ v), mu)
    return perigee_radius(a, float(np.linalg.norm(e_vec))) - radius


# --- entry state and reentry --------------------------------------------------------------


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
    heading = math.atan2(float(v_rel @ east), float(v_rel @ north)) % TWO_PI
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
class _EntryFlight:
    status: str
    reached: bool
    time_s: float
    state: np.ndarray
    max_heat_rate_w_m2: float
    max_load_g: float
    max_dynamic_pressure_pa: float


def _fly_entry(
    plan: MissionPlan,
    scenario: Scenario,
    entry: EntryState,
    record: tuple[_Recorder, Any] | None = None,
    perturbation: Perturbation = NOMINAL,
) -> _EntryFlight:
    """The open-loop reentry from ``entry`` with the plan's bank profile (DOP853).

    ``record``: a recorder and a function of (seconds from the entry interface, rows of
    the entry state) returning the times from the launch day, ECI positions and
    velocities; every interval between reversals is sampled into its own segment.
    """
    profile = plan.reentry.bank_profile
    settings = scenario.mission.plan
    model = perturbation.entry(EntryModel(reentry_input(scenario, entry=entry)))
    p = model.params.copy()
    p[dyn.P_SIGMA0] = math.radians(profile.sigma0_deg)
    p[dyn.P_SIGMA1] = math.radians(profile.sigma1_deg)
    p[dyn.P_V_START] = profile.speed_start_mps
    p[dyn.P_V_END] = profile.speed_end_mps
    p[dyn.P_SIGMA_MAX] = math.radians(profile.max_bank_deg)
    packed = dyn.pack(p, model.tables)  # once: the right-hand side runs thousands of times
    radius = p[dyn.P_RADIUS]

    def rhs_for(sign: float) -> Any:
        def rhs(_t: float, x: np.ndarray) -> np.ndarray:
            return np.array(
                dyn.derivatives_packed(np.ascontiguousarray(x, dtype=float), sign, packed)
            )

        return rhs

    def terminal_speed(_t: float, x: np.ndarray) -> float:
        return float(x[3]) - p[dyn.P_V_END]

    def ground(_t: float, x: np.ndarray) -> float:
        return float(x[0]) - radius

    def skip(_t: float, x: np.ndarray) -> float:
        return float(x[0]) - p[dyn.P_SKIP_RADIUS]

    for event, direction in ((terminal_speed, -1.0), (ground, -1.0), (skip, 1.0)):
        event.terminal = True
        event.direction = direction
    names = ("terminal", "crashed", "skipped")

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
        sol = solve_ivp(
            rhs_for(sign),
            (t0, t1),
            x,
            method="DOP853",
            rtol=settings.entry_rtol,
            atol=settings.entry_atol,
            events=[terminal_speed, ground, skip],
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
        if record is not None:
            recorder, to_eci = record
            times = recorder.times(t0, t_end, recorder.entry_step_s)
            states = sol.sol(times).T
            states[-1] = x
            recorder.add(
                f"entry, bank sign {sign:+.0f} ({t0:.1f} to {t_end:.1f} s from the interface)",
                *to_eci(times, states),
            )
        samples = np.unique(np.r_[np.arange(t0, t_end, settings.path_sample_step_s), t_end])
        for t in samples:
            state = x if t == t_end else sol.sol(t)
            _, _, _, heat, load, qdyn = dyn.path_packed(
                np.ascontiguousarray(state, dtype=float), packed
            )
            maxima = np.maximum(maxima, (heat, load, qdyn))
        if hit is not None:
            reached = hit == 0
            status = (
                "reached the terminal speed"
                if reached
                else dyn.STATUS_TEXT[dyn.CRASHED if hit == 1 else dyn.SKIPPED]
            )
            if not reached:
                status = f"{names[hit]}: {status}"
            break
    return _EntryFlight(
        status=status,
        reached=reached,
        time_s=t_end,
        state=x,
        max_heat_rate_w_m2=float(maxima[0]),
        max_load_g=float(maxima[1]),
        max_dynamic_pressure_pa=float(maxima[2]),
    )


# --- the replay ----------------------------------------------------------------------------


def fly_plan(
    plan: MissionPlan,
    recorder: _Recorder | None = None,
    perturbation: Perturbation = NOMINAL,
) -> FlightReport:
    """Replay ``plan`` through the dynamics; see the module notes. Never raises.

    ``recorder``: samples the trajectory (:func:`replay_ephemeris`); ``perturbation``:
    the errors of a dispersed open-loop flight (:mod:`ovtraj.mission.montecarlo`)."""
    start = time.perf_counter()
    report = FlightReport(
        ok=False,
        reason=None,
        landed_within_stated_miss=False,
        stated_miss_m=plan.terminal.stated_miss_m,
        predicted_miss_distance_m=plan.terminal.miss_distance_m,
        prediction_tolerance_m=plan.terminal.prediction_tolerance_m,
        planned_arrival_miss_m=plan.rendezvous.arrival_miss_m,
        arrival_miss_tolerance_m=plan.rendezvous.miss_tolerance_m,
        plan_code_version=plan.code_version,
        replay_code_version=code_version(),
    )
    try:
        with np.errstate(all="ignore"):
            _replay(plan, report, recorder, perturbation)
    except ReplayFailed as failure:
        report.reason = str(failure)
    except Exception as err:  # a replay never raises: any failure is reported
        report.reason = f"replay failed: {type(err).__name__}: {err}"
    report.ok = report.ok and report.reason is None
    report.landed_within_stated_miss = bool(
        report.ok
        and report.miss_distance_m is not None
        and report.miss_distance_m <= plan.terminal.stated_miss_m
    )
    report.passed = bool(
        report.landed_within_stated_miss
        and report.matches_prediction
        and all(c.ok for c in report.checks.values())
    )
    report.wall_time_s = time.perf_counter() - start
    return report


def replay_ephemeris(
    plan: MissionPlan, *, orbit_step_s: float, entry_step_s: float
) -> tuple[FlightReport, list[EphemerisSegment]]:
    """The replay of :func:`fly_plan` and its trajectory sampled every ``orbit_step_s`` [s]
    on the orbital arcs and ``entry_step_s`` [s] in the atmosphere, both ends of every arc
    included. The segments cover what was flown: up to the failure if the report failed."""
    if not (orbit_step_s > 0.0 and entry_step_s > 0.0):
        raise ValueError(f"sampling steps must be positive, got {orbit_step_s}, {entry_step_s}")
    recorder = _Recorder(orbit_step_s, entry_step_s)
    return fly_plan(plan, recorder), recorder.segments


def _replay(
    plan: MissionPlan,
    report: FlightReport,
    recorder: _Recorder | None = None,
    perturbation: Perturbation = NOMINAL,
) -> None:
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    earth = scenario.earth
    day = plan.day
    orbit = ReplayOrbit(scenario)
    entry_altitude_m = scenario.deorbit.entry.altitude_km * 1e3
    floor_m = scenario.limits.min_perigee_altitude_km * 1e3

    # 0. the ascent from the drop to insertion
    state, t = fly_ascent(plan, scenario, report, perturbation)
    if recorder is not None:
        _record_ascent(plan, scenario, recorder)
    # 1. orbital arcs from the flown insertion, each planned impulse at its epoch
    perigee = _perigee_altitude(state, earth.mu, earth.radius)
    lowest = _altitude(state, earth.radius)
    impulses = plan.impulses()
    previous = "insertion"
    for k, burn in enumerate(impulses):
        name = f"{previous} to {burn.name}"
        state, t_end, entered, low = orbit.arc(
            state,
            t,
            burn.t_s,
            floor_m=entry_altitude_m,
            record=None if recorder is None else (recorder, name),
        )
        previous = burn.name
        lowest = min(lowest, low)
        if entered:
            raise ReplayFailed(
                f"the OV falls through the entry interface at {t_end:.0f} s, before the "
                f"{burn.name} ({burn.t_s:.0f} s)"
            )
        if burn is plan.rendezvous.burn2:  # docking: the arrival miss at the target
            report.rendezvous_arrival_miss_m = _arrival_miss(plan, scenario, orbit, state)
        report.burns.append(_apply(burn, state))
        state = state + np.r_[0.0, 0.0, 0.0, perturbation.burn(k, burn.eci)]
        t = burn.t_s
        if k < len(impulses) - 1:  # every orbit before the deorbit burn
            perigee = min(perigee, _perigee_altitude(state, earth.mu, earth.radius))
    report.checks["min_perigee_altitude_m"] = LimitCheck(
        perigee, floor_m, "m (osculating, before the deorbit burn)", perigee >= floor_m
    )
    report.checks["min_altitude_m"] = LimitCheck(
        lowest, floor_m, "m (solver steps, before the deorbit burn)", lowest >= floor_m
    )
    report.checks["rendezvous_arrival_miss_m"] = LimitCheck(
        report.rendezvous_arrival_miss_m,
        plan.rendezvous.miss_tolerance_m,
        "m",
        report.rendezvous_arrival_miss_m is not None
        and report.rendezvous_arrival_miss_m <= plan.rendezvous.miss_tolerance_m,
    )

    # 2. descent to the entry interface
    r0 = float(np.linalg.norm(state[:3]))
    period = TWO_PI * math.sqrt(r0**3 / earth.mu)
    horizon = scenario.deorbit.max_descent_revolutions * period
    state, t_entry, entered, _ = orbit.arc(
        state,
        t,
        t + horizon,
        floor_m=entry_altitude_m,
        record=None if recorder is None else (recorder, f"{previous} to the entry interface"),
    )
    if not entered:
        raise ReplayFailed(
            f"the descent does not reach the entry interface ({entry_altitude_m / 1e3:g} km) "
            f"within {horizon:.0f} s of the deorbit burn"
        )
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

    # 3. the reentry, open-loop
    entry = EntryState(
        epoch=entry_epoch,
        latitude_rad=rel["latitude_rad"],
        longitude_rad=rel["longitude_rad"],
        altitude_m=rel["altitude_m"],
        speed_mps=rel["speed_mps"],
        fpa_rad=rel["fpa_rad"],
        heading_rad=rel["heading_rad"],
    )
    entry_record = None
    if recorder is not None:

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

        entry_record = (recorder, to_eci)
    flight = _fly_entry(plan, scenario, entry, entry_record, perturbation)
    reentry = scenario.reentry
    path = reentry.limits
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
    terminal = reentry.terminal
    report.checks["terminal_altitude_m"] = LimitCheck(
        altitude,
        terminal.altitude_km * 1e3,
        f"m (+- {terminal.altitude_tolerance_km * 1e3:g})",
        abs(altitude - terminal.altitude_km * 1e3) <= terminal.altitude_tolerance_km * 1e3,
    )
    site = reentry.landing_site
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
    if not flight.reached:
        raise ReplayFailed(
            f"the replayed reentry did not reach the terminal speed: {flight.status}"
        )
    values = [report.miss_distance_m, report.prediction_distance_m, *x]
    if not all(math.isfinite(v) for v in values):
        raise ReplayFailed("the replay produced non-finite values")
    report.ok = True


def _ascent(plan: MissionPlan, scenario: Scenario) -> tuple[Any, Any, np.ndarray]:
    """The launch problem of the plan's parking altitude, its model and the SI design row."""
    inp = launch_input(scenario, altitude_km=plan.launch.parking_altitude_m / 1e3)
    problem = launch_problem(inp)
    programme = plan.launch.programme
    missing = [name for name in DESIGN_VARIABLES if name not in programme.variables]
    if missing:
        raise ReplayFailed(f"the plan's launch programme lacks {', '.join(missing)}")
    values = np.array([programme.variables[name] for name in DESIGN_VARIABLES])
    design = problem.to_si(problem.to_scaled(values))
    azimuth_difference = math.degrees(float(design[0, 0])) - programme.azimuth_deg
    if abs(azimuth_difference) > 1e-9:
        raise ReplayFailed(
            f"the programme's azimuth differs from the plan's by {azimuth_difference:.3g} deg: "
            "the plan's scenario does not pose the launch it was solved for"
        )
    return inp, problem.model, design


def fly_ascent(
    plan: MissionPlan,
    scenario: Scenario,
    report: FlightReport,
    perturbation: Perturbation = NOMINAL,
) -> tuple[np.ndarray, float]:
    """Fly the plan's programme from the drop: the ECI state (6,) [m, m/s] and time [s, on
    the plan's clock] of insertion; the ascent's insertion differences and path-limit
    checks go into ``report``. The replay's ascent and the Monte Carlo's."""
    earth = scenario.earth
    inp, model, design = _ascent(plan, scenario)
    flown = perturbation.ascent(inp)
    if flown is not inp:
        model = ascent_model(flown)
    outcome = simulate(model, design)
    if bool(outcome.crashed[0]):
        raise ReplayFailed("the replayed ascent hits the ground before insertion")
    t_ins = plan.launch.drop_t_s + float(outcome.time_s[0])
    theta = plan.day.gmst_rad() + earth.omega * t_ins
    r = np.asarray(ecef_to_eci(outcome.r_ecef[0], theta), dtype=float)
    v = np.asarray(ecef_to_eci(outcome.v_inertial_ecef_axes[0], theta), dtype=float)
    r_plan = np.asarray(plan.launch.insertion_r_eci_m, dtype=float)
    v_plan = np.asarray(plan.launch.insertion_v_eci_mps, dtype=float)
    report.insertion = {
        "t_s": t_ins,
        "time_difference_s": t_ins - plan.launch.insertion_t_s,
        "position_difference_m": float(np.linalg.norm(r - r_plan)),
        "velocity_difference_mps": float(np.linalg.norm(v - v_plan)),
        "altitude_difference_m": float(np.linalg.norm(r) - np.linalg.norm(r_plan)),
        "speed_difference_mps": float(np.linalg.norm(v) - np.linalg.norm(v_plan)),
        "payload_kg": float(outcome.payload_kg[0]),
    }
    limits = inp.launcher.limits
    slack = 1.0 + inp.tolerances.path_limit_fraction
    q_max = float(outcome.max_dynamic_pressure_pa[0])
    load_max = float(outcome.max_axial_load_g[0])
    q_limit = limits.max_dynamic_pressure_kpa * 1e3
    report.checks["ascent_max_dynamic_pressure_pa"] = LimitCheck(
        q_max,
        q_limit,
        f"Pa (counts as within up to a fraction {slack - 1:g} over it)",
        q_max <= q_limit * slack,
    )
    report.checks["ascent_max_axial_load_g"] = LimitCheck(
        load_max,
        limits.max_axial_load_g,
        f"g (counts as within up to a fraction {slack - 1:g} over it)",
        load_max <= limits.max_axial_load_g * slack,
    )
    return np.r_[r, v], t_ins


def ascent_trajectory(plan: MissionPlan, scenario: Scenario) -> pd.DataFrame:
    """The plan's ascent from the drop as the launch stage tabulates its own
    (:func:`ovtraj.launch.result.trajectory_table`: time from the drop, altitude, Earth-relative
    and inertial speed, flight-path angle, mass, dynamic pressure, axial load...): the plan's
    programme flown by the stage's model, sampled every ``launch.integration.
    trajectory_step_s`` and at each phase's ends. Raises :class:`ReplayFailed` when the
    plan's scenario does not pose the launch its programme was solved for."""
    inp, model, design = _ascent(plan, scenario)
    outcome = simulate(model, design, keep_history=True)
    axes = launch_frame_axes(model.drop.latitude_rad, model.drop.longitude_rad, float(design[0, 0]))
    return trajectory_table(
        outcome.history,
        row=0,
        axes=axes,
        earth=inp.earth,
        drop_time_s=plan.launch.drop_t_s,
        step_s=inp.integration.trajectory_step_s,
    )


def _record_ascent(plan: MissionPlan, scenario: Scenario, recorder: _Recorder) -> None:
    """The ascent as ephemeris segments in ECI, one per phase (free fall, each burn and
    coast: no segment spans a thrust discontinuity), at the RK4 step points, each
    segment ending where the next phase starts."""
    earth = scenario.earth
    _, model, design = _ascent(plan, scenario)
    outcome = simulate(model, design, keep_history=True)
    axes = launch_frame_axes(model.drop.latitude_rad, model.drop.longitude_rad, float(design[0, 0]))
    history = outcome.history
    t_flight = np.array([float(h["t"][0]) for h in history])
    states = np.array([np.asarray(h["y"])[:6, 0] for h in history])
    r_ecef, v_ecef = launch_to_ecef(states[:, :3], states[:, 3:6], axes, radius_m=earth.radius)
    t_abs = plan.launch.drop_t_s + t_flight
    theta = plan.day.gmst_rad() + earth.omega * t_abs
    r_eci, v_eci = ecef_to_eci_state(r_ecef, v_ecef, theta, omega=earth.omega)
    starts = [
        k for k in range(len(history)) if k == 0 or history[k]["phase"] != history[k - 1]["phase"]
    ]
    ends = [*starts[1:], len(history)]
    for first, end in zip(starts, ends, strict=True):
        # A phase's samples, and the next phase's first one when it is later (a phase's
        # last sample and the next one's first may be the same instant).
        points = list(range(first, end))
        if end < len(history) and t_abs[end] > t_abs[points[-1]]:
            points.append(end)
        points = np.asarray(points)
        points = points[np.r_[True, np.diff(t_abs[points]) > 0.0]]
        recorder.add(
            f"ascent: {history[first]['phase']}", t_abs[points], r_eci[points], v_eci[points]
        )


def _apply(burn: PlannedImpulse, state: np.ndarray) -> BurnReplay:
    rsw = _rsw(burn.eci, state)
    return BurnReplay(
        name=burn.name,
        t_s=burn.t_s,
        dv_mps=float(np.linalg.norm(burn.eci)),
        local_frame_difference_mps=float(np.linalg.norm(rsw - burn.rsw)),
    )


def _arrival_miss(
    plan: MissionPlan, scenario: Scenario, orbit: ReplayOrbit, chaser: np.ndarray
) -> float:
    """Distance [m] from the chaser to the target at the planned arrival (docking) epoch."""
    offset = plan.day.seconds_since(scenario.epoch)
    target0 = target_state(scenario.target.orbit, scenario)
    target, _, _, _ = orbit.arc(target0, 0.0, plan.rendezvous.burn2.t_s + offset)
    return float(np.linalg.norm(chaser[:3] - target[:3]))


# --- text ----------------------------------------------------------------------------------


def format_flight_report(report: FlightReport) -> str:
    """A few lines for the command line (:mod:`ovtraj.formatting`: units, "-" for a value
    not reached)."""
    km = 1e-3

    def scaled(value: float | None, factor: float) -> float | None:
        return None if value is None else value * factor

    verdict = (
        "LANDED within the stated miss"
        if report.landed_within_stated_miss
        else "NOT within the stated miss"
    )
    lines = [
        f"replay from the {report.start}: {'completed' if report.ok else 'FAILED'}; {verdict}"
        + ("" if report.passed or not report.ok else " (but a check failed, see below)"),
    ]
    if report.reason:
        lines.append(f"  reason: {report.reason}")
    if report.insertion:
        i = report.insertion
        lines.append(
            f"  insertion vs plan: {number(i['position_difference_m'], 'm', 3)}, "
            f"{number(i['velocity_difference_mps'], 'm/s', 3)}, "
            f"{number(i['time_difference_s'], 's', 3)} "
            f"(altitude {number(i['altitude_difference_m'], 'm', 3)}, "
            f"speed {number(i['speed_difference_mps'], 'm/s', 3)})"
        )
    lines.append(
        f"  miss from the landing site: {number(scaled(report.miss_distance_m, km), 'km')} "
        f"(stated {number(scaled(report.stated_miss_m, km), 'km')}; plan predicted "
        f"{number(scaled(report.predicted_miss_distance_m, km), 'km')})"
    )
    lines.append(
        f"  distance from the predicted terminal point: "
        f"{number(report.prediction_distance_m, 'm')} "
        f"(tolerance {number(report.prediction_tolerance_m, 'm')})"
    )
    if report.terminal:
        t = report.terminal
        lines.append(
            f"  terminal: {utc(t['epoch_utc'])}  {number(t['latitude_deg'], 'deg', 6)}, "
            f"{number(t['longitude_deg'], 'deg', 6)}, {number(t['altitude_m'] * km, 'km')}, "
            f"{number(t['speed_mps'], 'm/s')}, fpa {number(t['fpa_deg'], 'deg', 3)} "
            f"({report.terminal_status})"
        )
    if report.entry:
        e = report.entry
        lines.append(
            f"  entry: {utc(e['epoch_utc'])}  {number(e['latitude_deg'], 'deg', 6)}, "
            f"{number(e['longitude_deg'], 'deg', 6)}, {number(e['speed_mps'], 'm/s')} "
            f"relative, inertial fpa {number(e['inertial_fpa_deg'], 'deg')}; vs plan "
            f"{number(report.entry_time_difference_s, 's', 3)}, "
            f"{number(report.entry_position_difference_m, 'm', 3)}"
        )
    lines.append(
        f"  rendezvous arrival miss: {number(report.rendezvous_arrival_miss_m, 'm', 3)} "
        f"(plan {number(report.planned_arrival_miss_m, 'm', 3)}, "
        f"tolerance {number(report.arrival_miss_tolerance_m, 'm')})"
    )
    for name, check in report.checks.items():
        lines.append(
            f"  {'ok  ' if check.ok else 'FAIL'} {name}: "
            f"{number(check.value, check.unit.split(' ')[0], 6)} "
            f"(limit {number(check.limit, check.unit, 6)})"
        )
    for burn in report.burns:
        lines.append(
            f"  burn {burn.name}: {number(burn.dv_mps, 'm/s')} at {duration(burn.t_s)} "
            f"from the launch day's 0 h UTC (local frame vs plan "
            f"{number(burn.local_frame_difference_mps, 'm/s', 2)})"
        )
    lines.append(f"  replay time {duration(report.wall_time_s)}")
    return "\n".join(lines)
