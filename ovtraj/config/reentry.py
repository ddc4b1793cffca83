"""Settings of the reentry stage (patent step 104): vehicle, limits, guidance, entry.

Angles in degrees, distances in km, heat rate in kW/m^2 in the file (the key
names say so); the stage converts to SI once, in :mod:`ovtraj.reentry.inputs`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from ovtraj.config.base import StrictModel, bounded


class PolynomialAeroConfig(StrictModel):
    """``C = sum_ij c[i][j] alpha^i Mach^j`` for lift and drag (row i: power of alpha).

    The seed-001 fit ``CL = 0.000181 a^2 + 0.022956 a - 0.010935 Ma + 0.0042806``
    (a in degrees) is ``cl: [[0.0042806, -0.010935], [0.022956, 0], [0.000181, 0]]``.
    """

    alpha_unit: Literal["deg", "rad"]
    cl: list[list[float]] = Field(min_length=1)
    cd: list[list[float]] = Field(min_length=1)

    @field_validator("cl", "cd")
    @classmethod
    def _rectangular(cls, value: list[list[float]]) -> list[list[float]]:
        widths = {len(row) for row in value}
        if len(widths) != 1 or 0 in widths:
            raise ValueError("coefficient rows must be non-empty and of equal length")
        if len(value) > 10 or widths.pop() > 10:
            raise ValueError("at most 10 x 10 coefficients (powers 0-9 of alpha and Mach)")
        if not all(abs(c) <= 1.0e6 for row in value for c in row):
            raise ValueError("coefficients must be finite, within [-1e6, 1e6]")
        return value


class AlphaScheduleConfig(StrictModel):
    """Angle of attack as a piecewise-linear function of Mach (held outside the table)."""

    mach: list[float] = Field(min_length=2)
    alpha_deg: list[float] = Field(min_length=2)

    @model_validator(mode="after")
    def _increasing_mach(self) -> AlphaScheduleConfig:
        if len(self.mach) != len(self.alpha_deg):
            raise ValueError(
                f"mach ({len(self.mach)} values) and alpha_deg ({len(self.alpha_deg)}) "
                "must have the same length"
            )
        if any(b <= a for a, b in zip(self.mach, self.mach[1:], strict=False)):
            raise ValueError(f"mach must be strictly increasing, got {self.mach}")
        if not (0.0 <= self.mach[0] and self.mach[-1] <= 100.0):
            raise ValueError(f"mach values must lie in [0, 100], got {self.mach}")
        if any(not -90.0 <= a <= 90.0 for a in self.alpha_deg):
            raise ValueError("alpha_deg values must lie in [-90, 90] deg")
        return self


class ReentryVehicleConfig(StrictModel):
    name: str
    mass_kg: float = bounded(unit="kg", gt=0, le=1.0e6)
    reference_area_m2: float = bounded(
        unit="m^2", gt=0, le=1000, description="the Space Shuttle's wing: 250 m^2"
    )
    aero: PolynomialAeroConfig
    alpha_schedule: AlphaScheduleConfig


class ReentryLimitsConfig(StrictModel):
    heat_rate_coefficient: float = bounded(
        gt=0,
        le=1,
        description="k_Q of Q = k_Q sqrt(rho) V^3.15 [SI: W/m^2 with rho kg/m^3, V m/s]",
    )
    heat_rate_exponent: float = bounded(gt=0, le=5, description="the 3.15 of Q")
    max_heat_rate_kw_m2: float = bounded(unit="kW/m^2", gt=0, le=1.0e5)
    max_load_g: float = bounded(unit="g", gt=0, le=100)
    max_dynamic_pressure_kpa: float = bounded(unit="kPa", gt=0, le=1000)
    max_bank_deg: float = bounded(unit="deg", gt=0, le=90)


class AtmosphereChoiceConfig(StrictModel):
    """US76 (tabulated), or an exponential density with a constant speed of sound."""

    model: Literal["us76", "exponential"]
    table_step_m: float = bounded(unit="m", ge=1, le=5000, default=250.0)
    density0_kg_m3: float = bounded(unit="kg/m^3", gt=0, le=100, default=1.225)
    scale_height_km: float = bounded(unit="km", gt=0, le=100, default=7.2)
    speed_of_sound_mps: float = bounded(unit="m/s", gt=0, le=2000, default=300.0)


class EntryStateConfig(StrictModel):
    """Stand-alone entry state (Earth-relative); the mission chain passes the deorbit's."""

    epoch_utc: str
    latitude_deg: float = bounded(unit="deg", ge=-90, le=90)
    longitude_deg: float = bounded(unit="deg", ge=-360, le=360)
    altitude_km: float = bounded(unit="km", gt=0, le=300)
    speed_mps: float = bounded(unit="m/s", gt=0, le=12000)
    fpa_deg: float = bounded(unit="deg", gt=-90, lt=90)
    heading_deg: float = bounded(unit="deg", ge=-360, le=360, description="from north, clockwise")


class LandingSiteConfig(StrictModel):
    name: str
    latitude_deg: float = bounded(unit="deg", ge=-90, le=90)
    longitude_deg: float = bounded(unit="deg", ge=-360, le=360)


class TerminalInterfaceConfig(StrictModel):
    """Where the entry ends: the terminal speed, with the expected altitude around it."""

    speed_mps: float = bounded(unit="m/s", gt=0, le=12000)
    altitude_km: float = bounded(unit="km", gt=0, le=300)
    altitude_tolerance_km: float = bounded(unit="km", gt=0, le=300)
    miss_tolerance_km: float = bounded(
        unit="km", gt=0, le=20000, description="landing-site miss accepted"
    )


class GuidanceConfig(StrictModel):
    """Bank profile |sigma| linear in speed from sigma_0 (entry) to sigma_1 (terminal).

    Newton on sigma_0 nulls the range-to-go at the terminal speed; golden-section on
    sigma_1 minimises the miss distance plus penalties on path-limit violations.
    The sign of the bank reverses when the heading error leaves a corridor that
    narrows linearly with range to go, from ``corridor_max_deg`` at
    ``corridor_range_km`` down to ``corridor_min_deg`` at the site.
    """

    sigma_1_bounds_deg: tuple[float, float]
    corridor_min_deg: float = bounded(unit="deg", gt=0, le=45)
    corridor_max_deg: float = bounded(unit="deg", gt=0, le=90)
    corridor_range_km: float = bounded(unit="km", gt=0, le=40000)
    newton_iterations: int = bounded(ge=1, le=100)
    newton_tolerance_km: float = bounded(unit="km", gt=0, le=1000)
    finite_difference_deg: float = bounded(unit="deg", gt=0, le=5)
    golden_iterations: int = bounded(ge=1, le=100)
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of the guidance (Newton and golden)"
    )
    violation_weight_km: float = bounded(
        unit="km", ge=0, le=1.0e6, description="penalty per unit relative path-limit violation"
    )

    @model_validator(mode="after")
    def _ordered(self) -> GuidanceConfig:
        lo, hi = self.sigma_1_bounds_deg
        if not 0.0 <= lo < hi <= 90.0:
            raise ValueError(f"sigma_1_bounds_deg needs 0 <= lower < upper <= 90, got {lo}, {hi}")
        if self.corridor_min_deg > self.corridor_max_deg:
            raise ValueError("corridor_min_deg must not exceed corridor_max_deg")
        return self


class ReentryIntegrationConfig(StrictModel):
    step_s: float = bounded(unit="s", ge=0.001, le=10)
    max_time_s: float = bounded(unit="s", gt=0, le=100000)
    earth_rotation: bool = True
    skip_altitude_margin_km: float = bounded(
        unit="km",
        gt=0,
        le=1000,
        description="above the entry altitude plus this, the OV has skipped out",
    )
    trajectory_step_s: float = bounded(unit="s", ge=0.01, le=3600)


class ReentrySettings(StrictModel):
    vehicle: ReentryVehicleConfig
    limits: ReentryLimitsConfig
    atmosphere: AtmosphereChoiceConfig
    entry: EntryStateConfig
    landing_site: LandingSiteConfig
    terminal: TerminalInterfaceConfig
    guidance: GuidanceConfig
    integration: ReentryIntegrationConfig
