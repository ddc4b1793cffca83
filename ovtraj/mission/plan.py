"""The mission plan (SPEC step 6, the patent's step 106): every manoeuvre of a chosen design.

A :class:`MissionPlan` holds the launch (the ten programme variables, the drop epoch and
state, the solved insertion state and the ascent's path maxima), each impulse with its
epoch in ECI and in the local RSW frame, the stay, the deorbit burn, the reentry's entry
state and bank profile (with the bank reversals, so it can be re-flown open-loop), the
predicted terminal state, the totals, the resolved scenario and the code version. A plan
file is self-contained: :mod:`.fly` replays it with nothing else. It is built from the
chain by :mod:`.plan_build`, checked against its front point by :mod:`.plan_check`, and
stored and read back by :mod:`.plan_store`.

Units are SI and named in the keys (``_m``, ``_mps``, ``_s``, ``_kg``); angles are
in degrees (``_deg``). Every epoch is given twice: as ISO 8601 UTC text
(``*_epoch_utc``) and as seconds from the launch day's 0 h UTC (``*_t_s``), except
where a key says otherwise (``t_from_entry_s`` of the bank reversals).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from ovtraj.astro.epoch import Epoch

SCHEMA_VERSION = "ovtraj.mission-plan/2"
Vector3 = tuple[float, float, float]
# What no flown plan holds: a mass, an altitude, a speed or a tolerance at or below zero, a
# duration or a magnitude below zero (a plan file refused naming the field, before a flight).
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


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
    # rendezvous, ovtraj.mission.plane); 0 in plan files written before the plane was aimed.
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
    # written before the plane was aimed lack it.
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
