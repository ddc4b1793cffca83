"""Replay of a mission plan through the dynamics, independently of the solvers (SPEC step 6).

:func:`fly_plan` starts at the carrier's drop and flies every planned manoeuvre
open-loop, with nothing but the plan (its resolved scenario included):

0. the ascent from the drop to insertion (:mod:`.replay_ascent`): the plan's ten programme
   variables through the launch stage's own 3-DOF model and fixed-step RK4, timed from
   the plan's drop epoch; the orbital phase continues from the flown insertion, not the
   planned one;
1. orbital arcs under point-mass + J2 gravity with each planned ECI impulse added at its
   epoch (:mod:`.replay_orbit`: scipy's DOP853 on its own right-hand side);
2. the arrival miss at the target after the rendezvous, the target propagated the same way;
3. after the deorbit burn, the descent to the entry interface altitude, then the
   conversion to the Earth-relative entry state (:mod:`.replay_entry`);
4. the reentry, open-loop with the plan's bank profile, through the reentry's own
   physical model integrated with adaptive DOP853 between the reversal times
   (:mod:`.replay_entry`); it stops at the terminal speed, as the reentry stage does.

:func:`replay_ephemeris` flies the same replay and also samples it: one
:class:`~ovtraj.mission.ephemeris.EphemerisSegment` per continuous arc (split at every
impulse, at the entry interface and at every bank reversal), in the project's ECI (TEME,
docs/conventions.md), the source of the CCSDS export (:mod:`ovtraj.mission.ccsds`).

The :class:`~ovtraj.mission.flight_report.FlightReport` holds the terminal state, the
misses, the path maxima against their limits and ``landed_within_stated_miss``. A replay
that cannot be flown is a report marked failed with the reason: nothing raises out of
:func:`fly_plan`, and no value in the report is NaN (values not reached are ``None``).
"""

from __future__ import annotations

import time

import numpy as np

from ovtraj.config import scenario_from_dict
from ovtraj.mission.ephemeris import EphemerisRecorder, EphemerisSegment
from ovtraj.mission.flight_report import FlightReport, ReplayFailed
from ovtraj.mission.perturbation import NOMINAL, Perturbation
from ovtraj.mission.plan import MissionPlan
from ovtraj.mission.replay_ascent import fly_ascent, record_ascent
from ovtraj.mission.replay_entry import entry_interface, entry_to_eci, fly_entry, report_terminal
from ovtraj.mission.replay_orbit import ReplayOrbit, descend, fly_impulses
from ovtraj.version import code_version


def fly_plan(
    plan: MissionPlan,
    recorder: EphemerisRecorder | None = None,
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
    recorder = EphemerisRecorder(orbit_step_s, entry_step_s)
    return fly_plan(plan, recorder), recorder.segments


def _replay(
    plan: MissionPlan,
    report: FlightReport,
    recorder: EphemerisRecorder | None = None,
    perturbation: Perturbation = NOMINAL,
) -> None:
    """The replay leg by leg, each filling ``report``; raises :class:`ReplayFailed` where
    it stops."""
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    orbit = ReplayOrbit(scenario)

    # 0. the ascent from the drop to insertion
    state, t = fly_ascent(plan, scenario, report, perturbation)
    if recorder is not None:
        record_ascent(plan, scenario, recorder)
    # 1. orbital arcs from the flown insertion, each planned impulse at its epoch
    state, t, previous = fly_impulses(
        plan, scenario, orbit, report, state, t, recorder, perturbation
    )

    # 2. descent to the entry interface
    state, t_entry = descend(scenario, orbit, state, t, previous, recorder)
    entry, theta = entry_interface(plan, scenario, report, state, t_entry)

    # 3. the reentry, open-loop
    entry_record = None
    if recorder is not None:
        entry_record = (recorder, entry_to_eci(scenario.earth, theta, t_entry))
    flight = fly_entry(plan, scenario, entry, entry_record, perturbation)
    report_terminal(plan, scenario, report, flight, entry.epoch, t_entry)
    report.ok = True
