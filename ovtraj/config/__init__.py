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
from ovtraj.config.store_settings import store_settings
from ovtraj.store.settings import use_settings

# The store, below this layer, reads no configuration file: it gets its settings from here,
# read at its first need (ovtraj/config/store_settings.py).
use_settings(store_settings)

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
