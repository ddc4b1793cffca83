"""Configuration: pydantic models of scenarios and settings (validation only: a scenario
file is read by :func:`ovtraj.target_sources.load_scenario`, its target sources too)."""

from ovtraj.config.base import ConfigError
from ovtraj.config.scenario import (
    LimitsConfig,
    OrbitElementsConfig,
    ParkingOrbitConfig,
    RendezvousSettings,
    Scenario,
    TargetConfig,
    TolerancesConfig,
    VehicleConfig,
    scenario_from_dict,
)

__all__ = [
    "ConfigError",
    "LimitsConfig",
    "OrbitElementsConfig",
    "ParkingOrbitConfig",
    "RendezvousSettings",
    "Scenario",
    "TargetConfig",
    "TolerancesConfig",
    "VehicleConfig",
    "scenario_from_dict",
]
