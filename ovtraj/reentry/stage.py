"""The reentry stage (patent step 104): guided lifting entry to the terminal interface.

``solve_reentry`` builds the compiled entry model for the input, runs the bank
guidance (:mod:`.guidance`) and reports the landing-site miss, the terminal
state, each path maximum with its time and margin, the bank reversals and the
iterations. A target outside the footprint, a path limit that cannot be kept, a
terminal altitude off its interface or a skip/crash come back as an infeasible
result with flags and the reason; nothing raises on a numerical failure.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.config.reentry import ReentryLimitsConfig
from ovtraj.deadline import Deadline
from ovtraj.reentry.dynamics import HISTORY_COLUMNS, STATUS_TEXT
from ovtraj.reentry.guidance import BankGuidance, Limits, Shot, unit_bounds
from ovtraj.reentry.inputs import ReentryInput
from ovtraj.reentry.model import EntryModel, Flight
from ovtraj.reentry.result import ReentryResult


def guidance_for(inp: ReentryInput, model: EntryModel) -> BankGuidance:
    s = inp.settings
    return BankGuidance(
        model,
        Limits(
            heat_rate_w_m2=s.limits.max_heat_rate_kw_m2 * 1e3,
            load_g=s.limits.max_load_g,
            dynamic_pressure_pa=s.limits.max_dynamic_pressure_kpa * 1e3,
        ),
        sigma_max_rad=math.radians(s.limits.max_bank_deg),
        newton_iterations=s.guidance.newton_iterations,
        newton_tolerance_m=s.guidance.newton_tolerance_km * 1e3,
        finite_difference_rad=math.radians(s.guidance.finite_difference_deg),
        violation_weight_m=s.guidance.violation_weight_km * 1e3,
        terminal_radius_m=inp.earth.radius + s.terminal.altitude_km * 1e3,
        deadline=Deadline(s.guidance.time_limit_s, "reentry.guidance.time_limit_s"),
    )


def solve_reentry(inp: ReentryInput, *, model: EntryModel | None = None) -> ReentryResult:
    """Guided entry from ``inp.entry`` to the terminal interface near the landing site.

    The guidance stops at ``guidance.time_limit_s`` (wall time, from the end of the
    model's build): the best trajectory so far is then reported infeasible, flagged
    ``time_limit``, with the limit in the reason; a Newton search that used all its
    ``newton_iterations`` with the range error still above its tolerance is flagged
    ``iteration_limit``.
    """
    start = time.perf_counter()
    s = inp.settings
    try:
        model = model or EntryModel(inp)
        guidance = guidance_for(inp, model)
        before = model.flights
        with np.errstate(all="ignore"):
            best, evaluations = guidance.solve(
                unit_bounds(s.guidance.sigma_1_bounds_deg, s.limits.max_bank_deg),
                s.guidance.golden_iterations,
            )
            final = guidance.shoot(best.sigma0_rad, best.sigma1_rad, record=True)
    except (ArithmeticError, ValueError) as err:
        return ReentryResult(
            False,
            f"numerical failure: {type(err).__name__}: {err}",
            inp.entry.epoch,
            flags=("numerical_failure",),
            wall_time_s=time.perf_counter() - start,
        )
    final.newton_iterations = best.newton_iterations
    final.newton_exhausted = best.newton_exhausted
    trajectories = model.flights - before
    limit = None
    if guidance.deadline.reached:
        limit = guidance.deadline.reason(trajectories, "trajectories")
    return _result(
        inp,
        model,
        final,
        evaluations=evaluations,
        trajectories=trajectories,
        wall_time_s=time.perf_counter() - start,
        time_limit=limit,
    )


def _result(
    inp: ReentryInput,
    model: EntryModel,
    shot: Shot,
    *,
    evaluations: int,
    trajectories: int,
    wall_time_s: float,
    time_limit: str | None = None,
) -> ReentryResult:
    """The stage's result of the final ``shot``: its flags and reasons, terminal state,
    path maxima and margins, and the guidance's counts."""
    flight = shot.flight
    x = flight.state
    altitude = float(x[0] - inp.earth.radius)
    margins = _margins(flight, inp.settings.limits)
    flags, reasons = _stop_flags(inp, shot, time_limit)
    for flag, reason in _limit_flags(inp, shot, margins, altitude):
        flags.append(flag)
        reasons.append(reason)
    feasible = not flags
    return ReentryResult(
        feasible=feasible,
        reason=None if feasible else "; ".join(reasons),
        epoch=inp.entry.epoch,
        flags=tuple(flags),
        miss_distance_m=shot.miss_m,
        flight_time_s=flight.time_s,
        terminal_altitude_m=altitude,
        terminal_speed_mps=float(x[3]),
        terminal_latitude_rad=float(x[2]),
        terminal_longitude_rad=float(x[1]),
        terminal_fpa_rad=float(x[4]),
        terminal_heading_rad=float(wrap_to_two_pi(x[5])),
        max_heat_rate_w_m2=flight.max_heat_rate_w_m2,
        max_heat_rate_time_s=flight.max_heat_rate_time_s,
        max_load_g=flight.max_load_g,
        max_load_time_s=flight.max_load_time_s,
        max_dynamic_pressure_pa=flight.max_dynamic_pressure_pa,
        max_dynamic_pressure_time_s=flight.max_dynamic_pressure_time_s,
        max_bank_rad=flight.max_bank_rad,
        heat_rate_margin=margins["heat"],
        load_margin=margins["load"],
        dynamic_pressure_margin=margins["q"],
        bank_margin=margins["bank"],
        sigma0_rad=shot.sigma0_rad,
        sigma1_rad=shot.sigma1_rad,
        reversals=flight.reversals,
        newton_iterations=shot.newton_iterations,
        golden_evaluations=evaluations,
        trajectories=trajectories,
        wall_time_s=wall_time_s,
        trajectory=trajectory_table(inp, flight.history),
    )


def _margins(flight: Flight, limits: ReentryLimitsConfig) -> dict[str, float]:
    """Each path maximum's margin: 1 - maximum / limit (negative: over the limit)."""
    return {
        "heat": 1.0 - flight.max_heat_rate_w_m2 / (limits.max_heat_rate_kw_m2 * 1e3),
        "load": 1.0 - flight.max_load_g / limits.max_load_g,
        "q": 1.0 - flight.max_dynamic_pressure_pa / (limits.max_dynamic_pressure_kpa * 1e3),
        "bank": 1.0 - flight.max_bank_rad / math.radians(limits.max_bank_deg),
    }


def _stop_flags(
    inp: ReentryInput, shot: Shot, time_limit: str | None
) -> tuple[list[str], list[str]]:
    """The flags and reasons of a guidance stopped by a limit or a flight that did not
    reach the terminal speed."""
    s = inp.settings
    flags, reasons = [], []
    if time_limit is not None:
        flags.append("time_limit")
        reasons.append(f"guidance stopped: {time_limit}")
    if shot.newton_exhausted:
        flags.append("iteration_limit")
        reasons.append(
            f"reentry.guidance.newton_iterations = {s.guidance.newton_iterations} reached "
            f"with the range error {abs(shot.range_error_m) / 1e3:.3g} km above "
            f"newton_tolerance_km = {s.guidance.newton_tolerance_km:g}"
        )
    if not shot.flight.reached:
        flags.append("terminal_not_reached")
        reasons.append(STATUS_TEXT[shot.flight.status])
    return flags, reasons


def _limit_flags(
    inp: ReentryInput, shot: Shot, margins: dict[str, float], altitude_m: float
) -> list[tuple[str, str]]:
    """The flags and reasons of the landing-site miss, the path limits and the terminal
    altitude, in that order."""
    terminal = inp.settings.terminal
    found = []
    if shot.miss_m > terminal.miss_tolerance_km * 1e3:
        found.append(
            (
                "outside_footprint",
                f"the landing site is outside the footprint: the best trajectory ends "
                f"{shot.miss_m / 1e3:.1f} km from it (tolerance {terminal.miss_tolerance_km:g} km)",
            )
        )
    for name, key in (("heat rate", "heat"), ("load", "load"), ("dynamic pressure", "q")):
        if margins[key] < 0.0:
            found.append((f"{key}_limit", f"{name} over its limit by {-100 * margins[key]:.1f} %"))
    if shot.flight.reached and abs(altitude_m / 1e3 - terminal.altitude_km) > (
        terminal.altitude_tolerance_km
    ):
        found.append(
            (
                "terminal_altitude",
                f"terminal altitude {altitude_m / 1e3:.1f} km outside "
                f"{terminal.altitude_km:g} +- {terminal.altitude_tolerance_km:g} km",
            )
        )
    return found


def trajectory_table(inp: ReentryInput, history: np.ndarray | None) -> pd.DataFrame:
    """Time, altitude, position, speed, angles, bank, Mach and path quantities, sampled.

    On plain arrays (the same arithmetic as on columns): a frame of Series aligns indexes
    and cost ~5 ms per flight, a tenth of the stage (benchmarks/mission.py).
    """
    if history is None or len(history) == 0:
        return pd.DataFrame()
    column = {name: k for k, name in enumerate(HISTORY_COLUMNS)}
    time_s = history[:, column["time_s"]]
    step = inp.settings.integration.trajectory_step_s
    keep = np.r_[np.flatnonzero(np.diff(np.floor(time_s / step)) > 0) + 1, 0, len(history) - 1]
    kept = history[np.unique(keep)]

    def value(name: str) -> np.ndarray:
        return kept[:, column[name]]

    radius = inp.earth.radius
    return pd.DataFrame(
        {
            "time_s": value("time_s"),
            "altitude_km": (value("radius_m") - radius) / 1e3,
            "latitude_deg": np.degrees(value("latitude_rad")),
            "longitude_deg": np.degrees(value("longitude_rad")),
            "speed_mps": value("speed_mps"),
            "fpa_deg": np.degrees(value("fpa_rad")),
            "heading_deg": np.degrees(value("heading_rad")) % 360.0,
            "alpha_deg": np.degrees(value("alpha_rad")),
            "bank_deg": np.degrees(value("bank_rad")),
            "mach": value("mach"),
            "heat_rate_kw_m2": value("heat_rate_w_m2") / 1e3,
            "load_g": value("load_g"),
            "dynamic_pressure_kpa": value("dynamic_pressure_pa") / 1e3,
            "range_to_go_km": value("range_to_go_m") / 1e3,
        }
    )
