"""The launch stage's typed input, and how a scenario becomes one."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import nonsingular_to_classical
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.j2_elements import secular_rates, state_to_mean
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.config.base import ConfigError
from ovtraj.config.launch import (
    TARGET_ALTITUDE_MAX_KM,
    TARGET_ALTITUDE_MIN_KM,
    DesignBoundsConfig,
    DropConfig,
    GeneticConfig,
    InsertionTolerancesConfig,
    IntegrationConfig,
    LauncherConfig,
    LocalConfig,
    Opportunity,
)
from ovtraj.config.scenario import Scenario
from ovtraj.target_state import target_state


@dataclass(frozen=True)
class TargetPlane:
    """The target's mean (first-order J2) plane at the launch day's 0 h and its drift."""

    inclination_rad: float
    raan_0h_rad: float
    raan_rate_rad_s: float

    def raan_at(self, t_s: float) -> float:
        """Mean RAAN [rad] ``t_s`` seconds after the launch day's 0 h."""
        return self.raan_0h_rad + self.raan_rate_rad_s * t_s

    def turned(self, raan_offset_rad: float) -> TargetPlane:
        """The plane with its node ``raan_offset_rad`` further east (the same drift): where
        a launch aims to meet the target's plane later (ovtraj.mission.plane)."""
        return replace(self, raan_0h_rad=self.raan_0h_rad + raan_offset_rad)


@dataclass(frozen=True)
class LaunchInput:
    """One maximum-payload launch problem (patent step 101), SI where it is not config."""

    earth: EarthModel
    launcher: LauncherConfig
    drop: DropConfig
    launch_day: Epoch  # 0 h UTC of the launch day
    opportunity: Opportunity
    target_altitude_m: float
    target_plane: TargetPlane
    bounds: DesignBoundsConfig
    tolerances: InsertionTolerancesConfig
    integration: IntegrationConfig
    genetic: GeneticConfig
    local: LocalConfig

    def at_altitude(self, altitude_m: float) -> LaunchInput:
        """The same problem aimed at another target altitude."""
        return replace(self, target_altitude_m=altitude_m)


def target_plane_at(scenario: Scenario, day: Epoch) -> TargetPlane:
    """Propagate the scenario's target under J2 to ``day`` and take its mean plane."""
    earth = scenario.earth
    state = target_state(scenario.target.orbit, scenario)
    dt = day.seconds_since(scenario.epoch)
    if dt != 0.0:
        propagator = OrbitPropagator(earth, tol=scenario.tolerances.integrator)
        result = propagator.propagate(state, 0.0, dt)
        if result.status == "error":
            raise ValueError(f"target propagation to the launch day failed: {result.message}")
        state = result.state
    mean = state_to_mean(state[:3], state[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
    coe = nonsingular_to_classical(mean)
    raan_rate, _, _ = secular_rates(
        float(coe.a), float(coe.e), float(coe.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    return TargetPlane(float(mean.i), wrap_to_two_pi(float(mean.raan)), float(raan_rate))


def launch_input(scenario: Scenario, *, altitude_km: float | None = None) -> LaunchInput:
    """The scenario's launch problem, optionally aimed at another target altitude."""
    settings = scenario.launch
    if settings is None:
        raise ConfigError(["launch: the scenario has no launch section"], scenario.name)
    low, high = TARGET_ALTITUDE_MIN_KM, TARGET_ALTITUDE_MAX_KM
    if altitude_km is not None and not low <= altitude_km <= high:
        raise ValueError(
            f"altitude_km must lie in [{low:g}, {high:g}] km (a launch target orbit); "
            f"got {altitude_km!r}"
        )
    day = Epoch.from_iso(settings.launch_date_utc)
    return LaunchInput(
        earth=scenario.earth,
        launcher=settings.launcher,
        drop=settings.drop,
        launch_day=day,
        opportunity=settings.opportunity,
        target_altitude_m=(settings.target_altitude_km if altitude_km is None else altitude_km)
        * 1e3,
        target_plane=target_plane_at(scenario, day),
        bounds=settings.design_bounds,
        tolerances=settings.insertion_tolerances,
        integration=settings.integration,
        genetic=settings.genetic,
        local=settings.local,
    )
