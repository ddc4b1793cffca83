"""A mission plan built from the whole-mission chain (SPEC step 6, the patent's step 106).

:func:`build_plan` solves the launch at the design's parking altitude
(:func:`plan_launch`: to the chain's own insertion, or the stage's optimum there; cached by
its inputs), evaluates the whole-mission chain from that launch and turns the stage
results into a :class:`~ovtraj.mission.plan.MissionPlan` (:func:`plan_from_record`): the
launch (programme, drop and insertion), each impulse with its epoch in ECI and RSW, the
stay, the deorbit burn, the reentry's entry state and bank profile (its reversals re-flown
from the final shot), the predicted terminal state, the totals, the resolved scenario and
the code version.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from ovtraj.astro.epoch import Epoch
from ovtraj.config import Scenario
from ovtraj.config.base import format_validation_error
from ovtraj.deorbit.result import DeorbitResult
from ovtraj.launch.exact import SolvedLaunch, cached_launch_at, cached_launch_to, drop_state
from ovtraj.launch.inputs import launch_input
from ovtraj.launch.insertion import InsertionPoint
from ovtraj.mission.chain import (
    MissionContext,
    MissionDesign,
    MissionRecord,
    StageResults,
    evaluate,
    launch_leg,
)
from ovtraj.mission.plan import SCHEMA_VERSION, MissionPlan, PlanError
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads
from ovtraj.reentry import EntryState, reentry_input
from ovtraj.reentry.dynamics import HISTORY_COLUMNS
from ovtraj.reentry.model import EntryModel
from ovtraj.reentry.result import ReentryResult
from ovtraj.rendezvous.result import Impulse, RendezvousResult
from ovtraj.store.files import StoreError
from ovtraj.store.records import json_text
from ovtraj.version import code_version

_BANK = HISTORY_COLUMNS.index("bank_rad")
_TIME = HISTORY_COLUMNS.index("time_s")
_SPEED = HISTORY_COLUMNS.index("speed_mps")


def build_plan(
    context: MissionContext,
    design: MissionDesign,
    *,
    source: dict[str, Any],
    launch_cache: Path | None = None,
) -> MissionPlan:
    """Evaluate the chain for ``design`` and return its plan (see :func:`plan_and_record`)."""
    return plan_and_record(context, design, source=source, launch_cache=launch_cache)[0]


def plan_and_record(
    context: MissionContext,
    design: MissionDesign,
    *,
    source: dict[str, Any],
    launch_cache: Path | None = None,
) -> tuple[MissionPlan, MissionRecord]:
    """Solve the launch at the design's parking altitude, evaluate the chain from it: the
    plan, and the record it comes from.

    ``source`` is the caller's metadata (run id, front index, objectives...), stored
    as given; it must be JSON data. ``launch_cache``: where solved launches are cached
    (default the workspace's ``launch_solves``). Raises :class:`PlanError` naming the
    failed stage and its reason when the design is infeasible.

    One BLAS thread, as every stored evaluation (:data:`ovtraj.parallel.
    EVALUATION_BLAS_THREADS`): the launch's solve with a thread per core ended 7e-11 kg
    away in payload from the same solve in a pool's one-thread process, so a window's day
    refused the plan ``ovtraj pipeline`` had stored for the same front point.
    """
    with blas_threads(EVALUATION_BLAS_THREADS):
        solved = plan_launch(context, design, launch_cache)
        record = evaluate(context, design, launch=solved)
        if not record.feasible:
            raise PlanError(
                f"design {design.as_dict()} is infeasible: the {record.failed_stage} stage "
                f"failed: {record.reason}",
                stage=record.failed_stage,
                reason=record.reason,
            )
        return plan_from_record(context, record, source=source, solved=solved), record


def plan_launch(
    context: MissionContext, design: MissionDesign, launch_cache: Path | None = None
) -> SolvedLaunch:
    """The launch a plan flies: solved to the chain's own insertion (``mission.insertion``,
    :func:`~ovtraj.launch.exact.cached_launch_to`), so that the plan of a front point starts
    where the front's evaluation did; for a scenario without that section (written before
    the chain posed its own insertion), the stage's optimum at the parking altitude.
    Cached; raises :class:`PlanError` when the launch cannot be solved, read or stored."""
    scenario, altitude_m = context.scenario, design.parking_altitude_km * 1e3
    try:
        if scenario.mission.insertion is None:
            return cached_launch_at(scenario, context.fit, altitude_m, launch_cache)
        try:
            leg = launch_leg(context, design)
        except ValueError as err:
            raise PlanError(
                f"design {design.as_dict()} is infeasible: the launch stage failed: {err}",
                stage="launch",
                reason=str(err),
            ) from None
        point = InsertionPoint(leg.insertion_time_s, leg.flight_time_s, leg.insertion_state)
        return cached_launch_to(
            scenario,
            context.fit,
            altitude_m,
            point,
            math.radians(leg.raan_offset_deg),
            launch_cache,
        )
    except StoreError as err:
        raise PlanError(f"the solved launch cannot be read or stored: {err}") from None


def plan_from_record(
    context: MissionContext,
    record: MissionRecord,
    *,
    source: dict[str, Any],
    solved: SolvedLaunch | None = None,
) -> MissionPlan:
    """The plan of a feasible record evaluated from ``solved`` (the launch it flew from)."""
    results = _flown_results(record, solved)
    scenario = context.scenario
    day = context.day
    rdv: RendezvousResult = results.rendezvous
    transfer: RendezvousResult = results.transfer
    deorbit: DeorbitResult = results.deorbit
    reentry: ReentryResult = results.reentry
    launch = _launch_plan(context, record, solved)
    t_prep = transfer.arrival_time_s
    t_entry = t_prep + deorbit.entry_t_s
    t_terminal = t_entry + reentry.flight_time_s
    data = {
        "schema_version": SCHEMA_VERSION,
        "code_version": code_version(),
        "source": _json_data(source),
        "design": record.design.as_dict(),
        "launch_day_utc": day.iso(),
        "launch": launch,
        "rendezvous": _rendezvous_plan(scenario, rdv, day),
        "stay": _stay_plan(rdv, transfer, day),
        "transfer": _transfer_plan(record, transfer, day, t_prep),
        "deorbit": _deorbit_plan(deorbit, day, t_prep, t_entry),
        "reentry": _reentry_plan(context, results, day, t_entry),
        "terminal": _terminal_plan(scenario, reentry, day, t_terminal),
        "totals": {
            "t_total_s": record.t_total_s,
            "dv_total_mps": record.dv_total_mps,
            "m_load_kg": record.m_load_kg,
        },
        "scenario": scenario.resolved(),
    }
    try:
        return MissionPlan.model_validate(_json_data(data))
    except ValidationError as err:  # a stage left a value the plan cannot hold (a bug)
        problems = "; ".join(format_validation_error(err, MissionPlan))
        raise PlanError(f"the chain's results do not make a valid plan: {problems}") from None


def _flown_results(record: MissionRecord, solved: SolvedLaunch | None) -> StageResults:
    """The stage results of a feasible record flown from a solved launch; raises
    :class:`PlanError` naming what a plan lacks otherwise."""
    if (
        solved is None
        or record.results.launch is None
        or (record.results.launch.source != "solved launch")
    ):
        raise PlanError(
            "a plan flies from the drop: evaluate the chain from the solved launch "
            "(plan_and_record)"
        )
    if not record.feasible:
        raise PlanError(
            f"the record is infeasible: the {record.failed_stage} stage failed: {record.reason}",
            stage=record.failed_stage,
            reason=record.reason,
        )
    results: StageResults = record.results
    missing = results.missing()
    if missing:
        raise PlanError(f"the record lacks the stage results of {', '.join(missing)}")
    return results


def _rendezvous_plan(scenario: Scenario, rdv: RendezvousResult, day: Epoch) -> dict[str, Any]:
    return {
        "wait_time_s": rdv.wait_time_s,
        "transfer_time_s": rdv.transfer_time_s,
        "lead_angle_deg": math.degrees(rdv.lead_angle_rad),
        "burn1": _impulse("rendezvous burn 1", rdv.burn1, day),
        "burn2": _impulse("rendezvous burn 2", rdv.burn2, day),
        "arrival_epoch_utc": _iso(day, rdv.arrival_time_s),
        "arrival_t_s": rdv.arrival_time_s,
        "arrival_miss_m": rdv.miss_distance_m,
        "miss_tolerance_m": scenario.tolerances.miss_distance_m,
        "plane_difference_deg": math.degrees(rdv.plane_difference_rad),
    }


def _stay_plan(rdv: RendezvousResult, transfer: RendezvousResult, day: Epoch) -> dict[str, Any]:
    return {
        "docking_epoch_utc": _iso(day, rdv.arrival_time_s),
        "docking_t_s": rdv.arrival_time_s,
        "separation_epoch_utc": _iso(day, transfer.burn1.t_s),
        "separation_t_s": transfer.burn1.t_s,
        "duration_s": transfer.burn1.t_s - rdv.arrival_time_s,
    }


def _transfer_plan(
    record: MissionRecord, transfer: RendezvousResult, day: Epoch, t_prep: float
) -> dict[str, Any]:
    return {
        "preparation_altitude_m": record.design.preparation_altitude_km * 1e3,
        "burn1": _impulse("transfer burn 1", transfer.burn1, day),
        "burn2": _impulse("transfer burn 2", transfer.burn2, day),
        "arrival_epoch_utc": _iso(day, t_prep),
        "arrival_t_s": t_prep,
    }


def _deorbit_plan(
    deorbit: DeorbitResult, day: Epoch, t_prep: float, t_entry: float
) -> dict[str, Any]:
    return {
        "burn": _impulse(
            "deorbit burn",
            Impulse(t_prep + deorbit.burn_t_s, deorbit.dv_eci_mps, deorbit.dv_rsw_mps),
            day,
        ),
        "entry_epoch_utc": _iso(day, t_entry),
        "entry_t_s": t_entry,
    }


def _reentry_plan(
    context: MissionContext, results: StageResults, day: Epoch, t_entry: float
) -> dict[str, Any]:
    deorbit: DeorbitResult = results.deorbit
    reentry: ReentryResult = results.reentry
    entry_state: EntryState = results.entry
    settings = context.scenario.reentry
    return {
        "entry": {
            "epoch_utc": _iso(day, t_entry),
            "t_s": t_entry,
            "latitude_deg": math.degrees(entry_state.latitude_rad),
            "longitude_deg": math.degrees(entry_state.longitude_rad),
            "altitude_m": entry_state.altitude_m,
            "speed_mps": entry_state.speed_mps,
            "fpa_deg": math.degrees(entry_state.fpa_rad),
            "heading_deg": math.degrees(entry_state.heading_rad),
            "inertial_speed_mps": deorbit.entry_speed_mps,
            "inertial_fpa_deg": math.degrees(deorbit.entry_fpa_rad),
            "r_eci_m": _vector(deorbit.entry_r_eci_m),
            "v_eci_mps": _vector(deorbit.entry_v_eci_mps),
        },
        "bank_profile": _bank_profile(context, entry_state, reentry),
        "flight_time_s": reentry.flight_time_s,
        "integrator": (
            f"fixed-step RK4, {settings.integration.step_s:g} s, reversals decided at the "
            "step starts (ovtraj.reentry.dynamics)"
        ),
        "max_heat_rate_w_m2": reentry.max_heat_rate_w_m2,
        "max_load_g": reentry.max_load_g,
        "max_dynamic_pressure_pa": reentry.max_dynamic_pressure_pa,
        "max_bank_deg": math.degrees(reentry.max_bank_rad),
    }


def _terminal_plan(
    scenario: Scenario, reentry: ReentryResult, day: Epoch, t_terminal: float
) -> dict[str, Any]:
    settings = scenario.reentry
    site = settings.landing_site
    return {
        "epoch_utc": _iso(day, t_terminal),
        "t_s": t_terminal,
        "latitude_deg": math.degrees(reentry.terminal_latitude_rad),
        "longitude_deg": math.degrees(reentry.terminal_longitude_rad),
        "altitude_m": reentry.terminal_altitude_m,
        "speed_mps": reentry.terminal_speed_mps,
        "fpa_deg": math.degrees(reentry.terminal_fpa_rad),
        "heading_deg": math.degrees(reentry.terminal_heading_rad),
        "miss_distance_m": reentry.miss_distance_m,
        "landing_site_name": site.name,
        "landing_site_latitude_deg": site.latitude_deg,
        "landing_site_longitude_deg": site.longitude_deg,
        "stated_miss_m": settings.terminal.miss_tolerance_km * 1e3,
        "stated_miss_basis": (
            "reentry.terminal.miss_tolerance_km: the terminal miss the reentry stage "
            "accepts; the replay must end this close to the landing site"
        ),
        "prediction_tolerance_m": scenario.mission.plan.prediction_tolerance_km * 1e3,
    }


def _iso(day: Epoch, t_s: float) -> str:
    return day.plus_seconds(t_s).iso()


def _vector(values: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float).reshape(3)]


def _impulse(name: str, burn: Impulse, day: Epoch) -> dict[str, Any]:
    rsw = np.asarray(burn.rsw_mps, dtype=float)
    return {
        "name": name,
        "epoch_utc": _iso(day, burn.t_s),
        "t_s": float(burn.t_s),
        "dv_eci_mps": _vector(burn.eci_mps),
        "dv_radial_mps": float(rsw[0]),
        "dv_along_track_mps": float(rsw[1]),
        "dv_cross_track_mps": float(rsw[2]),
        "dv_mps": burn.magnitude_mps,
    }


def _launch_plan(
    context: MissionContext, record: MissionRecord, solved: SolvedLaunch
) -> dict[str, Any]:
    launch = record.results.launch
    day = context.day
    t_ins = launch.insertion_time_s
    t_drop = launch.drop_time_s
    state = np.asarray(launch.insertion_state, dtype=float)
    scenario = context.scenario
    inp = launch_input(scenario, altitude_km=launch.parking_altitude_m / 1e3)
    azimuth = math.radians(solved.value("azimuth_deg"))
    r_drop, v_drop = drop_state(inp, azimuth, launch.payload_kg, t_drop)
    drop = scenario.launch.drop
    return {
        "source": (
            "solved launch (patent step 101) at the parking altitude: continuation from the "
            "launch fit's grid (ovtraj.launch.exact), cached by its inputs"
            if context.scenario.mission.insertion is None
            else "solved launch (patent step 101), maximum payload flown to the chain's "
            "insertion (ovtraj.launch.insertion), cached by its inputs"
        ),
        "launcher": launch.launcher,
        "drop_epoch_utc": _iso(day, t_drop),
        "drop_t_s": t_drop,
        "insertion_epoch_utc": _iso(day, t_ins),
        "insertion_t_s": t_ins,
        "flight_time_s": launch.flight_time_s,
        "parking_altitude_m": launch.parking_altitude_m,
        "payload_kg": launch.payload_kg,
        "insertion_arg_latitude_deg": launch.insertion_u_deg,
        "plane_inclination_deg": math.degrees(context.plane.inclination_rad),
        "plane_raan_deg": (math.degrees(context.plane.raan_at(t_ins)) + launch.raan_offset_deg)
        % 360.0,
        "plane_raan_offset_deg": launch.raan_offset_deg,
        "insertion_r_eci_m": _vector(state[:3]),
        "insertion_v_eci_mps": _vector(state[3:]),
        "programme": {
            "basis": "the launch stage's optimum (ten design variables, configuration units)",
            "variables": solved.design,
            "azimuth_deg": solved.value("azimuth_deg"),
            "opportunity": str(solved.row["opportunity"]),
        },
        "drop": {
            "epoch_utc": _iso(day, t_drop),
            "t_s": t_drop,
            "latitude_deg": drop.latitude_deg,
            "longitude_deg": drop.longitude_deg,
            "altitude_m": drop.altitude_km * 1e3,
            "mach": drop.mach,
            "fpa_deg": drop.flight_path_angle_deg,
            "r_eci_m": _vector(r_drop),
            "v_eci_mps": _vector(v_drop),
        },
        "max_dynamic_pressure_pa": solved.value("max_dynamic_pressure_pa"),
        "max_axial_load_g": solved.value("max_axial_load_g"),
    }


def _bank_profile(
    context: MissionContext, entry: EntryState, reentry: ReentryResult
) -> dict[str, Any]:
    """The solved bank profile and its reversal times, from a re-flight of the final shot.

    The reentry result keeps a sampled table; the reversals (decided at the RK4 step
    starts) need the full history, so the final shot is flown once more with the same
    model and inputs and must end exactly where the stage's did.
    """
    scenario = context.scenario
    settings = scenario.reentry
    model = EntryModel(reentry_input(scenario, entry=entry))
    flight = model.fly(reentry.sigma0_rad, reentry.sigma1_rad, record=True)
    if flight.time_s != reentry.flight_time_s or flight.reversals != reentry.reversals:
        raise PlanError(
            "the re-flown reentry does not reproduce the stage's result "
            f"(flight time {flight.time_s} vs {reentry.flight_time_s} s, reversals "
            f"{flight.reversals} vs {reentry.reversals})"
        )
    history = flight.history
    negative = np.signbit(history[:, _BANK])
    changes = np.flatnonzero(negative[1:] != negative[:-1]) + 1
    if len(changes) != flight.reversals:
        raise PlanError(
            f"found {len(changes)} bank sign changes in the reentry history, "
            f"the flight reports {flight.reversals} reversals"
        )
    vehicle = settings.vehicle
    return {
        "law": (
            "|sigma| linear in Earth-relative speed from sigma0 at speed_start to sigma1 at "
            "speed_end, clipped to [0, max_bank]; sign flipped at each reversal time"
        ),
        "sigma0_deg": math.degrees(reentry.sigma0_rad),
        "sigma1_deg": math.degrees(reentry.sigma1_rad),
        "speed_start_mps": entry.speed_mps,
        "speed_end_mps": settings.terminal.speed_mps,
        "max_bank_deg": settings.limits.max_bank_deg,
        "initial_sign": -1 if negative[0] else 1,
        "reversals": [
            {
                "t_from_entry_s": float(history[k, _TIME]),
                "speed_mps": float(history[k, _SPEED]),
                "sign_after": -1 if negative[k] else 1,
            }
            for k in changes
        ],
        "alpha_schedule_mach": list(vehicle.alpha_schedule.mach),
        "alpha_schedule_deg": list(vehicle.alpha_schedule.alpha_deg),
    }


def _json_data(value: Any) -> Any:
    """Plain JSON data (:func:`ovtraj.store.records.json_text`); raises PlanError otherwise."""
    try:
        text = json_text(value, indent=None)
    except (TypeError, ValueError) as err:
        raise PlanError(f"plan content is not JSON data: {err}") from None
    return json.loads(text)
