"""Settings of the whole-mission chain and its design space (SPEC step 5)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ovtraj.config.base import StrictModel, bounded
from ovtraj.config.launch import Bound


class MissionBoundsConfig(StrictModel):
    """The three design variables of the whole-mission optimisation (SPEC step 5)."""

    parking_altitude_km: Bound  # H_P0, launch target (parking) altitude
    preparation_altitude_km: Bound  # H_dp, deorbit preparation orbit
    separation_delay_h: Bound  # t_dsp, after the configured stay


class DoeSettings(StrictModel):
    """Design of experiments over ``mission.design_bounds`` and how the flow runs it."""

    samples: int = bounded(ge=1, le=100000)
    seed: int = bounded(ge=0)
    batch_size: int = bounded(ge=1, le=10000, description="samples per Prefect task")
    task_runner: Literal["threads", "processes", "dask"]
    workers: int = bounded(ge=1, le=1024)
    dask_address: str | None = Field(
        default=None, description="scheduler of an existing Dask cluster; none: a local one"
    )
    task_retries: int = bounded(ge=0, le=10)
    store: str = Field(description="run store root, relative to the working directory")


class MissionSettings(StrictModel):
    stay_h: float = bounded(unit="h", ge=0, description="docked with the target after arrival")
    design_bounds: MissionBoundsConfig
    doe: DoeSettings
