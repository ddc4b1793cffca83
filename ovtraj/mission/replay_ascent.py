"""The ascent of a plan's replay (:mod:`ovtraj.mission.fly`): from the carrier's drop to
insertion, the plan's ten programme variables through the launch stage's own 3-DOF model
and fixed-step RK4 (``ovtraj.launch.ascent``, whose scheme ``tests/test_launch_dynamics.py``
checks against DOP853), timed from the plan's drop epoch. The insertion it reaches is
compared with the plan's; the orbital phase continues from the flown insertion, not the
planned one. Also the ascent as a table (:func:`ascent_trajectory`) and as ephemeris
(:func:`record_ascent`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.frames import ecef_to_eci, ecef_to_eci_state
from ovtraj.config import Scenario
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.launch.ascent import simulate
from ovtraj.launch.frame import launch_frame_axes, launch_to_ecef
from ovtraj.launch.inputs import launch_input
from ovtraj.launch.result import trajectory_table
from ovtraj.launch.stage import ascent_model, launch_problem
from ovtraj.mission.ephemeris import EphemerisRecorder
from ovtraj.mission.flight_report import FlightReport, LimitCheck, ReplayFailed
from ovtraj.mission.perturbation import NOMINAL, Perturbation
from ovtraj.mission.plan import MissionPlan


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


def record_ascent(plan: MissionPlan, scenario: Scenario, recorder: EphemerisRecorder) -> None:
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
