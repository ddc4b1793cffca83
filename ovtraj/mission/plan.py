"""The mission plan (SPEC step 6, the patent's step 106): every manoeuvre of a chosen design.

:func:`build_plan` solves the launch at the design's parking altitude
(:func:`ovtraj.launch.exact.cached_launch_at`: the stage's own optimisation, cached by
its inputs), evaluates the whole-mission chain from that launch and turns the stage
results into a :class:`MissionPlan`: the launch (the ten programme variables, the drop
epoch and state, the solved insertion state and the ascent's path maxima), each impulse with
its epoch in ECI and in the local RSW frame, the stay, the deorbit burn, the
reentry's entry state and bank profile (with the bank reversals, so it can be
re-flown open-loop), the predicted terminal state, the totals, the resolved
scenario and the code version. A plan file is self-contained: :mod:`.fly`
replays it with nothing else.

Units are SI and named in the keys (``_m``, ``_mps``, ``_s``, ``_kg``); angles are
in degrees (``_deg``). Every epoch is given twice: as ISO 8601 UTC text
(``*_epoch_utc``) and as seconds from the launch day's 0 h UTC (``*_t_s``), except
where a key says otherwise (``t_from_entry_s`` of the bank reversals).

:func:`write_plan` stores a plan as JSON and YAML (never replacing a different
stored plan); :func:`read_plan` reads either back, naming the file and the field
on bad content.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from ovtraj.astro.epoch import Epoch
from ovtraj.config.base import ConfigError, format_validation_error, parse_yaml
from ovtraj.config.io_limits import echoed, read_config_file
from ovtraj.deorbit.result import DeorbitResult
from ovtraj.formatting import printable
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
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads
from ovtraj.reentry import EntryState, reentry_input
from ovtraj.reentry.dynamics import HISTORY_COLUMNS
from ovtraj.reentry.model import EntryModel
from ovtraj.reentry.result import ReentryResult
from ovtraj.rendezvous.result import Impulse, RendezvousResult
from ovtraj.store.backends import location
from ovtraj.store.files import StoreError, holds_other, json_data, write_bytes
from ovtraj.store.records import json_text
from ovtraj.version import code_version

SCHEMA_VERSION = "ovtraj.mission-plan/2"
Vector3 = tuple[float, float, float]
# What no flown plan holds: a mass, an altitude, a speed or a tolerance at or below zero, a
# duration or a magnitude below zero (a plan file refused naming the field, before a flight).
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
_BANK = HISTORY_COLUMNS.index("bank_rad")
_TIME = HISTORY_COLUMNS.index("time_s")
_SPEED = HISTORY_COLUMNS.index("speed_mps")


class PlanError(ValueError):
    """A design without a plan (infeasible), or a plan file that cannot be stored or read.

    ``stage`` and ``reason`` are set when the chain failed for the design.
    """

    def __init__(
        self, message: str, *, stage: str | None = None, reason: str | None = None
    ) -> None:
        super().__init__(message)
        self.stage = stage
        self.reason = reason


class PlanMismatch(PlanError):
    """A plan that does not fly the front point it was picked from, within
    ``mission.plan.front_tolerance``: ``differences`` names each total off, by how much,
    and ``causes`` the stage figures behind it (issue 43; the command exits 1)."""

    def __init__(self, message: str, differences: list[str], causes: list[str]) -> None:
        super().__init__(message)
        self.differences = differences
        self.causes = causes


# The totals a plan must reproduce: name, label, unit, scale to the label's unit, and the
# front tolerance's field.
_PROMISED = (
    ("dv_total_mps", "dV_total", "m/s", 1.0, "dv_total_mps"),
    ("t_total_s", "T_total", "h", 1.0 / 3600.0, "t_total_s"),
    ("m_load_kg", "M_load", "kg", 1.0, "m_load_kg"),
)
# The stage figures that explain a difference of the totals: stage, row column, label, unit.
_CAUSES = (
    ("launch", "payload_kg", "launch payload", "kg"),
    ("launch", "drop_time_s", "drop", "s"),
    ("rendezvous", "wait_time_s", "phasing wait", "s"),
    ("rendezvous", "dv_total_mps", "rendezvous dV", "m/s"),
    ("rendezvous", "plane_difference_deg", "plane difference at the burn", "deg"),
    ("transfer", "dv_total_mps", "transfer dV", "m/s"),
    ("deorbit", "wait_time_s", "deorbit wait", "s"),
    ("deorbit", "dv_mps", "deorbit dV", "m/s"),
    ("reentry", "flight_time_s", "entry flight", "s"),
)


def check_front_point(
    record: MissionRecord,
    front: dict[str, float],
    front_stages: dict[str, dict[str, Any]],
    tolerance: Any,
    what: str,
) -> None:
    """Raise :class:`PlanMismatch` when the plan's chain ``record`` does not reproduce the
    ``front`` totals (``t_total_s``, ``dv_total_mps``, ``m_load_kg``) within ``tolerance``
    (:class:`~ovtraj.config.mission.FrontTolerance`). ``front_stages``: the front point's
    stored stage rows, to say why (the figures of each stage that moved)."""
    differences = []
    for name, label, unit, scale, field in _PROMISED:
        planned, promised = getattr(record, name), front.get(name)
        if promised is None or planned is None:
            continue
        if abs(planned - promised) > getattr(tolerance, field):
            differences.append(
                f"{label} {promised * scale:.6g} -> {planned * scale:.6g} {unit} "
                f"({(planned - promised) * scale:+.3g}; tolerance "
                f"{getattr(tolerance, field) * scale:.3g})"
            )
    if not differences:
        return
    causes = []
    for stage, column, label, unit in _CAUSES:
        before = (front_stages.get(stage) or {}).get(column)
        after = record.stages.get(stage, {}).get(column)
        if isinstance(before, int | float) and isinstance(after, int | float):
            if not math.isclose(before, after, rel_tol=1e-9, abs_tol=1e-6):
                causes.append(f"{label} {before:.6g} -> {after:.6g} {unit}")
    why = "; ".join(causes) or "no stored stage figures to compare"
    raise PlanMismatch(
        f"the plan of {what} does not fly its front values: {'; '.join(differences)}. "
        f"Stage figures, front -> plan: {why}",
        differences,
        causes,
    )


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class PlannedImpulse(_Model):
    """One impulsive manoeuvre: epoch, ECI vector and its RSW components at the burn state."""

    name: str
    epoch_utc: str
    t_s: float
    dv_eci_mps: Vector3
    dv_radial_mps: float
    dv_along_track_mps: float
    dv_cross_track_mps: float
    dv_mps: NonNegative

    @property
    def eci(self) -> np.ndarray:
        return np.asarray(self.dv_eci_mps, dtype=float)

    @property
    def rsw(self) -> np.ndarray:
        return np.array([self.dv_radial_mps, self.dv_along_track_mps, self.dv_cross_track_mps])


class LaunchProgramme(_Model):
    """The launch's ten programme variables (patent step 101) solved at the parking altitude.

    ``variables``: the stage's design variables in configuration units (``docs/launch.md``);
    ``azimuth_deg``: the absolute launch azimuth from north they imply.
    """

    basis: str
    variables: dict[str, float]
    azimuth_deg: float
    opportunity: str


class DropPlan(_Model):
    """The carrier's release: where and how the ascent starts."""

    epoch_utc: str
    t_s: float
    latitude_deg: float
    longitude_deg: float
    altitude_m: NonNegative
    mach: NonNegative
    fpa_deg: float
    r_eci_m: Vector3
    v_eci_mps: Vector3


class LaunchPlan(_Model):
    source: str
    launcher: str
    drop_epoch_utc: str
    drop_t_s: float
    insertion_epoch_utc: str
    insertion_t_s: float
    flight_time_s: NonNegative
    parking_altitude_m: Positive
    payload_kg: Positive
    insertion_arg_latitude_deg: float
    plane_inclination_deg: float
    plane_raan_deg: float
    # The parking orbit's node east of the target's at insertion (the plane aimed at the
    # rendezvous, ovtraj.mission.plane); plan files before issue 43: 0.
    plane_raan_offset_deg: float = 0.0
    insertion_r_eci_m: Vector3
    insertion_v_eci_mps: Vector3
    programme: LaunchProgramme
    drop: DropPlan
    max_dynamic_pressure_pa: NonNegative
    max_axial_load_g: NonNegative


class RendezvousPlan(_Model):
    wait_time_s: NonNegative
    transfer_time_s: NonNegative
    lead_angle_deg: float
    burn1: PlannedImpulse
    burn2: PlannedImpulse
    arrival_epoch_utc: str
    arrival_t_s: float
    arrival_miss_m: NonNegative
    miss_tolerance_m: Positive
    # Between the chaser's and the target's planes at the first burn as phased; plan files
    # before issue 43 lack it.
    plane_difference_deg: float | None = None


class StayPlan(_Model):
    docking_epoch_utc: str
    docking_t_s: float
    separation_epoch_utc: str
    separation_t_s: float
    duration_s: NonNegative


class TransferPlan(_Model):
    preparation_altitude_m: Positive
    burn1: PlannedImpulse
    burn2: PlannedImpulse
    arrival_epoch_utc: str
    arrival_t_s: float


class DeorbitPlan(_Model):
    burn: PlannedImpulse
    entry_epoch_utc: str
    entry_t_s: float


class EntryPlan(_Model):
    """Entry interface state: Earth-relative (what the reentry flies from) and inertial."""

    epoch_utc: str
    t_s: float
    latitude_deg: float
    longitude_deg: float
    altitude_m: Positive
    speed_mps: Positive
    fpa_deg: float
    heading_deg: float
    inertial_speed_mps: Positive
    inertial_fpa_deg: float
    r_eci_m: Vector3
    v_eci_mps: Vector3


class BankReversal(_Model):
    t_from_entry_s: float
    speed_mps: float
    sign_after: Literal[-1, 1]


class BankProfile(_Model):
    """The reentry's bank programme, enough to fly it open-loop.

    |sigma| runs linearly in Earth-relative speed from ``sigma0_deg`` at
    ``speed_start_mps`` to ``sigma1_deg`` at ``speed_end_mps`` (held outside, clipped to
    [0, ``max_bank_deg``]); its sign starts at ``initial_sign`` and flips at each reversal
    time (s from the entry epoch). The angle of attack follows the scenario's Mach
    schedule (copied here).
    """

    law: str
    sigma0_deg: float
    sigma1_deg: float
    speed_start_mps: NonNegative
    speed_end_mps: NonNegative
    max_bank_deg: NonNegative
    initial_sign: Literal[-1, 1]
    reversals: list[BankReversal]
    alpha_schedule_mach: list[float]
    alpha_schedule_deg: list[float]

    def sign_at(self, t_from_entry_s: float) -> float:
        """Bank sign ``t_from_entry_s`` seconds after the entry epoch."""
        sign = float(self.initial_sign)
        for reversal in self.reversals:
            if t_from_entry_s >= reversal.t_from_entry_s:
                sign = float(reversal.sign_after)
        return sign


class ReentryPlan(_Model):
    entry: EntryPlan
    bank_profile: BankProfile
    flight_time_s: NonNegative
    integrator: str
    max_heat_rate_w_m2: NonNegative
    max_load_g: NonNegative
    max_dynamic_pressure_pa: NonNegative
    max_bank_deg: NonNegative


class TerminalPlan(_Model):
    """The predicted end of the reentry at the terminal interface, and the stated miss."""

    epoch_utc: str
    t_s: float
    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    speed_mps: NonNegative
    fpa_deg: float
    heading_deg: float
    miss_distance_m: NonNegative
    landing_site_name: str
    landing_site_latitude_deg: float
    landing_site_longitude_deg: float
    stated_miss_m: Positive
    stated_miss_basis: str
    prediction_tolerance_m: NonNegative


class PlanTotals(_Model):
    t_total_s: NonNegative
    dv_total_mps: NonNegative
    m_load_kg: Positive


class PlanDesign(_Model):
    parking_altitude_km: Positive
    preparation_altitude_km: Positive
    separation_delay_h: NonNegative


class MissionPlan(_Model):
    """A flyable mission plan; see the module notes for units and epochs."""

    schema_version: Literal["ovtraj.mission-plan/2"]
    code_version: str
    source: dict[str, Any]
    design: PlanDesign
    launch_day_utc: str
    launch: LaunchPlan
    rendezvous: RendezvousPlan
    stay: StayPlan
    transfer: TransferPlan
    deorbit: DeorbitPlan
    reentry: ReentryPlan
    terminal: TerminalPlan
    totals: PlanTotals
    scenario: dict[str, Any]

    @field_validator("launch_day_utc")
    @classmethod
    def _parses(cls, value: str) -> str:
        Epoch.from_iso(value)
        return value

    @property
    def day(self) -> Epoch:
        return Epoch.from_iso(self.launch_day_utc)

    def impulses(self) -> list[PlannedImpulse]:
        """Every OV impulse in time order."""
        return [
            self.rendezvous.burn1,
            self.rendezvous.burn2,
            self.transfer.burn1,
            self.transfer.burn2,
            self.deorbit.burn,
        ]

    def to_dict(self) -> dict[str, Any]:
        return self.model_dump(mode="json")


# --- building ---------------------------------------------------------------------------


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
    where the front's evaluation did; for a scenario without that section (before issue
    43), the stage's optimum at the parking altitude. Cached; raises :class:`PlanError`
    when the launch cannot be solved, read or stored."""
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
    scenario = context.scenario
    day = context.day
    rdv: RendezvousResult = results.rendezvous
    transfer: RendezvousResult = results.transfer
    deorbit: DeorbitResult = results.deorbit
    reentry: ReentryResult = results.reentry
    entry_state: EntryState = results.entry
    launch = _launch_plan(context, record, solved)
    t_prep = transfer.arrival_time_s
    t_entry = t_prep + deorbit.entry_t_s
    t_terminal = t_entry + reentry.flight_time_s
    settings = scenario.reentry
    plan_settings = scenario.mission.plan
    site = settings.landing_site
    stated_miss_m = settings.terminal.miss_tolerance_km * 1e3
    data = {
        "schema_version": SCHEMA_VERSION,
        "code_version": code_version(),
        "source": _json_data(source),
        "design": record.design.as_dict(),
        "launch_day_utc": day.iso(),
        "launch": launch,
        "rendezvous": {
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
        },
        "stay": {
            "docking_epoch_utc": _iso(day, rdv.arrival_time_s),
            "docking_t_s": rdv.arrival_time_s,
            "separation_epoch_utc": _iso(day, transfer.burn1.t_s),
            "separation_t_s": transfer.burn1.t_s,
            "duration_s": transfer.burn1.t_s - rdv.arrival_time_s,
        },
        "transfer": {
            "preparation_altitude_m": record.design.preparation_altitude_km * 1e3,
            "burn1": _impulse("transfer burn 1", transfer.burn1, day),
            "burn2": _impulse("transfer burn 2", transfer.burn2, day),
            "arrival_epoch_utc": _iso(day, t_prep),
            "arrival_t_s": t_prep,
        },
        "deorbit": {
            "burn": _impulse(
                "deorbit burn",
                Impulse(t_prep + deorbit.burn_t_s, deorbit.dv_eci_mps, deorbit.dv_rsw_mps),
                day,
            ),
            "entry_epoch_utc": _iso(day, t_entry),
            "entry_t_s": t_entry,
        },
        "reentry": {
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
        },
        "terminal": {
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
            "stated_miss_m": stated_miss_m,
            "stated_miss_basis": (
                "reentry.terminal.miss_tolerance_km: the terminal miss the reentry stage "
                "accepts; the replay must end this close to the landing site"
            ),
            "prediction_tolerance_m": plan_settings.prediction_tolerance_km * 1e3,
        },
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


# --- storing and reading ----------------------------------------------------------------


def plan_json(plan: MissionPlan) -> bytes:
    """The plan as JSON text (UTF-8), keys in schema order."""
    return (json.dumps(plan.to_dict(), indent=2, allow_nan=False) + "\n").encode("utf-8")


class _WrittenOut(yaml.SafeDumper):
    """Every value written where it is: :func:`read_plan` refuses anchors and aliases
    (:func:`ovtraj.store.paths.read_yaml`), which PyYAML writes for an object met twice."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


def plan_yaml(plan: MissionPlan) -> bytes:
    """The plan as YAML text (UTF-8), keys in schema order; floats round-trip exactly."""
    text = yaml.dump(
        plan.to_dict(), Dumper=_WrittenOut, sort_keys=False, allow_unicode=True, width=100
    )
    return text.encode("utf-8")


def write_plan(plan: MissionPlan, directory: Path, name: str) -> tuple[Path, Path]:
    """Write ``<name>.json`` and ``<name>.yaml`` in ``directory`` atomically.

    An existing file with the same content is left as it is; one with different
    content raises :class:`PlanError` and neither file is touched (a stored plan is
    never replaced by another).
    """
    if not name or Path(name).name != name or name in {".", ".."}:
        raise PlanError(f"plan name {name!r} must be a plain file name")
    directory = location(directory)
    targets = (
        (directory / f"{name}.json", plan_json(plan)),
        (directory / f"{name}.yaml", plan_yaml(plan)),
    )
    for path, payload in targets:
        try:  # a file already there is read as a stored file (no FIFO, device or link)
            other = holds_other(path, payload)
        except StoreError as err:
            raise PlanError(str(err)) from None
        if other:
            raise PlanError(
                f"{path}: a different plan is stored there; refusing to overwrite it "
                "(choose another name or directory)"
            )
    for path, payload in targets:
        write_bytes(path, payload)
    return targets[0][0], targets[1][0]


def read_plan(path: Path) -> MissionPlan:
    """A plan from its JSON or YAML file; :class:`PlanError` names the file and the field."""
    path = Path(path)
    shown = printable(str(path))
    suffix = path.suffix.lower()
    if suffix not in {".json", ".yaml", ".yml"}:
        raise PlanError(f"{shown}: a plan file ends in .json, .yaml or .yml")
    try:  # a regular file within config_file_max_kib (configs/io_limits.yaml)
        text = read_config_file(path)
    except ConfigError as err:
        raise PlanError(f"{shown}: cannot read the plan file ({'; '.join(err.problems)})") from None
    try:  # both bounded: depth and numbers (json_data), anchors and aliases (parse_yaml)
        data = json_data(text) if suffix == ".json" else parse_yaml(text)
    except ValueError as err:  # one line
        raise PlanError(f"{shown}: {err}") from None
    if not isinstance(data, dict):
        raise PlanError(f"{shown}: expected a mapping at the top level, got {type(data).__name__}")
    version = data.get("schema_version")
    if version != SCHEMA_VERSION:
        raise PlanError(
            f"{shown}: schema_version = {echoed(repr(version))}: this code reads "
            f"{SCHEMA_VERSION!r} plans"
        )
    try:
        plan = MissionPlan.model_validate(data)
    except ValidationError as err:
        problems = format_validation_error(err, MissionPlan)
        if len(problems) == 1:  # one line, as ConfigError has it
            raise PlanError(f"{shown}: invalid mission plan: {problems[0]}") from None
        raise PlanError(
            "\n".join([f"{shown}: invalid mission plan:", *(f"  - {p}" for p in problems)])
        ) from None
    # the scenario the plan is flown in, checked as a scenario file is (bad input named
    # here, not a flight that fails later)
    from ovtraj.config import scenario_from_dict

    try:
        scenario_from_dict(plan.scenario, f"{shown}: scenario")
    except ConfigError as err:
        raise PlanError(str(err)) from None
    return plan
