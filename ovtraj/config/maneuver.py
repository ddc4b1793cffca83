"""Settings of the quick orbit manoeuvre of an upper stage (seed 003).

A manoeuvre is posed by a YAML file alone: the stage (mass, thrust, specific impulse,
working time), the chaser's and the target's orbits, the manoeuvre (end condition,
objective, number of impulses, time-of-flight bounds, dynamics, budget rules), the
improved differential evolution (IDE) or scipy's, the Lambert solver, the finite-thrust
correction and the integrator. Angles are in degrees and lengths in km in the file (the
key names say so); :mod:`ovtraj.studies.maneuver.problem` converts to SI once. Bad values are
refused with one line per field naming the allowed range (:class:`ConfigError`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from ovtraj.config.base import StrictModel, bounded, load_model, model_from_dict

__all__ = [
    "BudgetConfig",
    "FiniteBurnConfig",
    "ManeuverConfig",
    "ManeuverSettingsConfig",
    "OptimizerConfig",
    "OrbitConfig",
    "PublishedConfig",
    "StageConfig",
    "load_maneuver_config",
    "maneuver_config_from_dict",
]

EndCondition = Literal["interception", "rendezvous", "transfer"]
Objective = Literal["min_time", "min_dv"]
Dynamics = Literal["two_body", "j2"]
ImpulseFrame = Literal["eci", "rsw"]
Method = Literal["ide", "scipy"]
DvLimit = Literal["seed_eq14", "rocket_equation"]


class StageConfig(StrictModel):
    """The upper stage: constant vacuum thrust and specific impulse (seed sec. 2.2)."""

    name: str
    initial_mass_kg: float = bounded(
        unit="kg", gt=0, le=1.0e7, description="m0, stage plus payload"
    )
    thrust_n: float = bounded(unit="N", gt=0, le=1.0e8, description="F_e, vacuum thrust")
    specific_impulse_n_s_kg: float = bounded(
        unit="N s/kg", gt=0, le=50000, description="I_sp as effective exhaust speed (= m/s)"
    )
    max_burn_time_s: float = bounded(
        unit="s", gt=0, le=100000, description="t_e, engine working time"
    )

    @model_validator(mode="after")
    def _propellant_left(self) -> StageConfig:
        burnt = self.thrust_n * self.max_burn_time_s / self.specific_impulse_n_s_kg
        if burnt >= self.initial_mass_kg:
            raise ValueError(
                f"max_burn_time_s = {self.max_burn_time_s:g}: {burnt:.1f} kg of propellant, "
                f"not less than initial_mass_kg = {self.initial_mass_kg:g}"
            )
        return self


class OrbitConfig(StrictModel):
    """Osculating classical elements at t = 0 (a, e, i, RAAN, argp, M), as the seed lists them.

    A perigee inside the Earth is refused when the problem is built (it needs the Earth
    model's radius).
    """

    semi_major_axis_km: float = bounded(unit="km", gt=0, le=1.0e6)
    eccentricity: float = bounded(ge=0, lt=1)
    inclination_deg: float = bounded(unit="deg", ge=0, le=180)
    raan_deg: float = bounded(unit="deg", ge=-360, le=360)
    arg_perigee_deg: float = bounded(unit="deg", ge=-360, le=360)
    mean_anomaly_deg: float = bounded(unit="deg", ge=-360, le=360, default=0.0)


class BudgetConfig(StrictModel):
    """Which limits bound the impulses (seed eqs. 4, 13, 14, 15)."""

    dv_limit: DvLimit = Field(
        description="seed_eq14: sum |dv| <= F t_e / (m0 - F t_e / c) (eq. 4 with eq. 14); "
        "rocket_equation: sum |dv| <= c ln(m0 / m_e)"
    )
    burn_time_limit: bool = Field(
        description="also require the eq. 15 burn times of the impulses to sum to <= t_e "
        "(eq. 13): the stage's true capacity"
    )


class ManeuverSettingsConfig(StrictModel):
    end_condition: EndCondition
    objective: Objective
    impulses: int = bounded(ge=2, le=6, description="n, counting the final one")
    time_of_flight_bounds_s: tuple[float, float] = Field(
        description="[lower, upper] of t_f, the end of the manoeuvre [s]"
    )
    impulse_frame: ImpulseFrame = Field(
        description="axes of the free impulse components: eci (seed eq. 2) or local rsw"
    )
    impulse_component_bound_mps: float = bounded(
        unit="m/s", gt=0, le=20000, description="bound of each free impulse component"
    )
    dynamics: Dynamics = Field(description="impulsive model: two-body (seed eq. 3) or J2")
    budget: BudgetConfig
    min_perigee_altitude_km: float = bounded(
        unit="km", ge=0, le=100000, description="lowest altitude allowed on any coast arc"
    )

    @field_validator("time_of_flight_bounds_s")
    @classmethod
    def _ordered(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not 0.0 < value[0] < value[1] <= 1.0e6:
            raise ValueError(f"need 0 < lower < upper <= 1e6, got {value[0]:g}, {value[1]:g}")
        return value


class OptimizerConfig(StrictModel):
    """The global search: the seed's improved DE (sec. 1.2) or scipy's, same settings."""

    method: Method
    population_per_variable: int = bounded(
        ge=1, le=100, description="N / n, population size per decision variable"
    )
    min_population: int = bounded(ge=4, le=10000, description="floor on N (DE needs >= 4)")
    scale_factor: float = bounded(gt=0, le=2, description="F of eq. 8")
    crossover_probability: float = bounded(ge=0, le=1, description="P_c")
    accept_ties: bool = Field(
        description="eq. 11: a trial equal to its parent replaces it (Storn & Price's <=); "
        "false is the seed's strict <"
    )
    generations: int = bounded(ge=1, le=100000)
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of the global search"
    )
    stall_generations: int = bounded(
        ge=0,
        le=100000,
        description="stop after this many generations without improvement "
        "of the best feasible objective (0: run all generations)",
    )
    stall_tolerance: float = bounded(
        ge=0, le=1.0e6, description="an improvement smaller than this (objective units) is a stall"
    )
    seed: int = bounded(ge=0, le=2**32 - 1)


class LambertConfig(StrictModel):
    """Solving the last leg exactly (universal-variable Lambert; aim-point iteration for J2)."""

    time_tolerance: float = bounded(gt=0, lt=1e-3, description="relative, on the time of flight")
    j2_iterations: int = bounded(ge=1, le=50, description="aim-point corrections under J2")
    j2_position_tolerance_m: float = bounded(unit="m", gt=0, le=1000)


class FiniteBurnConfig(StrictModel):
    """Finite-thrust correction (seed sec. 2): eq. 15 burns, then SLSQP on the burns."""

    enabled: bool
    dynamics: Dynamics = Field(description="two-body, or J2 as the perturbation a_p of eq. 12")
    max_iterations: int = bounded(ge=1, le=10000, description="SLSQP iterations")
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of the correction (SLSQP and polish)"
    )
    polish_iterations: int = bounded(
        ge=0, le=100, description="Gauss-Newton steps on the end conditions after SLSQP"
    )
    optimality_tolerance: float = bounded(gt=0, lt=1, description="SLSQP ftol, scaled")
    stall_iterations: int = bounded(
        ge=0,
        le=10000,
        description="stop SLSQP when the objective moved less than "
        "stall_tolerance_s over this many iterations (0: never)",
    )
    stall_tolerance_s: float = bounded(
        unit="s",
        ge=0,
        le=10000,
        description="objective (t_f or total burning time) change of a stall",
    )
    position_tolerance_m: float = bounded(unit="m", gt=0, le=1.0e6, description="end condition met")
    velocity_tolerance_mps: float = bounded(
        unit="m/s", gt=0, le=10000, description="end condition met"
    )
    time_scale_s: float = bounded(
        unit="s", gt=0, le=100000, description="unit of the time variables"
    )
    angle_scale_rad: float = bounded(
        unit="rad", gt=0, le=1, description="unit of the direction variables"
    )
    position_scale_m: float = bounded(
        unit="m", gt=0, le=1.0e8, description="unit of position residuals"
    )
    velocity_scale_mps: float = bounded(
        unit="m/s", gt=0, le=10000, description="unit of velocity residuals"
    )
    difference_step: float = bounded(
        gt=0, lt=1, description="central-difference step in scaled variables"
    )


class IntegratorConfig(StrictModel):
    tolerance: float = bounded(gt=0, lt=1e-3, description="heyoka Taylor tolerance")


class PublishedConfig(StrictModel):
    """The seed's published figures, printed next to ours (nothing is computed from them)."""

    time_of_flight_s: float | None = bounded(unit="s", ge=0, le=1.0e6, default=None)
    impulse_epochs_s: list[float] | None = None
    burn_starts_s: list[float] | None = None
    burn_durations_s: list[float] | None = None
    burn_dv_mps: list[float] | None = None
    mass_before_kg: list[float] | None = None
    mass_after_kg: list[float] | None = None
    total_dv_mps: float | None = bounded(unit="m/s", ge=0, le=100000, default=None)
    dv_budget_mps: float | None = bounded(unit="m/s", ge=0, le=100000, default=None)
    final_position_error_m: float | None = bounded(unit="m", ge=0, le=1.0e8, default=None)

    @field_validator(
        "impulse_epochs_s",
        "burn_starts_s",
        "burn_durations_s",
        "burn_dv_mps",
        "mass_before_kg",
        "mass_after_kg",
    )
    @classmethod
    def _finite_figures(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and not all(0.0 <= v <= 1.0e7 for v in value):
            raise ValueError("published figures must be finite, within [0, 1e7]")
        return value


class ManeuverConfig(StrictModel):
    name: str
    source: str = Field(description="where the problem is published")
    stage: StageConfig
    chaser: OrbitConfig
    target: OrbitConfig
    maneuver: ManeuverSettingsConfig
    optimizer: OptimizerConfig
    lambert: LambertConfig
    finite_burn: FiniteBurnConfig
    integrator: IntegratorConfig
    published: PublishedConfig | None = None


def maneuver_config_from_dict(data: Any, source: str = "") -> ManeuverConfig:
    """Validate a mapping into a :class:`ManeuverConfig`, raising :class:`ConfigError`."""
    return model_from_dict(ManeuverConfig, data, source)


def load_maneuver_config(path: str | Path) -> ManeuverConfig:
    """Read and validate a manoeuvre YAML file."""
    return load_model(ManeuverConfig, path)
