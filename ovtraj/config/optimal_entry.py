"""Settings of the pseudospectral optimal-entry solver (seed 001).

A published optimal-entry problem is posed by a YAML file alone: Earth constants,
vehicle and aerodynamics, atmosphere, fixed initial state, terminal conditions (fixed
or bounded), state and control bounds, path limits, objective, transcription, solver,
initial-guess and feasibility-check settings. Angles are in degrees, altitudes in km,
heat rate in kW/m^2 and dynamic pressure in kPa in the file (the key names say so);
:mod:`ovtraj.studies.optimal_entry.problem` converts to SI once and refuses problems
that cannot be posed (terminal energy not below the initial one, an initial state
outside the state bounds, ...), naming the field.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from ovtraj.config.base import StrictModel, bounded, load_model, model_from_dict
from ovtraj.config.reentry import PolynomialAeroConfig

__all__ = [
    "BoundConfig",
    "ControlBoundConfig",
    "OptimalEntryConfig",
    "load_optimal_entry_config",
    "optimal_entry_config_from_dict",
]

Objective = Literal["max_downrange", "max_crossrange", "min_heat_load", "min_time"]
Independent = Literal["energy", "time"]
Method = Literal["lg", "lgr"]
Backend = Literal["ipopt", "slsqp", "trust-constr"]
Interpolation = Literal["linear", "cubic"]


class EarthSettingsConfig(StrictModel):
    """Earth model of the problem; ``null`` takes the project value (``configs/earth.yaml``).

    Problems stated in other unit systems (e.g. feet and slugs) give their own radius and
    ``mu`` converted to SI.
    """

    mu_m3_s2: float | None = bounded(unit="m^3/s^2", gt=0, le=1.0e18, default=None)
    radius_m: float | None = bounded(unit="m", gt=0, le=1.0e8, default=None)
    rotation_rate_rad_s: float | None = bounded(unit="rad/s", ge=0, le=1.0e-2, default=None)
    g0_m_s2: float | None = bounded(
        unit="m/s^2",
        gt=0,
        le=100,
        default=None,
        description="load-factor unit and constant gravity",
    )
    gravity: Literal["inverse_square", "constant"]
    rotating: bool


class VehicleSettingsConfig(StrictModel):
    name: str
    mass_kg: float = bounded(unit="kg", gt=0, le=1.0e6)
    reference_area_m2: float = bounded(
        unit="m^2", gt=0, le=1000, description="the Space Shuttle's wing: 250 m^2"
    )
    aero: PolynomialAeroConfig


class AtmosphereSettingsConfig(StrictModel):
    """US76 (closed form below 86 km in the NLP), or ``rho0 exp(-h / H)``."""

    model: Literal["us76", "exponential"]
    density0_kg_m3: float | None = bounded(unit="kg/m^3", gt=0, le=100, default=None)
    scale_height_km: float | None = bounded(unit="km", gt=0, le=100, default=None)
    speed_of_sound_mps: float | None = bounded(unit="m/s", gt=0, le=2000, default=None)
    upper_sound_step_km: float = bounded(
        unit="km",
        ge=0.01,
        le=50,
        default=1.0,
        description="US76 above 86 km: sampling of the speed of sound for the NLP",
    )

    @model_validator(mode="after")
    def _exponential_complete(self) -> AtmosphereSettingsConfig:
        if self.model == "exponential":
            missing = [
                name
                for name in ("density0_kg_m3", "scale_height_km", "speed_of_sound_mps")
                if getattr(self, name) is None
            ]
            if missing:
                raise ValueError(f"the exponential model needs {', '.join(missing)}")
        return self


class InitialStateConfig(StrictModel):
    """The fixed initial state, Earth-relative (geocentric latitude, spherical Earth)."""

    altitude_km: float = bounded(unit="km", ge=0, le=1000)
    speed_mps: float = bounded(unit="m/s", gt=0, le=20000)
    fpa_deg: float = bounded(unit="deg", gt=-90, lt=90)
    longitude_deg: float = bounded(unit="deg", ge=-360, le=360)
    latitude_deg: float = bounded(unit="deg", gt=-90, lt=90)
    heading_deg: float = bounded(unit="deg", ge=-360, le=360, description="from north, clockwise")


class BoundConfig(StrictModel):
    """A fixed value (``value``) or bounds (``lower`` and/or ``upper``)."""

    value: float | None = Field(default=None, allow_inf_nan=False)
    lower: float | None = Field(default=None, allow_inf_nan=False)
    upper: float | None = Field(default=None, allow_inf_nan=False)

    @model_validator(mode="after")
    def _consistent(self) -> BoundConfig:
        if self.value is not None and (self.lower is not None or self.upper is not None):
            raise ValueError("give either value or lower/upper, not both")
        if self.value is None and self.lower is None and self.upper is None:
            raise ValueError("give value, or lower and/or upper")
        if self.lower is not None and self.upper is not None and self.lower > self.upper:
            raise ValueError(f"empty bounds: lower ({self.lower:g}) > upper ({self.upper:g})")
        return self

    def interval(self) -> tuple[float, float]:
        """``(lower, upper)``, infinite where not given."""
        if self.value is not None:
            return self.value, self.value
        lower = -float("inf") if self.lower is None else self.lower
        upper = float("inf") if self.upper is None else self.upper
        return lower, upper

    @property
    def fixed(self) -> bool:
        return self.value is not None


class TerminalConfig(StrictModel):
    """Terminal conditions; altitude and speed are required (they fix the terminal energy)."""

    altitude_km: BoundConfig
    speed_mps: BoundConfig
    fpa_deg: BoundConfig | None = None
    heading_deg: BoundConfig | None = None
    latitude_deg: BoundConfig | None = None
    longitude_deg: BoundConfig | None = None


def _ordered_pair(value: tuple[float, float]) -> tuple[float, float]:
    lower, upper = value
    if not (abs(lower) < float("inf") and abs(upper) < float("inf")):
        raise ValueError(f"bounds must be finite numbers, got [{lower:g}, {upper:g}]")
    if lower > upper:
        raise ValueError(f"empty bounds: lower ({lower:g}) > upper ({upper:g})")
    return value


class StateBoundsConfig(StrictModel):
    """Box bounds ``[lower, upper]`` on the states over the whole trajectory."""

    altitude_km: tuple[float, float]
    speed_mps: tuple[float, float]
    fpa_deg: tuple[float, float]
    heading_deg: tuple[float, float]
    latitude_deg: tuple[float, float]
    longitude_deg: tuple[float, float]

    @field_validator("*")
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        return _ordered_pair(value)

    @field_validator("latitude_deg")
    @classmethod
    def _inside_poles(cls, value: tuple[float, float]) -> tuple[float, float]:
        # The longitude rate has 1 / cos(latitude): the poles are singular.
        if not (-90.0 < value[0] and value[1] < 90.0):
            raise ValueError("latitude bounds must lie strictly inside (-90, 90) deg")
        return value

    @field_validator("fpa_deg")
    @classmethod
    def _not_vertical(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not (-90.0 < value[0] and value[1] < 90.0):
            raise ValueError("flight-path angle bounds must lie strictly inside (-90, 90) deg")
        return value


class ControlBoundConfig(StrictModel):
    """Bounds of one control, with an optional rate limit (then the angle becomes a state)."""

    lower_deg: float = bounded(unit="deg", ge=-180, le=180)
    upper_deg: float = bounded(unit="deg", ge=-180, le=180)
    max_rate_deg_s: float | None = bounded(unit="deg/s", gt=0, le=360, default=None)

    @model_validator(mode="after")
    def _not_empty(self) -> ControlBoundConfig:
        if self.lower_deg > self.upper_deg:
            raise ValueError(
                f"empty control bounds: lower_deg ({self.lower_deg:g}) > "
                f"upper_deg ({self.upper_deg:g})"
            )
        return self


class ControlsConfig(StrictModel):
    alpha: ControlBoundConfig
    bank: ControlBoundConfig


class HeatRateConfig(StrictModel):
    """Stagnation heat rate ``Q = k rho^m V^n P(alpha)`` [W/m^2 with SI inputs].

    ``alpha_polynomial`` holds ``P``'s coefficients, constant term first, in the aero's
    angle-of-attack unit; ``[1.0]`` (the default) is no dependence on alpha.
    """

    coefficient: float = bounded(gt=0, le=1, description="k, SI (W/m^2 from kg/m^3 and m/s)")
    density_exponent: float = bounded(gt=0, le=2, description="m")
    speed_exponent: float = bounded(gt=0, le=5, description="n")
    alpha_polynomial: list[float] = Field(
        default_factory=lambda: [1.0], min_length=1, max_length=10
    )
    max_kw_m2: float = bounded(unit="kW/m^2", gt=0, le=1.0e5)

    @field_validator("alpha_polynomial")
    @classmethod
    def _finite(cls, value: list[float]) -> list[float]:
        if not all(abs(c) <= 1.0e6 for c in value):
            raise ValueError("coefficients must be finite, within [-1e6, 1e6]")
        return value


class PathConfig(StrictModel):
    """Path limits; ``null`` leaves a quantity unconstrained."""

    max_load_g: float | None = bounded(unit="g", gt=0, le=100, default=None)
    load_definition: Literal["normal", "total"] = "normal"
    max_dynamic_pressure_kpa: float | None = bounded(unit="kPa", gt=0, le=1000, default=None)
    heat_rate: HeatRateConfig | None = None


class TranscriptionConfig(StrictModel):
    independent: Independent
    method: Method
    segments: int = bounded(ge=1, le=50)
    nodes_per_segment: int = bounded(ge=2, le=200)
    max_refinements: int = bounded(
        ge=0,
        le=20,
        description="h-refinements after the first mesh until the re-flight meets "
        "feasibility.tolerance_km (0: the configured mesh only)",
    )
    max_segments: int = bounded(ge=1, le=400, description="refinement stops at this many segments")
    final_time_bounds_s: tuple[float, float] = Field(
        description="time formulation: bounds of the free final time [s]"
    )

    @field_validator("final_time_bounds_s")
    @classmethod
    def _positive_ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not 0.0 < value[0] < value[1] <= 1.0e5:
            raise ValueError(f"need 0 < lower < upper <= 1e5, got {value[0]:g}, {value[1]:g}")
        return value

    @model_validator(mode="after")
    def _room_to_refine(self) -> TranscriptionConfig:
        if self.max_segments < self.segments:
            raise ValueError(
                f"max_segments ({self.max_segments}) is below segments ({self.segments})"
            )
        return self


class SolverConfig(StrictModel):
    """NLP solver: IPOPT (exact Hessian through CasADi) or a scipy method (fallback)."""

    backend: Backend
    tolerance: float = bounded(gt=0, lt=1, description="IPOPT tol / scipy ftol, scaled NLP")
    constraint_tolerance: float = bounded(gt=0, lt=1, description="IPOPT constr_viol_tol")
    max_iterations: int = bounded(ge=1, le=100000)
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of the solve: guess, NLP, re-flights"
    )
    linear_solver: str = "mumps"
    barrier_strategy: Literal["monotone", "adaptive"] = Field(
        description="IPOPT mu_strategy: the barrier parameter decreased monotonically (Fiacco-"
        "McCormick) or chosen each iteration (Nocedal, Waechter & Waltz, 2009)"
    )
    print_level: int = bounded(ge=0, le=12, default=0)
    expand: bool = Field(
        default=False,
        description="IPOPT: expand the NLP to a scalar (SX) graph: slower to build, faster "
        "iterations",
    )


class GuessConfig(StrictModel):
    """The initial guess: one trajectory integrated with constant controls.

    ``alpha_deg: null`` flies the angle of attack of maximum L/D at the initial Mach
    number (inside the alpha bounds), found on a grid of ``alpha_grid_points``.
    """

    alpha_deg: float | None = bounded(unit="deg", ge=-90, le=90, default=None)
    bank_deg: float = bounded(unit="deg", ge=-90, le=90)
    alpha_grid_points: int = bounded(ge=2, le=10000)
    max_time_s: float = bounded(unit="s", gt=0, le=100000)
    relative_tolerance: float = bounded(gt=0, lt=1)


class FeasibilityConfig(StrictModel):
    """Seed 001 section 3.3: the optimal controls re-flown by an independent integrator."""

    interpolations: list[Interpolation] = Field(min_length=1)
    relative_tolerance: float = bounded(gt=0, lt=1)
    absolute_tolerance: float = bounded(gt=0, lt=1)
    tolerance_km: float = bounded(
        unit="km",
        gt=0,
        le=1.0e4,
        description="a result converges only if every re-flight ends this close to the "
        "optimised terminal point",
    )
    tolerance_deg: float = bounded(
        unit="deg",
        gt=0,
        le=180,
        description="... and its terminal angles (fpa, heading, latitude, longitude) this close",
    )


class OptimalEntryConfig(StrictModel):
    name: str
    source: str = Field(description="where the problem is published")
    earth: EarthSettingsConfig
    vehicle: VehicleSettingsConfig
    atmosphere: AtmosphereSettingsConfig
    initial: InitialStateConfig
    terminal: TerminalConfig
    state_bounds: StateBoundsConfig
    controls: ControlsConfig
    path: PathConfig
    objective: Objective
    transcription: TranscriptionConfig
    solver: SolverConfig
    guess: GuessConfig
    feasibility: FeasibilityConfig


def optimal_entry_config_from_dict(data: Any, source: str = "") -> OptimalEntryConfig:
    """Validate a mapping into an :class:`OptimalEntryConfig`, raising :class:`ConfigError`."""
    return model_from_dict(OptimalEntryConfig, data, source)


def load_optimal_entry_config(path: str | Path) -> OptimalEntryConfig:
    """Read and validate an optimal-entry YAML file."""
    return load_model(OptimalEntryConfig, path)
