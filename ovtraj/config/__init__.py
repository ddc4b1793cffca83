"""Configuration: pydantic models of scenarios and settings, loaded from YAML."""

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
    load_scenario,
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
    "load_scenario",
    "scenario_from_dict",
]
