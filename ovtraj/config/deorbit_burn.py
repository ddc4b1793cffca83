"""Settings of the finite-thrust deorbit burn by osculating-element prediction (seed 004).

A deorbit-burn problem is posed by a YAML file alone (``configs/cases/shuttle_deorbit.yaml``
is the seed's published case): Earth constants, the waiting orbit, the vehicle (mass, thrust,
specific impulse), the entry requirements, the guidance settings (cut-off strategy, burn
angle, gain k_u of seed eq. 27, tolerances), the burn-angle study, the Monte Carlo
dispersions and the published figures the results are compared with. Angles are in degrees
and distances in km in the file (the key names say so); :mod:`ovtraj.studies.deorbit_burn.problem`
converts to SI once. Every bounded field names its unit and allowed range, so a bad value is
refused as ``guidance.gain_ku = 1.5: out of range, allowed [0.1, 0.9]``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, field_validator

from ovtraj.config.base import StrictModel, bounded, load_model, model_from_dict

__all__ = [
    "DeorbitBurnConfig",
    "deorbit_burn_config_from_dict",
    "load_deorbit_burn_config",
]

Strategy = Literal[1, 2]
Distribution = Literal["uniform", "normal"]


class BurnEarthConfig(StrictModel):
    """Earth model of the problem; ``null`` takes the project value (``configs/earth.yaml``)."""

    mu_m3_s2: float | None = bounded(unit="m^3/s^2", gt=0, le=1.0e18, default=None)
    radius_m: float | None = bounded(unit="m", gt=0, le=1.0e8, default=None)
    j2: float | None = bounded(ge=0, lt=0.01, default=None)
    g0_m_s2: float | None = bounded(
        unit="m/s^2", gt=0, le=100, default=None, description="rocket-equation unit of Isp"
    )
    include_j2: bool = Field(description="false: two-body dynamics and two-body prediction")


class WaitingOrbitConfig(StrictModel):
    """The waiting (deorbit stand-by) orbit at t = 0.

    ``mean``: first-order J2 mean elements (Brouwer, no long-period terms), so that mean
    ``eccentricity: 0`` is a circular orbit under J2; ``osculating``: the elements of the
    initial state itself. The simulation starts at ``start_arg_latitude_deg``.
    """

    element_set: Literal["mean", "osculating"]
    altitude_km: float = bounded(unit="km", gt=100, le=5000, description="a - R_E")
    eccentricity: float = bounded(ge=0, lt=0.2)
    arg_perigee_deg: float = bounded(unit="deg", ge=-360, le=360)
    inclination_deg: float = bounded(
        unit="deg", gt=0, lt=180, description="the node (and u) is undefined at 0 and 180"
    )
    raan_deg: float = bounded(unit="deg", ge=-360, le=360)
    start_arg_latitude_deg: float = bounded(unit="deg", ge=-360, le=360)


class BurnVehicleConfig(StrictModel):
    mass_kg: float = bounded(unit="kg", gt=0, le=1.0e6, description="mass at ignition")
    engines: int = bounded(ge=1, le=16)
    thrust_per_engine_n: float = bounded(unit="N", gt=0, le=1.0e7)
    isp_s: float = bounded(unit="s", gt=0, le=1000, description="vacuum specific impulse")


class EntryTargetConfig(StrictModel):
    """Entry requirements at the entry altitude (inertial speed and flight-path angle)."""

    altitude_km: float = bounded(unit="km", ge=60, le=300)
    speed_mps: float = bounded(unit="m/s", gt=1000, le=12000, description="inertial")
    fpa_deg: float = bounded(unit="deg", gt=-30, lt=0, description="inertial, descending")
    arg_latitude_deg: float = bounded(unit="deg", ge=-360, le=360)


class PredictionConfig(StrictModel):
    """The on-line entry prediction and the search of the cut-off instant (seed sec. 2.3-2.4)."""

    grid_step_s: float = bounded(
        unit="s", gt=0, le=60, description="spacing of the predictions along the burn"
    )
    time_to_go_iterations: int = bounded(
        ge=1, le=20, description="passes of the time-to-go estimate (seed eqs. 23-26)"
    )
    cutoff_time_tolerance_s: float = bounded(
        unit="s", gt=0, le=1, description="accuracy of the cut-off instant"
    )


class GuidanceConfig(StrictModel):
    """Burn parameters and the iteration on the burn start (seed sec. 2.4, eq. 27)."""

    strategy: Strategy = Field(description="cut-off: 1 predicted entry u, 2 predicted entry fpa")
    burn_angle_deg: float | None = bounded(
        unit="deg", ge=-80, le=80, default=None, description="null: the impulsive angle, eq. 10"
    )
    gain_ku: float = bounded(ge=0.1, le=0.9, description="k_u of seed eq. 27")
    u_tolerance_deg: float = bounded(unit="deg", gt=0, le=1)
    max_iterations: int = bounded(ge=1, le=100)
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of one solve (iteration and final flight)"
    )
    max_dv_mps: float = bounded(unit="m/s", gt=0, le=3000, description="longest burn allowed")
    max_coast_revolutions: float = bounded(
        gt=0, le=5, description="limit on the coasts (start to burn, cut-off to entry)"
    )
    integrator_tolerance: float = bounded(gt=0, lt=1e-3, description="heyoka rel/abs tol")
    prediction: PredictionConfig


class StudyConfig(StrictModel):
    """Burn-angle study (seed sec. 2.5): the converged solve repeated for each angle."""

    burn_angles_deg: list[float] = Field(min_length=1)

    @field_validator("burn_angles_deg")
    @classmethod
    def _inside(cls, value: list[float]) -> list[float]:
        bad = [a for a in value if not -80.0 <= a <= 80.0]
        if bad:
            raise ValueError(f"burn angles must lie in [-80, 80] deg, got {bad}")
        return value


class _Dispersion(StrictModel):
    """A zero-mean random error: uniform on [-bound, bound], or normal with
    sigma = bound / sigma_level (``bound`` is then a k-sigma value)."""

    distribution: Distribution
    sigma_level: float = bounded(gt=0, le=10, default=3.0, description="normal: bound in sigmas")


class SemiMajorAxisDispersion(_Dispersion):
    bound_km: float = bounded(unit="km", ge=0, le=100)


class EccentricityDispersion(_Dispersion):
    """Added to the mean eccentricity vector in a uniformly random direction."""

    bound: float = bounded(ge=0, lt=0.1)


class AttitudeDispersion(_Dispersion):
    """Constant pointing error of the thrust during a burn, drawn in pitch and in yaw."""

    bound_deg: float = bounded(unit="deg", ge=0, le=10)


class FractionDispersion(_Dispersion):
    bound_fraction: float = bounded(ge=0, lt=0.5, description="relative to the nominal")


class DispersionsConfig(StrictModel):
    semi_major_axis: SemiMajorAxisDispersion
    eccentricity: EccentricityDispersion
    attitude: AttitudeDispersion
    mass: FractionDispersion
    thrust: FractionDispersion


class MonteCarloConfig(StrictModel):
    """Monte Carlo of the closed-loop burn (seed sec. 4) and how the flow runs it."""

    runs: int = bounded(ge=1, le=100000)
    seed: int = bounded(ge=0, le=2**32 - 1)
    strategies: list[Strategy] = Field(min_length=1)
    replan_initial_orbit: bool = Field(
        description="true: the on-board iteration knows the dispersed initial orbit"
    )
    dispersions: DispersionsConfig
    batch_size: int = bounded(ge=1, le=10000, description="runs per Prefect task")
    workers: int = bounded(ge=1, le=64)
    task_runner: Literal["threads", "processes"]
    task_retries: int = bounded(ge=0, le=10)
    store: str | None = Field(
        description="run-store root, relative to the config file's folder; null: the "
        "workspace's runs/ (OVTRAJ_HOME)"
    )

    @field_validator("strategies")
    @classmethod
    def _distinct(cls, value: list[int]) -> list[int]:
        if len(set(value)) != len(value):
            raise ValueError(f"strategies must be distinct, got {value}")
        return value


class PublishedConfig(StrictModel):
    """The seed's published figures, printed next to ours (never used by the solver)."""

    iterations: int = bounded(ge=1, le=1000, description="iterations to the u tolerance")
    dv_burn_angle_0_mps: float = bounded(unit="m/s", gt=0, le=3000)
    dv_burn_angle_27_mps: float = bounded(unit="m/s", gt=0, le=3000)
    zero_speed_error_burn_angle_deg: float = bounded(unit="deg", ge=0, le=90)
    speed_error_increase_mps: float = bounded(
        unit="m/s", ge=0, le=1000, description="entry speed error at angle 0 minus at +-27 deg"
    )
    strategy1_along_track_km: float = bounded(unit="km", gt=0, le=10000)
    strategy2_fpa_deg: float = bounded(unit="deg", gt=0, le=30)
    strategy2_along_track_km: float = bounded(unit="km", gt=0, le=10000)
    approximate_tolerance_mps: float = bounded(
        unit="m/s",
        ge=0,
        le=1000,
        description="how far from a '~' delta-v figure still matches it",
    )


class DeorbitBurnConfig(StrictModel):
    name: str
    source: str = Field(description="where the problem is published")
    earth: BurnEarthConfig
    waiting_orbit: WaitingOrbitConfig
    vehicle: BurnVehicleConfig
    entry: EntryTargetConfig
    guidance: GuidanceConfig
    study: StudyConfig
    monte_carlo: MonteCarloConfig
    published: PublishedConfig


def deorbit_burn_config_from_dict(data: Any, source: str = "") -> DeorbitBurnConfig:
    """Validate a mapping into a :class:`DeorbitBurnConfig`, raising :class:`ConfigError`."""
    return model_from_dict(DeorbitBurnConfig, data, source)


def load_deorbit_burn_config(path: str | Path) -> DeorbitBurnConfig:
    """Read and validate a deorbit-burn YAML file."""
    return load_model(DeorbitBurnConfig, path)
