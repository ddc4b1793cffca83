"""The deorbit-burn problem in SI, built once from its YAML config.

:func:`load_deorbit_burn` reads a file (:mod:`ovtraj.config.deorbit_burn`), fills the
Earth constants left ``null`` from ``configs/earth.yaml`` and converts degrees and km to
rad and m. Nothing else in the package reads a configuration or a unit other than SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ovtraj.astro.constants import EarthConstants
from ovtraj.astro.elements import NonsingularElements
from ovtraj.config.deorbit_burn import (
    DeorbitBurnConfig,
    deorbit_burn_config_from_dict,
    load_deorbit_burn_config,
)
from ovtraj.config.physical import default_earth
from ovtraj.units import RAD_PER_DEG

__all__ = [
    "DeorbitBurnProblem",
    "EarthConstants",
    "EntryTarget",
    "Vehicle",
    "deorbit_burn_from_dict",
    "load_deorbit_burn",
]


@dataclass(frozen=True)
class Vehicle:
    """Mass at ignition [kg], total thrust [N], specific impulse [s] (g0 from the Earth)."""

    mass_kg: float
    thrust_n: float
    isp_s: float

    def mass_flow(self, g0: float) -> float:
        """dm/dt = F / (Isp g0) [kg/s] (constant thrust and specific impulse)."""
        return self.thrust_n / (self.isp_s * g0)


@dataclass(frozen=True)
class EntryTarget:
    """Entry requirements: radius r_E [m], inertial speed [m/s], fpa [rad] (< 0), u_E [rad]."""

    radius_m: float
    speed_mps: float
    fpa_rad: float
    u_rad: float


@dataclass(frozen=True)
class DeorbitBurnProblem:
    """A deorbit-burn problem in SI; ``config`` keeps the validated file for reports."""

    config: DeorbitBurnConfig
    source: str
    earth: EarthConstants
    waiting: NonsingularElements  # at t = 0, u = the start argument of latitude
    waiting_is_mean: bool
    vehicle: Vehicle
    entry: EntryTarget

    @property
    def name(self) -> str:
        return self.config.name

    def resolved(self) -> dict[str, Any]:
        """The config with every default and Earth constant filled in (JSON types).

        What results depend on: the run id of a Monte Carlo hashes this.
        """
        data = self.config.model_dump(mode="json")
        data["earth"].update(
            mu_m3_s2=self.earth.mu,
            radius_m=self.earth.radius,
            j2=self.config.earth.j2 if self.config.earth.j2 is not None else default_earth().j2,
            g0_m_s2=self.earth.g0,
        )
        return data


def deorbit_burn_problem(config: DeorbitBurnConfig, source: str = "") -> DeorbitBurnProblem:
    """Convert a validated config to SI."""
    project = default_earth()
    cfg_earth = config.earth
    radius = cfg_earth.radius_m if cfg_earth.radius_m is not None else project.radius
    j2 = cfg_earth.j2 if cfg_earth.j2 is not None else project.j2
    earth = EarthConstants(
        mu=cfg_earth.mu_m3_s2 if cfg_earth.mu_m3_s2 is not None else project.mu,
        radius=radius,
        j2=j2 if cfg_earth.include_j2 else 0.0,
        g0=cfg_earth.g0_m_s2 if cfg_earth.g0_m_s2 is not None else project.g0_m_s2,
    )
    orbit = config.waiting_orbit
    argp = orbit.arg_perigee_deg * RAD_PER_DEG
    waiting = NonsingularElements(
        a=radius + orbit.altitude_km * 1e3,
        ex=orbit.eccentricity * math.cos(argp),
        ey=orbit.eccentricity * math.sin(argp),
        i=orbit.inclination_deg * RAD_PER_DEG,
        raan=orbit.raan_deg * RAD_PER_DEG,
        u=orbit.start_arg_latitude_deg * RAD_PER_DEG,
    )
    vehicle = Vehicle(
        mass_kg=config.vehicle.mass_kg,
        thrust_n=config.vehicle.engines * config.vehicle.thrust_per_engine_n,
        isp_s=config.vehicle.isp_s,
    )
    entry = EntryTarget(
        radius_m=radius + config.entry.altitude_km * 1e3,
        speed_mps=config.entry.speed_mps,
        fpa_rad=config.entry.fpa_deg * RAD_PER_DEG,
        u_rad=config.entry.arg_latitude_deg * RAD_PER_DEG,
    )
    return DeorbitBurnProblem(
        config=config,
        source=source,
        earth=earth,
        waiting=waiting,
        waiting_is_mean=orbit.element_set == "mean",
        vehicle=vehicle,
        entry=entry,
    )


def load_deorbit_burn(path: str | Path) -> DeorbitBurnProblem:
    """Read, validate and convert a deorbit-burn YAML file (e.g. the published case).

    Raises :class:`ovtraj.config.ConfigError` naming each bad field and its allowed range.
    """
    return deorbit_burn_problem(load_deorbit_burn_config(path), str(path))


def deorbit_burn_from_dict(data: Any, source: str = "") -> DeorbitBurnProblem:
    """The same from a mapping (tests, scripted studies)."""
    return deorbit_burn_problem(deorbit_burn_config_from_dict(data, source), source)
