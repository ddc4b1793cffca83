"""The air-launch stage: maximum payload to the target orbit (patent step 101).

``solve_launch`` optimises the ten-variable flight programme (:mod:`.optimize`),
then times the launch: the ascent relative to the Earth does not depend on the
epoch, so the drop epoch on the launch day is the one that puts the insertion
orbit's mean ascending node on the target's,

    Omega_fixed + theta(t_ins) = Omega_T(0 h) + dOmega_T/dt t_ins   (mod 2 pi)

with ``theta`` the Earth rotation angle (GMST at 0 h plus ``omega_E t``), ``Omega_fixed``
the insertion orbit's node in Earth-fixed axes, and ``t_ins = t_drop + t_flight``.
The first solution with ``t_drop >= 0`` is taken. The two daily in-plane
opportunities are the drop point crossing the plane northbound (``ascending``,
azimuth ``asin(cos i / cos phi)``) and southbound (``descending``, its supplement).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.angles import TWO_PI, wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.atmosphere import TabulatedAtmosphere
from ovtraj.astro.elements import rv_to_coe
from ovtraj.astro.frames import ecef_to_eci, ecef_to_geocentric
from ovtraj.astro.j2_elements import state_to_mean
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.config.physical import default_atmosphere
from ovtraj.environment import require_pinned_kernel
from ovtraj.launch.ascent import (
    AERO,
    BACK_PRESSURE,
    GRAVITY,
    IDEAL,
    STEERING,
    AscentModel,
    AscentOutcome,
    DropPoint,
)
from ovtraj.launch.ascent_optimization import OptimisationOutcome, optimise_launch
from ovtraj.launch.frame import launch_frame_axes
from ovtraj.launch.inputs import LaunchInput
from ovtraj.launch.problem import (
    EQUALITY_NAMES,
    INEQUALITY_NAMES,
    Evaluation,
    InsertionTarget,
    LaunchProblem,
)
from ovtraj.launch.result import LaunchResult, trajectory_table
from ovtraj.launch.vehicle import LauncherModel
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads


@lru_cache(maxsize=4)
def _atmosphere_table(step_m: float) -> TabulatedAtmosphere:
    us76 = default_atmosphere()
    return TabulatedAtmosphere(us76, top_m=us76.top_altitude_m, step_m=step_m)


def nominal_azimuth_rad(inclination_rad: float, latitude_rad: float, opportunity: str) -> float:
    """In-plane launch azimuth from north [rad] (spherical trigonometry, no Earth rotation).

    Raises ``ValueError`` when the plane never passes over the drop latitude.
    """
    ratio = math.cos(inclination_rad) / math.cos(latitude_rad)
    if abs(ratio) > 1.0:
        raise ValueError(
            f"the target plane (inclination {math.degrees(inclination_rad):.2f} deg) never "
            f"passes over the drop latitude {math.degrees(latitude_rad):.2f} deg"
        )
    azimuth = math.asin(ratio)
    return azimuth if opportunity == "ascending" else math.pi - azimuth


def ascent_model(inp: LaunchInput) -> AscentModel:
    drop = inp.drop
    return AscentModel(
        launcher=LauncherModel.from_config(inp.launcher, g0=inp.earth.g0_m_s2),
        earth=inp.earth,
        atmosphere=_atmosphere_table(inp.integration.atmosphere_table_step_m),
        drop=DropPoint(
            latitude_rad=math.radians(drop.latitude_deg),
            longitude_rad=math.radians(drop.longitude_deg),
            altitude_m=drop.altitude_km * 1e3,
            mach=drop.mach,
            flight_path_angle_rad=math.radians(drop.flight_path_angle_deg),
        ),
        powered_step_s=inp.integration.powered_step_s,
        coast_step_s=inp.integration.coast_step_s,
        longest_coast_s=inp.bounds.coast_s.upper,
    )


def launch_problem(inp: LaunchInput) -> LaunchProblem:
    tol = inp.tolerances
    lower, upper = inp.bounds.as_arrays()
    return LaunchProblem(
        ascent_model(inp),
        InsertionTarget(
            altitude_m=inp.target_altitude_m,
            inclination_rad=inp.target_plane.inclination_rad,
            altitude_tol_m=tol.altitude_m,
            speed_tol_mps=tol.speed_mps,
            flight_path_angle_tol_rad=math.radians(tol.flight_path_angle_deg),
            inclination_tol_rad=math.radians(tol.inclination_deg),
            path_limit_fraction=tol.path_limit_fraction,
        ),
        np.array(lower),
        np.array(upper),
        nominal_azimuth_rad(
            inp.target_plane.inclination_rad, math.radians(inp.drop.latitude_deg), inp.opportunity
        ),
    )


def insertion_time_s(
    inp: LaunchInput, node_fixed_rad: float, flight_time_s: float
) -> tuple[float, float]:
    """``(t_drop, t_ins)`` [s from the launch day's 0 h] of the in-plane drop (module notes)."""
    theta0 = inp.launch_day.gmst_rad()
    plane = inp.target_plane
    rate = inp.earth.omega - plane.raan_rate_rad_s
    phase = wrap_to_two_pi(plane.raan_0h_rad - node_fixed_rad - theta0)
    t_ins = phase / rate
    while t_ins - flight_time_s < 0.0:
        t_ins += TWO_PI / rate
    return t_ins - flight_time_s, t_ins


def solve_launch(
    inp: LaunchInput,
    *,
    seed_design: dict[str, float] | None = None,
    global_search: bool = True,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> LaunchResult:
    """Maximum-payload ascent to ``inp.target_altitude_m`` in the target plane.

    ``seed_design`` (configuration units, keys of ``DESIGN_VARIABLES``) starts the
    search from a known design: inside the GA's first population, or as the local
    phases' start when ``global_search`` is off. Never raises on a numerical
    failure: the result comes back infeasible with the reason. ``on_progress(done, total,
    phase)`` follows the optimiser (:func:`~ovtraj.launch.ascent_optimization.optimise_launch`).
    Refused in a process on another OpenBLAS kernel than the pin (a launch fit's points and
    a plan's launch are stored: :func:`ovtraj.environment.require_pinned_kernel`). Solved
    on one BLAS thread whatever the process's pools: with two, the solve's sums split
    differently and the optimum moved in its 7th digit, so ``ovtraj launch-fit`` and the
    flow's tasks (one thread) stored different fits of the same grid.
    """
    require_pinned_kernel()
    with blas_threads(EVALUATION_BLAS_THREADS):
        return _solve(inp, seed_design, global_search, on_progress)


def _solve(
    inp: LaunchInput,
    seed_design: dict[str, float] | None,
    global_search: bool,
    on_progress: Callable[[int, int, str], None] | None,
) -> LaunchResult:
    start = time.perf_counter()
    try:
        problem = launch_problem(inp)
    except ValueError as err:
        return LaunchResult.infeasible(inp, str(err))
    seed_x = None
    if seed_design is not None:
        values = np.array([seed_design[name] for name in DESIGN_VARIABLES])
        seed_x = np.clip(problem.to_scaled(values), 0.0, 1.0)
    try:
        with np.errstate(all="ignore"):
            outcome = optimise_launch(
                problem,
                inp.genetic,
                inp.local,
                seed_x=seed_x,
                global_search=global_search,
                on_progress=on_progress,
            )
            return finish_launch(inp, problem, outcome, time.perf_counter() - start)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as err:
        return LaunchResult.infeasible(inp, f"numerical failure: {type(err).__name__}: {err}")


def finish_launch(
    inp: LaunchInput,
    problem: LaunchProblem,
    outcome: OptimisationOutcome,
    wall_time_s: float,
    *,
    insertion_time: float | None = None,
    violations: list[str] | None = None,
) -> LaunchResult:
    """The stage's result of an optimised design: the ascent flown again with its history,
    timed to the plane, its insertion, losses and trajectory table.

    ``insertion_time`` [s from the launch day's 0 h]: the insertion's epoch when the caller
    has fixed it (:mod:`ovtraj.launch.insertion`), else the first in-plane one.
    ``violations``: the caller's reasons in place of the constraints' (a time limit and a
    crash are always reported)."""
    ev = problem.evaluate(outcome.x, keep_history=True)
    asc = ev.outcome
    flight_time = float(asc.time_s[0])
    t_drop, t_ins = _timed(inp, asc, insertion_time)
    theta = inp.launch_day.gmst_rad() + inp.earth.omega * t_ins
    r_eci = ecef_to_eci(asc.r_ecef[0], theta)
    v_eci = ecef_to_eci(asc.v_inertial_ecef_axes[0], theta)
    insertion = _insertion_figures(inp, r_eci, v_eci, t_ins, asc.speed_start_inertial_mps[0])
    ideal_rocket = _ideal_rocket_delta_v(problem.model.launcher, ev)
    reasons = _failure_reasons(ev, outcome, violations)
    design = problem.to_config_units(outcome.x)
    azimuth = problem.to_si(outcome.x)[0, 0]
    table = _trajectory(inp, asc, azimuth, t_drop)
    lat, lon, _ = ecef_to_geocentric(asc.r_ecef[0], radius=inp.earth.radius)
    return LaunchResult(
        feasible=not reasons,
        reason="; ".join(reasons) or None,
        target_altitude_m=inp.target_altitude_m,
        opportunity=inp.opportunity,
        launch_day=inp.launch_day,
        payload_kg=float(ev.payload_kg[0]),
        design=dict(zip(DESIGN_VARIABLES, (float(v) for v in design), strict=True)),
        azimuth_rad=float(azimuth),
        drop_time_s=t_drop,
        insertion_time_s=t_ins,
        flight_time_s=flight_time,
        insertion_latitude_rad=float(lat),
        insertion_longitude_rad=float(lon),
        ideal_delta_v_rocket_equation_mps=ideal_rocket,
        phases=outcome.phases,
        trajectories=outcome.trajectories + 1,
        wall_time_s=wall_time_s,
        trajectory=table,
        **insertion,
        **_path_figures(asc),
    )


def _timed(
    inp: LaunchInput, asc: AscentOutcome, insertion_time: float | None
) -> tuple[float, float]:
    """The drop and insertion epochs [s from the launch day's 0 h]: the insertion's when
    given, else the first in-plane one (module notes)."""
    flight_time = float(asc.time_s[0])
    if insertion_time is None:
        earth = inp.earth
        mean_fixed = state_to_mean(
            asc.r_ecef[0],
            asc.v_inertial_ecef_axes[0],
            mu=earth.mu,
            radius=earth.radius,
            j2=earth.j2,
        )
        return insertion_time_s(inp, float(mean_fixed.raan), flight_time)
    t_ins = float(insertion_time)
    return t_ins - flight_time, t_ins


def _trajectory(
    inp: LaunchInput, asc: AscentOutcome, azimuth_rad: float, t_drop: float
) -> pd.DataFrame:
    """Row 0's recorded ascent as the stage's trajectory table (launch frame of the
    azimuth, times from the launch day's 0 h)."""
    return trajectory_table(
        asc.history,
        row=0,
        axes=launch_frame_axes(
            math.radians(inp.drop.latitude_deg), math.radians(inp.drop.longitude_deg), azimuth_rad
        ),
        earth=inp.earth,
        drop_time_s=t_drop,
        step_s=inp.integration.trajectory_step_s,
    )


def _insertion_figures(
    inp: LaunchInput, r_eci: np.ndarray, v_eci: np.ndarray, t_ins: float, speed_start_mps: float
) -> dict[str, Any]:
    """The insertion state's elements, its errors from the target orbit and plane, and the
    speed gained since the drop (``speed_start_mps``, inertial)."""
    earth = inp.earth
    osc = rv_to_coe(r_eci, v_eci, mu=earth.mu)
    mean = state_to_mean(r_eci, v_eci, mu=earth.mu, radius=earth.radius, j2=earth.j2)
    r_norm, v_norm = float(np.linalg.norm(r_eci)), float(np.linalg.norm(v_eci))
    radius_target = earth.radius + inp.target_altitude_m
    plane = inp.target_plane
    raan_error = wrap_to_pi(float(mean.raan) - plane.raan_at(t_ins))
    return {
        "insertion_r_eci_m": r_eci,
        "insertion_v_eci_mps": v_eci,
        "osculating": osc,
        "mean_inclination_rad": float(mean.i),
        "mean_raan_rad": wrap_to_two_pi(float(mean.raan)),
        "mean_u_rad": wrap_to_two_pi(float(mean.u)),
        "altitude_error_m": r_norm - radius_target,
        "speed_error_mps": v_norm - math.sqrt(earth.mu / radius_target),
        "flight_path_angle_error_rad": math.asin(float(np.dot(r_eci, v_eci)) / (r_norm * v_norm)),
        "inclination_error_rad": float(mean.i) - plane.inclination_rad,
        "raan_error_rad": raan_error,
        "speed_gain_mps": float(v_norm - speed_start_mps),
    }


def _ideal_rocket_delta_v(launcher: LauncherModel, ev: Evaluation) -> float:
    """The rocket equation's speed [m/s] of the flown design, its fairing where it left."""
    asc = ev.outcome
    fairing_stage = int(asc.fairing_stage[0])
    return launcher.ideal_delta_v_mps(
        float(ev.payload_kg[0]),
        fairing_stage=fairing_stage if fairing_stage >= 0 else None,
        fairing_burn_time_s=float(asc.fairing_burn_time_s[0]),
    )


def _failure_reasons(
    ev: Evaluation, outcome: OptimisationOutcome, violations: list[str] | None
) -> list[str]:
    """Why the design is infeasible (empty: feasible); see :func:`finish_launch`."""
    reasons = []
    if outcome.limit is not None:
        reasons.append(outcome.limit)
    if violations is not None:
        reasons.extend(violations)
    elif outcome.max_violation > 0.0:
        worst = _worst_constraints(ev)
        reasons.append(f"insertion or path constraints not met: {worst}")
    if ev.outcome.crashed[0]:
        reasons.append("the trajectory hits the ground")
    return reasons


def _path_figures(asc: AscentOutcome) -> dict[str, Any]:
    """The path maxima, the fairing's jettison and the speed budget's terms of row 0."""
    state = asc.state[0]
    return {
        "max_dynamic_pressure_pa": float(asc.max_dynamic_pressure_pa[0]),
        "max_dynamic_pressure_time_s": float(asc.max_dynamic_pressure_time_s[0]),
        "max_axial_load_g": float(asc.max_axial_load_g[0]),
        "max_axial_load_time_s": float(asc.max_axial_load_time_s[0]),
        "fairing_jettison_time_s": float(asc.fairing_time_s[0]),
        "ideal_delta_v_integrated_mps": float(state[IDEAL]),
        "losses_mps": {
            "gravity": float(state[GRAVITY]),
            "aero": float(state[AERO]),
            "steering": float(state[STEERING]),
            "back_pressure": float(state[BACK_PRESSURE]),
        },
    }


def _worst_constraints(ev: Evaluation) -> str:
    eq = np.abs(ev.equality[0])
    parts = [f"{n} {v:.3g} tolerances" for n, v in zip(EQUALITY_NAMES, eq, strict=True) if v > 1]
    parts += [
        f"{n} over its limit by {-v:.3g} tolerances"
        for n, v in zip(INEQUALITY_NAMES, ev.inequality[0], strict=True)
        if v < -1
    ]
    return ", ".join(parts)
