"""Dispersions of a flown mission plan and the closed-loop settings.

``configs/dispersions.yaml``: the 1-sigma errors a real flight meets, each drawn
normally per Monte Carlo run (``ovtraj.mission.montecarlo``), and the corrections the
flight makes (re-targeting, the deorbit cut-off, the entry guidance re-solved in flight).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

from pydantic import Field, field_validator

from ovtraj.config.base import StrictModel, bounded, load_model


class DropDispersion(StrictModel):
    """The carrier's release (1 sigma)."""

    position_m: float = bounded(unit="m", ge=0, le=10000, description="horizontal, per axis")
    altitude_m: float = bounded(unit="m", ge=0, le=5000)
    mach: float = bounded(ge=0, le=0.2)
    fpa_deg: float = bounded(unit="deg", ge=0, le=5)


class StageDispersion(StrictModel):
    """Each solid stage's delivered performance (1 sigma, fractions; independent stages)."""

    thrust_fraction: float = bounded(ge=0, le=0.2)
    isp_fraction: float = bounded(ge=0, le=0.1)


class NavigationDispersion(StrictModel):
    """The on-board state estimate before each burn and at the entry interface (1 sigma)."""

    position_m: float = bounded(unit="m", ge=0, le=10000, description="per axis")
    velocity_mps: float = bounded(unit="m/s", ge=0, le=10, description="per axis")


class BurnDispersion(StrictModel):
    """Execution of each impulse (1 sigma)."""

    magnitude_fraction: float = bounded(ge=0, le=0.2)
    pointing_deg: float = bounded(unit="deg", ge=0, le=10, description="per transverse axis")


class EntryDispersion(StrictModel):
    """The atmosphere and the vehicle's aerodynamics (1 sigma, one factor per run)."""

    density_fraction: float = bounded(ge=0, le=0.5)
    lift_fraction: float = bounded(ge=0, le=0.5)
    drag_fraction: float = bounded(ge=0, le=0.5)
    minimum_factor: float = bounded(
        gt=0, le=1, description="a drawn density, lift or drag factor is held at least this"
    )


class ClosedLoopSettings(StrictModel):
    """The corrections of a closed-loop flight."""

    rendezvous_corrections: list[float] = Field(
        min_length=0,
        max_length=10,
        description="mid-course corrections of the rendezvous arc, at these fractions of it",
    )
    correction_tolerance_m: float = bounded(
        unit="m", gt=0, le=1000, description="the corrections' predicted arrival miss"
    )
    correction_iterations: int = bounded(
        ge=1, le=50, description="Newton steps of a mid-course correction at most"
    )
    cutoff_scale_bounds: tuple[float, float] = Field(
        description="where the deorbit cut-off is searched: fractions of the nominal impulse"
    )
    docking_capture_m: float = bounded(
        unit="m",
        gt=0,
        le=1.0e6,
        description="arrival miss the proximity operations still close; farther fails",
    )
    guidance_interval_s: float = bounded(
        unit="s", gt=0, le=3600, description="the entry guidance re-solved this often"
    )
    drag_estimate_threshold_mps2: float = bounded(
        unit="m/s^2",
        ge=0,
        le=100,
        description="measured drag from which the guidance scales its model to the measured "
        "lift and drag",
    )
    accelerometer_fraction: float = bounded(
        ge=0, le=0.2, description="1-sigma relative error of a measured lift or drag"
    )
    prediction_iterations: int = bounded(
        ge=1, le=10, description="passes of the osculating-element entry prediction"
    )

    @field_validator("cutoff_scale_bounds")
    @classmethod
    def _bracket(cls, bounds: tuple[float, float]) -> tuple[float, float]:
        if not 0.0 < bounds[0] < 1.0 < bounds[1] <= 10.0:
            raise ValueError("need 0 < lower < 1 < upper <= 10 (fractions of the impulse)")
        return bounds

    @field_validator("rendezvous_corrections")
    @classmethod
    def _inside_the_arc(cls, fractions: list[float]) -> list[float]:
        if any(not 0.0 < f < 1.0 for f in fractions) or fractions != sorted(set(fractions)):
            raise ValueError("fractions of the arc must increase strictly inside (0, 1)")
        return fractions


class MonteCarloExecution(StrictModel):
    """How the Monte Carlo flow runs (never part of a run's id or results)."""

    runs: int = bounded(ge=1, le=100000)
    seed: int = bounded(ge=0, le=2**32 - 1)
    batch_size: int = bounded(ge=1, le=10000, description="runs per Prefect task")
    workers: int = bounded(ge=1, le=64)
    task_runner: Literal["serial", "threads", "processes", "dask"]
    task_retries: int = bounded(ge=0, le=10)
    store: str | None = Field(
        description="run-store root, relative to the config file's folder; null: the "
        "workspace's runs/ (OVTRAJ_HOME)"
    )


class DispersionsConfig(StrictModel):
    drop: DropDispersion
    stages: StageDispersion
    navigation: NavigationDispersion
    burns: BurnDispersion
    entry: EntryDispersion
    closed_loop: ClosedLoopSettings
    execution: MonteCarloExecution

    def results_content(self) -> dict:
        """What the runs' results depend on: every group but ``execution``."""
        return self.model_dump(mode="json", exclude={"execution"})


@lru_cache(maxsize=1)
def default_dispersions() -> DispersionsConfig:
    """The shipped ``configs/dispersions.yaml``."""
    from ovtraj.paths import config_path

    return load_model(DispersionsConfig, config_path("dispersions.yaml"))
