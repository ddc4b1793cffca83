"""The air-launch stage's configuration: the launcher, the drop, the programme bounds.

A launcher (``configs/launchers/*.yaml``) holds the rocket's figures: solid stages,
fairing, wing, aerodynamic tables and structural limits. The scenario's ``launch``
section names a launcher file (or inlines one) and adds what belongs to the
mission: the drop point, the launch day, the opportunity, the target altitude,
the bounds of the ten design variables, the insertion tolerances and the
optimiser's settings. Units are part of every key name; ``launch_input`` in
:mod:`ovtraj.launch.inputs` converts to SI once.
"""

from __future__ import annotations

import datetime
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from ovtraj.config.base import ConfigError, StrictModel, bounded, parse_yaml
from ovtraj.config.physical import default_earth
from ovtraj.paths import config_dir

# The ten design variables of patent step 101, in the order of the design vector.
DESIGN_VARIABLES: tuple[str, ...] = (
    "azimuth_offset_deg",
    "alpha_1_deg",
    "t_12_s",
    "alpha_2_deg",
    "t_23_s",
    "coast_s",
    "pitch_rate_2_deg_s",
    "pitch_3_deg",
    "pitch_rate_3_deg_s",
    "payload_kg",
)

# The target altitudes a launch may aim at [km]. Below ~150 km drag brings a circular orbit
# down within about a day (US76: 2.1e-9 kg/m^3 at 150 km), so it is no orbit to aim at;
# 2000 km is the upper edge of low Earth orbit (the IADC Space Debris Mitigation
# Guidelines' LEO region), far beyond what this class of air-launched rocket lifts a
# payload to. The scenario's target and fit-grid altitudes and launch_input's override.
TARGET_ALTITUDE_MIN_KM = 150.0
TARGET_ALTITUDE_MAX_KM = 2000.0


class SolidStageConfig(StrictModel):
    """One solid-rocket stage: masses, vacuum performance, nozzle and separation."""

    name: str
    gross_mass_kg: float = bounded(unit="kg", gt=0, le=1.0e6, description="stage mass at ignition")
    propellant_mass_kg: float = bounded(unit="kg", gt=0, le=1.0e6)
    vacuum_thrust_n: float = bounded(unit="N", gt=0, le=1.0e8, description="average vacuum thrust")
    vacuum_isp_s: float = bounded(unit="s", gt=0, le=500, description="solid motors: ~300 s")
    burn_time_s: float = bounded(unit="s", gt=0, le=1000, description="published action time")
    nozzle_exit_area_m2: float = bounded(
        unit="m^2", ge=0, le=50, description="back-pressure thrust loss p_a * A_e"
    )
    jettisoned_with_stage_kg: float = bounded(
        unit="kg",
        ge=0,
        le=1.0e5,
        default=0.0,
        description="interstage/other mass dropped at burnout",
    )

    @model_validator(mode="after")
    def _propellant_below_gross(self) -> SolidStageConfig:
        if self.propellant_mass_kg >= self.gross_mass_kg:
            raise ValueError(
                f"propellant_mass_kg ({self.propellant_mass_kg:g}) must be below "
                f"gross_mass_kg ({self.gross_mass_kg:g})"
            )
        return self

    @property
    def inert_mass_kg(self) -> float:
        return self.gross_mass_kg - self.propellant_mass_kg

    def mass_flow_kg_s(self, g0: float) -> float:
        """Propellant mass flow [kg/s] = F_vac / (Isp g0)."""
        return self.vacuum_thrust_n / (self.vacuum_isp_s * g0)

    def derived_burn_time_s(self, g0: float) -> float:
        """Burn time [s] implied by propellant, thrust and Isp: m_p Isp g0 / F_vac."""
        return self.propellant_mass_kg / self.mass_flow_kg_s(g0)


class FairingConfig(StrictModel):
    """The payload fairing: dropped once the vehicle climbs above ``jettison_altitude_km``."""

    mass_kg: float = bounded(unit="kg", ge=0, le=1.0e4)
    jettison_altitude_km: float = bounded(unit="km", gt=0, le=500)
    earliest_stage: int = bounded(ge=1, le=3, description="stage (1-based) from which it may go")


class AeroTableConfig(StrictModel):
    """Axial- and normal-force coefficients against Mach, monotone cubic (PCHIP) in Mach.

    Body: ``C_A(M)`` and ``C_N = C_N_alpha(M) sin(alpha)`` on ``reference_area_m2``.
    Wing (first-stage flight only): ``C_N_alpha_wing(M)`` on ``wing_area_m2``.
    Lift and drag follow from the body-axis forces (``C_L = C_N cos a - C_A sin a``,
    ``C_D = C_N sin a + C_A cos a``).
    """

    reference_area_m2: float = bounded(unit="m^2", gt=0, le=100)
    wing_area_m2: float = bounded(unit="m^2", ge=0, le=1000)
    mach: tuple[float, ...] = Field(min_length=2)
    axial_force_coefficient: tuple[float, ...] = Field(min_length=2)
    normal_force_slope_per_rad: tuple[float, ...] = Field(min_length=2)
    wing_normal_force_slope_per_rad: tuple[float, ...] = Field(min_length=2)
    axial_force_scale_above_stage_1: float = bounded(
        ge=0, le=1, description="C_A of the upper stack relative to the full vehicle"
    )
    mach_resolution: float = bounded(ge=1e-4, le=0.1, description="resampling of the PCHIP curves")

    @model_validator(mode="after")
    def _consistent_table(self) -> AeroTableConfig:
        n = len(self.mach)
        for name in (
            "axial_force_coefficient",
            "normal_force_slope_per_rad",
            "wing_normal_force_slope_per_rad",
        ):
            if len(getattr(self, name)) != n:
                raise ValueError(f"{name} has {len(getattr(self, name))} values, mach has {n}")
            if not all(0.0 <= c <= 100.0 for c in getattr(self, name)):
                raise ValueError(f"{name} values must lie in [0, 100]")
        if any(b <= a for a, b in zip(self.mach, self.mach[1:], strict=False)):
            raise ValueError("mach must be strictly increasing")
        if not self.mach[-1] <= 50.0:
            raise ValueError(f"mach values must lie in [0, 50], got up to {self.mach[-1]:g}")
        if self.mach[0] != 0.0:
            raise ValueError("mach must start at 0")
        return self


class LauncherLimitsConfig(StrictModel):
    max_dynamic_pressure_kpa: float = bounded(unit="kPa", gt=0, le=1000)
    max_axial_load_g: float = bounded(unit="g0", gt=0, le=100)


class PublishedPerformance(StrictModel):
    """A published payload figure, for benchmarks (not used by the solver)."""

    altitude_km: float = bounded(unit="km", gt=0, le=100000)
    inclination_deg: float = bounded(unit="deg", ge=0, le=180)
    payload_kg: float = bounded(unit="kg", gt=0, le=1.0e6)
    source: str


class LauncherConfig(StrictModel):
    """A multi-stage solid air-launched rocket (Pegasus XL class)."""

    name: str
    stages: tuple[SolidStageConfig, ...] = Field(min_length=3, max_length=3)
    fairing: FairingConfig
    aero: AeroTableConfig
    limits: LauncherLimitsConfig
    free_fall_s: float = bounded(unit="s", ge=0, le=60, description="drop to stage-1 ignition")
    separation_coast_s: float = bounded(
        unit="s", ge=0, le=600, description="stage-1 burnout to 2 ignition"
    )
    alpha_drop_deg: float = bounded(unit="deg", ge=-10, le=30, description="alpha at the drop")
    max_alpha_rate_deg_s: float = bounded(unit="deg/s", gt=0, le=90, description="programme ramps")
    burn_time_tolerance: float = bounded(
        gt=0, le=0.5, description="allowed mismatch of burn time vs propellant/thrust/Isp"
    )
    published_performance: tuple[PublishedPerformance, ...] = ()

    @model_validator(mode="after")
    def _stage_data_consistent(self) -> LauncherConfig:
        g0 = _standard_gravity()
        problems = []
        for k, stage in enumerate(self.stages, start=1):
            derived = stage.derived_burn_time_s(g0)
            mismatch = abs(stage.burn_time_s - derived) / derived
            if mismatch > self.burn_time_tolerance:
                problems.append(
                    f"stages[{k}] ({stage.name}): burn_time_s {stage.burn_time_s:g} s does not "
                    f"match propellant * Isp * g0 / thrust = {derived:.1f} s "
                    f"({100 * mismatch:.1f} % apart, allowed {100 * self.burn_time_tolerance:g} %)"
                )
        if self.fairing.earliest_stage > len(self.stages):
            problems.append(f"fairing.earliest_stage must be at most {len(self.stages)}")
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def ignition_masses_kg(self, payload_kg: float) -> list[float]:
        """Mass of the stack at each stage's ignition (fairing still on)."""
        above = payload_kg + self.fairing.mass_kg
        masses = []
        for stage in reversed(self.stages):
            above += stage.gross_mass_kg + stage.jettisoned_with_stage_kg
            masses.append(above)
        return masses[::-1]

    def check_thrust_to_weight(self, payload_kg: float, g0: float) -> list[str]:
        """Stages whose vacuum thrust does not exceed the weight of the stack at ignition."""
        problems = []
        for k, (stage, mass) in enumerate(
            zip(self.stages, self.ignition_masses_kg(payload_kg), strict=True), start=1
        ):
            weight = mass * g0
            if stage.vacuum_thrust_n <= weight:
                problems.append(
                    f"stages[{k}] ({stage.name}): vacuum_thrust_n {stage.vacuum_thrust_n:g} N "
                    f"does not exceed the weight at ignition {weight:.0f} N "
                    f"({mass:.0f} kg with a {payload_kg:g} kg payload)"
                )
        return problems


def _standard_gravity() -> float:
    """g0 [m/s^2] of ``configs/earth.yaml``, for the plausibility checks of launcher data."""
    return default_earth().g0_m_s2


class DropConfig(StrictModel):
    """The carrier's release point (spherical Earth, geocentric latitude)."""

    latitude_deg: float = bounded(unit="deg", ge=-90, le=90)
    longitude_deg: float = bounded(unit="deg", ge=-360, le=360)
    altitude_km: float = bounded(unit="km", gt=0, le=30)
    mach: float = bounded(gt=0, le=3)
    flight_path_angle_deg: float = bounded(unit="deg", ge=-30, le=30)


class Bound(StrictModel):
    """``[lower, upper]``, finite; the model holding it bounds it further (units in its name)."""

    lower: float = Field(allow_inf_nan=False)
    upper: float = Field(allow_inf_nan=False)

    @model_validator(mode="after")
    def _ordered(self) -> Bound:
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower:g}) must be below upper ({self.upper:g})")
        return self


# Plausible ranges of the design variables' bounds (config units): angles within a
# quadrant or half-turn, times within a Pegasus-class flight (stages burn ~70 s, the
# coast to stage 3 ~10 min), payloads up to the largest launchers' (~100 t).
_DESIGN_LIMITS: dict[str, tuple[float, float]] = {
    "azimuth_offset_deg": (-180.0, 180.0),
    "alpha_1_deg": (-90.0, 90.0),
    "t_12_s": (0.0, 1000.0),
    "alpha_2_deg": (-90.0, 90.0),
    "t_23_s": (0.0, 1000.0),
    "coast_s": (0.0, 10000.0),
    "pitch_rate_2_deg_s": (-10.0, 10.0),
    "pitch_3_deg": (-180.0, 180.0),
    "pitch_rate_3_deg_s": (-10.0, 10.0),
    "payload_kg": (0.0, 1.0e5),
}


class DesignBoundsConfig(StrictModel):
    """Bounds of the ten design variables (patent step 101).

    The launch azimuth is bounded around the in-plane azimuth of the chosen
    opportunity (``asin(cos i / cos latitude)`` or its supplement), hence an offset.
    Pitch angles are measured in the launch frame from its downrange axis.
    """

    azimuth_offset_deg: Bound
    alpha_1_deg: Bound
    t_12_s: Bound
    alpha_2_deg: Bound
    t_23_s: Bound
    coast_s: Bound
    pitch_rate_2_deg_s: Bound
    pitch_3_deg: Bound
    pitch_rate_3_deg_s: Bound
    payload_kg: Bound

    @model_validator(mode="after")
    def _physical(self) -> DesignBoundsConfig:
        problems = []
        for name, (lo, hi) in _DESIGN_LIMITS.items():
            bound = getattr(self, name)
            if not lo <= bound.lower < bound.upper <= hi:
                problems.append(
                    f"{name} [{bound.lower:g}, {bound.upper:g}] must lie in [{lo:g}, {hi:g}]"
                )
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def as_arrays(self) -> tuple[list[float], list[float]]:
        lower = [getattr(self, name).lower for name in DESIGN_VARIABLES]
        upper = [getattr(self, name).upper for name in DESIGN_VARIABLES]
        return lower, upper


class InsertionTolerancesConfig(StrictModel):
    """How close the insertion must be to the target orbit to count as met."""

    altitude_m: float = bounded(unit="m", gt=0, le=100000)
    speed_mps: float = bounded(unit="m/s", gt=0, le=1000)
    flight_path_angle_deg: float = bounded(unit="deg", gt=0, le=10)
    inclination_deg: float = bounded(unit="deg", gt=0, le=10)
    path_limit_fraction: float = bounded(
        gt=0,
        le=0.05,
        description="a path maximum counts as within its limit up to this fraction over it",
    )


class IntegrationConfig(StrictModel):
    """Fixed-step RK4 of the ascent, vectorised over a population (see docs/launch.md)."""

    powered_step_s: float = bounded(unit="s", ge=0.01, le=5)
    coast_step_s: float = bounded(unit="s", ge=0.01, le=60)
    trajectory_step_s: float = bounded(
        unit="s", ge=0.01, le=3600, description="trajectory table sampling"
    )
    atmosphere_table_step_m: float = bounded(
        unit="m", ge=1, le=1000, description="US76 sampled for the vectorised ascent"
    )


class GeneticConfig(StrictModel):
    population: int = bounded(ge=4, le=10000)
    generations: int = bounded(ge=1, le=10000)
    time_limit_s: float = bounded(unit="s", gt=0, le=86400, description="wall time of the GA")
    seed: int = bounded(ge=0, le=2**32 - 1)
    constraint_relaxation: float = bounded(
        ge=1,
        le=10000,
        description="the GA accepts |c| up to this many tolerances; the local phases close it",
    )


class LocalConfig(StrictModel):
    slsqp_max_iterations: int = bounded(ge=1, le=10000)
    slsqp_ftol: float = bounded(gt=0, lt=1)
    trust_constr_max_iterations: int = bounded(ge=0, le=10000)
    trust_constr_gtol: float = bounded(gt=0, lt=1)
    trust_constr_xtol: float = bounded(gt=0, lt=1)
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of each local phase"
    )
    finite_difference_step: float = bounded(gt=0, lt=0.1, description="scaled variables")
    stall_iterations: int = bounded(ge=1, le=1000)
    stall_payload_kg: float = bounded(
        unit="kg",
        ge=0,
        le=1000,
        description="a phase whose payload moves less over stall_iterations stops",
    )
    converged_residual: float = bounded(
        gt=0,
        le=1,
        description="a design is converged when every |c| is within this fraction of its "
        "tolerance; converged designs rank above merely feasible ones",
    )


class FitGridConfig(StrictModel):
    """Target altitudes of the launch fit (patent 5.1) and the series' settings."""

    altitude_min_km: float = bounded(unit="km", ge=TARGET_ALTITUDE_MIN_KM)
    altitude_max_km: float = bounded(unit="km", le=TARGET_ALTITUDE_MAX_KM)
    points: int = bounded(ge=3, le=1000)
    order: int = bounded(ge=1, le=20)
    ridge_candidates: tuple[float, ...] = Field(
        min_length=1,
        description="Tikhonov weights on the harmonics (fourier.py); each output's fit "
        "keeps the one with the smallest leave-one-out error",
    )

    @field_validator("ridge_candidates")
    @classmethod
    def _non_negative_ridges(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        bad = [r for r in value if not 0.0 <= r <= 1.0e6]
        if bad:
            raise ValueError(f"ridge weights must lie in [0, 1e6], got {bad}")
        return value

    @model_validator(mode="after")
    def _ordered(self) -> FitGridConfig:
        if not self.altitude_min_km < self.altitude_max_km:
            raise ValueError("altitude_min_km must be below altitude_max_km")
        return self

    def altitudes_km(self) -> list[float]:
        step = (self.altitude_max_km - self.altitude_min_km) / (self.points - 1)
        return [self.altitude_min_km + k * step for k in range(self.points)]


Opportunity = Literal["ascending", "descending"]


class LaunchSettings(StrictModel):
    """The scenario's ``launch`` section (patent step 101)."""

    launcher: LauncherConfig
    drop: DropConfig
    launch_date_utc: str = Field(description="the launch day; times are counted from its 0 h")
    opportunity: Opportunity
    target_altitude_km: float = bounded(
        unit="km", ge=TARGET_ALTITUDE_MIN_KM, le=TARGET_ALTITUDE_MAX_KM
    )
    design_bounds: DesignBoundsConfig
    insertion_tolerances: InsertionTolerancesConfig
    integration: IntegrationConfig
    genetic: GeneticConfig
    local: LocalConfig
    fit: FitGridConfig

    @model_validator(mode="before")
    @classmethod
    def _load_launcher_file(cls, data: Any, info: ValidationInfo) -> Any:
        """``launcher: launchers/x.yaml`` reads that file: relative to the config file's
        folder, else to the shipped ``configs/``."""
        if isinstance(data, dict) and isinstance(data.get("launcher"), str):
            data = dict(data)
            source_dir = (info.context or {}).get("source_dir")
            data["launcher"] = _read_launcher(data["launcher"], source_dir)
        return data

    @field_validator("launch_date_utc")
    @classmethod
    def _a_date(cls, value: str) -> str:
        try:
            datetime.date.fromisoformat(value)
        except ValueError:
            from ovtraj.config.io_limits import echoed

            raise ValueError(
                f"must be a calendar date YYYY-MM-DD, got {echoed(repr(value))}"
            ) from None
        return value

    @model_validator(mode="after")
    def _feasible_figures(self) -> LaunchSettings:
        # Target altitudes below TARGET_ALTITUDE_MIN_KM are refused by the fields' bounds.
        lightest = self.design_bounds.payload_kg.lower
        problems = self.launcher.check_thrust_to_weight(lightest, _standard_gravity())
        if problems:
            raise ValueError("; ".join(problems))
        return self


def _read_launcher(name: str, source_dir: Path | None) -> dict[str, Any]:
    path = Path(name).expanduser()
    if not path.is_absolute():
        beside = source_dir / path if source_dir is not None else None
        path = beside if beside is not None and beside.is_file() else config_dir() / path
    from ovtraj.config.io_limits import read_config_file

    try:
        text = read_config_file(path)
    except ConfigError as err:
        raise ValueError(f"launcher file {path}: {'; '.join(err.problems)}") from None
    try:
        data = parse_yaml(text)
    except ValueError as err:
        raise ValueError(f"launcher file {path}: {err}") from None
    if not isinstance(data, dict):
        raise ValueError(f"launcher file {path} must hold a mapping")
    return data
