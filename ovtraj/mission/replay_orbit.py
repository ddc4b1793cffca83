"""The orbital phase of a plan's replay (:mod:`ovtraj.mission.fly`): from the flown
insertion, arcs under point-mass + J2 gravity integrated with scipy's DOP853 on a
right-hand side written here (the chain uses heyoka's Taylor integrator and the shared
gravity module), each planned ECI impulse added at its epoch (rendezvous 1 and 2,
transfer 1 and 2, deorbit); the arrival miss at the target after the rendezvous (the
target propagated the same way from the scenario's elements); after the deorbit burn, the
descent to the entry interface altitude (an integration event).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from ovtraj.astro.elements import (
    eccentricity_vector_from_dots,
    orbital_period,
    perigee_radius,
)
from ovtraj.config import Scenario
from ovtraj.mission.ephemeris import EphemerisRecorder
from ovtraj.mission.flight_report import BurnReplay, FlightReport, LimitCheck, ReplayFailed
from ovtraj.mission.perturbation import NOMINAL, Perturbation
from ovtraj.mission.plan import MissionPlan, PlannedImpulse
from ovtraj.target_state import target_state


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
        record: tuple[EphemerisRecorder, str] | None = None,
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
            return state.copy(), t0, False, altitude(state, self.earth.radius)
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


def altitude(state: np.ndarray, radius: float) -> float:
    """Distance [m] of a Cartesian state (6,) [m, m/s] above a sphere of ``radius`` [m]."""
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


def fly_impulses(
    plan: MissionPlan,
    scenario: Scenario,
    orbit: ReplayOrbit,
    report: FlightReport,
    state: np.ndarray,
    t: float,
    recorder: EphemerisRecorder | None = None,
    perturbation: Perturbation = NOMINAL,
) -> tuple[np.ndarray, float, str]:
    """Fly from the insertion ``state`` (6,) [m, m/s] at ``t`` [s, the plan's clock] with
    each planned impulse at its epoch: the state just after the deorbit burn, its time and
    the last burn's name. The arrival miss at docking, each burn as applied and the
    perigee, altitude and arrival checks go into ``report``."""
    earth = scenario.earth
    entry_altitude_m = scenario.deorbit.entry.altitude_km * 1e3
    perigee = _perigee_altitude(state, earth.mu, earth.radius)
    lowest = altitude(state, earth.radius)
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
    _orbit_checks(plan, scenario, report, perigee, lowest)
    return state, t, previous


def _orbit_checks(
    plan: MissionPlan, scenario: Scenario, report: FlightReport, perigee: float, lowest: float
) -> None:
    """The lowest perigee and altitude [m] before the deorbit burn against the floor, and
    the rendezvous arrival miss against its tolerance."""
    floor_m = scenario.limits.min_perigee_altitude_km * 1e3
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


def descend(
    scenario: Scenario,
    orbit: ReplayOrbit,
    state: np.ndarray,
    t: float,
    previous: str,
    recorder: EphemerisRecorder | None = None,
) -> tuple[np.ndarray, float]:
    """From just after the deorbit burn (``previous``) down to the entry interface altitude:
    the ECI state (6,) [m, m/s] and time [s] there; fails when the descent does not reach
    it within ``deorbit.max_descent_revolutions`` periods."""
    earth = scenario.earth
    entry_altitude_m = scenario.deorbit.entry.altitude_km * 1e3
    r0 = float(np.linalg.norm(state[:3]))
    period = float(orbital_period(r0, mu=earth.mu))
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
    return state, t_entry


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
