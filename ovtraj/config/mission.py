"""Settings of the whole-mission chain and its design space (SPEC step 5)."""

from __future__ import annotations

from ovtraj.config.base import StrictModel, bounded
from ovtraj.config.launch import Bound


class MissionBoundsConfig(StrictModel):
    """The three design variables of the whole-mission optimisation (SPEC step 5)."""

    parking_altitude_km: Bound  # H_P0, launch target (parking) altitude
    preparation_altitude_km: Bound  # H_dp, deorbit preparation orbit
    separation_delay_h: Bound  # t_dsp, after the configured stay


class MissionSettings(StrictModel):
    stay_h: float = bounded(unit="h", ge=0, description="docked with the target after arrival")
    design_bounds: MissionBoundsConfig
