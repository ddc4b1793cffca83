"""The scenario: epoch, target orbit, vehicle, limits, tolerances and stage settings.

Units are part of every key name (``_km``, ``_deg``, ``_s``, ``_mps``...);
conversion to SI happens once, in the properties and helpers of these models.
"""

from __future__ import annotations

from typing import Any

from pydantic import Field, field_validator, model_serializer, model_validator

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.config.base import StrictModel, bounded, model_from_dict
from ovtraj.config.body import BodyConfig
from ovtraj.config.deorbit import DeorbitSettings
from ovtraj.config.launch import LaunchSettings
from ovtraj.config.mission import MissionSettings
from ovtraj.config.physical import default_earth
from ovtraj.config.reentry import ReentrySettings

# The target's models live in ovtraj.config.target; importable from here as before.
from ovtraj.config.target import ElementSet, TargetConfig
from ovtraj.config.target import OrbitElementsConfig as OrbitElementsConfig
from ovtraj.config.target import TargetSourceSettings as TargetSourceSettings


class ParkingOrbitConfig(StrictModel):
    """The OV's near-circular parking orbit at the epoch, placed relative to the target's plane.

    Mean elements (first-order J2) with zero mean eccentricity are the natural
    definition of a circular orbit under J2; the offsets let a scenario start the
    OV out of the target's plane.
    """

    element_set: ElementSet = "mean"
    altitude_km: float = bounded(unit="km", gt=0, le=100000)
    arg_latitude_deg: float = bounded(unit="deg", ge=-360, le=360)
    inclination_offset_deg: float = bounded(unit="deg", ge=-180, le=180, default=0.0)
    raan_offset_deg: float = bounded(unit="deg", ge=-360, le=360, default=0.0)


class VehicleConfig(StrictModel):
    """The orbital vehicle (OV) as the orbital stages see it."""

    name: str
    mass_kg: float = bounded(
        unit="kg", gt=0, le=1.0e6, description="wet mass at the start of the scenario"
    )
    dry_mass_kg: float = bounded(unit="kg", gt=0, le=1.0e6)
    thrust_n: float = bounded(unit="N", gt=0, le=1.0e7)
    isp_s: float = bounded(unit="s", gt=0, le=10000, description="electric engines reach ~5000 s")
    max_impulse_mps: float = bounded(
        unit="m/s", gt=0, le=20000, description="largest single impulse"
    )
    body: BodyConfig | None = Field(
        default=None, description="drag and radiation pressure figures (the high-fidelity flight)"
    )

    @model_serializer(mode="wrap")
    def _body_when_given(self, handler: Any) -> dict[str, Any]:
        """A vehicle without ``body`` dumps as before bodies existed (same run ids)."""
        data = handler(self)
        if data.get("body") is None:
            data.pop("body", None)
        return data

    @model_validator(mode="after")
    def _dry_not_above_wet(self) -> VehicleConfig:
        if self.dry_mass_kg > self.mass_kg:
            raise ValueError(
                f"dry_mass_kg ({self.dry_mass_kg:g}) must not exceed mass_kg ({self.mass_kg:g})"
            )
        return self


class LimitsConfig(StrictModel):
    min_perigee_altitude_km: float = bounded(unit="km", ge=0, le=2000)


class TolerancesConfig(StrictModel):
    integrator: float = bounded(gt=0, lt=1e-3, description="Taylor integrator tolerance")
    miss_distance_m: float = bounded(
        unit="m", gt=0, le=100000, description="epsilon_dis of patent step 102"
    )


class RendezvousSettings(StrictModel):
    """Settings of the modified-Hohmann rendezvous stage (patent step 102)."""

    max_wait_time_s: float = bounded(unit="s", ge=0, le=30 * 86400)
    max_plane_difference_deg: float = bounded(unit="deg", ge=0, le=90)
    max_eccentricity: float = bounded(ge=0, lt=1)
    transfer_time_bounds: tuple[float, float] = Field(
        description="bounds of the corrected transfer time as fractions of the Hohmann time"
    )
    burn_epoch_window_s: float = bounded(unit="s", ge=0, le=86400)
    start_transfer_fractions: tuple[float, ...] = Field(
        min_length=1, description="transfer times (fractions of Hohmann) tried for the start"
    )
    # Optional (null when absent): the configs stored with runs made before it existed
    # still read, and mean what they meant then (the cheapest start only).
    multi_start_fractions: tuple[float, ...] | None = Field(
        default=None,
        min_length=1,
        description=(
            "rendezvous only: transfer times (fractions of Hohmann) whose shots each start "
            "the interior point; the cheapest optimum is kept"
        ),
    )
    max_iterations: int = bounded(
        ge=1, le=100000, description="interior-point iteration limit, per solve"
    )
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of one rendezvous or transfer solve"
    )
    optimality_tol: float = bounded(
        gt=0, lt=1, description="interior-point KKT tolerance, scaled problem"
    )
    initial_barrier_parameter: float = bounded(gt=0, lt=1)
    initial_trust_radius: float = bounded(
        gt=0, le=1000, description="interior point's first trust radius, scaled variables"
    )
    trajectory_step_s: float = bounded(unit="s", ge=0.01, le=86400)

    @field_validator("transfer_time_bounds")
    @classmethod
    def _ordered_fractions(cls, value: tuple[float, float]) -> tuple[float, float]:
        lo, hi = value
        if not 0.0 < lo < 1.0 < hi <= 10.0:
            raise ValueError(f"needs 0 < lower < 1 < upper <= 10, got [{lo:g}, {hi:g}]")
        return value

    @model_validator(mode="after")
    def _starts_inside_bounds(self) -> RendezvousSettings:
        lo, hi = self.transfer_time_bounds
        for name in ("start_transfer_fractions", "multi_start_fractions"):
            outside = [f for f in getattr(self, name) or () if not lo <= f <= hi]
            if outside:
                raise ValueError(
                    f"{name} {outside} lie outside transfer_time_bounds [{lo:g}, {hi:g}]"
                )
        return self


class Scenario(StrictModel):
    """A complete scenario; the file is the whole truth (no hidden defaults)."""

    name: str
    epoch_utc: str
    earth: EarthModel = Field(default_factory=default_earth)
    target: TargetConfig
    vehicle: VehicleConfig
    parking_orbit: ParkingOrbitConfig
    limits: LimitsConfig
    tolerances: TolerancesConfig
    rendezvous: RendezvousSettings
    launch: LaunchSettings | None = None
    deorbit: DeorbitSettings | None = None
    reentry: ReentrySettings | None = None
    mission: MissionSettings | None = None

    @field_validator("epoch_utc")
    @classmethod
    def _parses_as_utc(cls, value: str) -> str:
        Epoch.from_iso(value)  # raises ValueError naming the text
        return value

    @model_validator(mode="after")
    def _perigees_above_minimum(self) -> Scenario:
        floor = self.limits.min_perigee_altitude_km
        radius = self.earth.equatorial_radius_m
        problems = []
        perigee = self.target.perigee_altitude_km(radius)
        if perigee < floor:
            problems.append(f"target.{self.target.source_key}: perigee altitude {perigee:.1f} km")
        if self.parking_orbit.altitude_km < floor:
            problems.append(f"parking_orbit.altitude_km: {self.parking_orbit.altitude_km:g} km")
        if self.deorbit is not None and self.deorbit.preparation_orbit.altitude_km < floor:
            altitude = self.deorbit.preparation_orbit.altitude_km
            problems.append(f"deorbit.preparation_orbit.altitude_km: {altitude:g} km")
        if problems:
            raise ValueError(
                "; ".join(problems)
                + f" below the minimum perigee altitude (allowed >= {floor:g} km,"
                " limits.min_perigee_altitude_km)"
            )
        return self

    @model_validator(mode="after")
    def _entry_below_preparation_orbit(self) -> Scenario:
        if self.deorbit is None:
            return self
        entry = self.deorbit.entry.altitude_km
        orbit = self.deorbit.preparation_orbit.altitude_km
        if entry >= orbit:
            raise ValueError(
                f"deorbit.entry.altitude_km = {entry:g} must lie below the preparation orbit "
                f"(deorbit.preparation_orbit.altitude_km = {orbit:g})"
            )
        return self

    @model_validator(mode="after")
    def _mission_bounds_inside_the_stages(self) -> Scenario:
        if self.mission is None:
            return self
        missing = [name for name in ("launch", "deorbit", "reentry") if getattr(self, name) is None]
        if missing:
            raise ValueError(f"mission: needs the {', '.join(missing)} section(s) too")
        parking = self.mission.design_bounds.parking_altitude_km
        fit = self.launch.fit
        if parking.lower < fit.altitude_min_km or parking.upper > fit.altitude_max_km:
            raise ValueError(
                f"mission.design_bounds.parking_altitude_km [{parking.lower:g}, "
                f"{parking.upper:g}] must lie inside the launch fit's range "
                f"[{fit.altitude_min_km:g}, {fit.altitude_max_km:g}] km (launch.fit)"
            )
        prep = self.mission.design_bounds.preparation_altitude_km
        floor = max(self.limits.min_perigee_altitude_km, self.deorbit.entry.altitude_km)
        if prep.lower <= floor:
            raise ValueError(
                f"mission.design_bounds.preparation_altitude_km lower bound {prep.lower:g} km "
                f"must lie above {floor:g} km (minimum perigee and entry altitude)"
            )
        delay = self.mission.design_bounds.separation_delay_h
        if delay.lower < 0.0:
            raise ValueError("mission.design_bounds.separation_delay_h must not be negative")
        return self

    @property
    def epoch(self) -> Epoch:
        return Epoch.from_iso(self.epoch_utc)

    def resolved(self) -> dict[str, Any]:
        """The scenario with every default filled in, as plain data (for run stores)."""
        return self.model_dump(mode="json")


def scenario_from_dict(data: Any, source: str = "") -> Scenario:
    """Validate a mapping into a :class:`Scenario`, raising :class:`ConfigError`."""
    return model_from_dict(Scenario, data, source)
