"""The deorbit stage's input: the OV's state at an epoch and the entry requirements (SI)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ovtraj.astro.angles import wrap_to_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.config.deorbit import DeorbitSolverConfig, PreparationOrbitConfig
from ovtraj.config.scenario import Scenario
from ovtraj.target_state import circular_orbit_state
from ovtraj.units import S_PER_HOUR


@dataclass(frozen=True)
class EntryRegion:
    """The entry interface: a latitude/longitude box at an altitude, and its angle limits.

    Latitudes and longitudes are geocentric over a spherical Earth; the
    flight-path angles are inertial (the orbital angle at the entry radius).
    """

    latitude_rad: float
    longitude_rad: float
    latitude_tol_rad: float
    longitude_tol_rad: float
    altitude_m: float
    fpa_min_rad: float
    fpa_max_rad: float
    fpa_target_rad: float
    pass_direction: str = "any"  # northbound, southbound or any

    def accepts_direction(self, northbound: bool) -> bool:
        if self.pass_direction == "any":
            return True
        return northbound == (self.pass_direction == "northbound")

    def offsets(self, latitude_rad: float, longitude_rad: float) -> tuple[float, float]:
        """(latitude, longitude) of a point minus the entry point's [rad], longitude wrapped."""
        return latitude_rad - self.latitude_rad, wrap_to_pi(longitude_rad - self.longitude_rad)

    def contains(self, latitude_rad: float, longitude_rad: float, slack: float = 0.0) -> bool:
        """Inside the box, each half-width enlarged by the fraction ``slack``."""
        d_lat, d_lon = self.offsets(latitude_rad, longitude_rad)
        return abs(d_lat) <= self.latitude_tol_rad * (1.0 + slack) and abs(
            d_lon
        ) <= self.longitude_tol_rad * (1.0 + slack)


@dataclass(frozen=True)
class DeorbitInput:
    """Everything the deorbit stage needs; times are seconds from ``epoch``."""

    epoch: Epoch
    state0: np.ndarray  # ECI position [m] and velocity [m/s] at the epoch
    earth: EarthModel
    integrator_tol: float
    entry: EntryRegion
    max_impulse_mps: float
    horizon_s: float
    max_descent_revolutions: float
    solver: DeorbitSolverConfig
    trajectory_step_s: float

    @property
    def earth_angle0_rad(self) -> float:
        return self.epoch.gmst_rad()


def preparation_state(orbit: PreparationOrbitConfig, earth: EarthModel) -> np.ndarray:
    """ECI state of a circular preparation orbit given by its elements at its epoch."""
    return circular_orbit_state(
        orbit.altitude_km * 1e3,
        math.radians(orbit.inclination_deg),
        math.radians(orbit.raan_deg),
        math.radians(orbit.arg_latitude_deg),
        element_set=orbit.element_set,
        earth=earth,
    )


def deorbit_input(
    scenario: Scenario, *, state0: np.ndarray | None = None, epoch: Epoch | None = None
) -> DeorbitInput:
    """The deorbit problem of a scenario; ``state0``/``epoch`` override its preparation orbit.

    Raises ``ValueError`` when the scenario has no ``deorbit`` section.
    """
    settings = scenario.deorbit
    if settings is None:
        raise ValueError("the scenario has no deorbit section")
    earth = scenario.earth
    entry = settings.entry
    if state0 is None:
        state0 = preparation_state(settings.preparation_orbit, earth)
        epoch = Epoch.from_iso(settings.preparation_orbit.epoch_utc)
    elif epoch is None:
        raise ValueError("epoch is required with state0")
    return DeorbitInput(
        epoch=epoch,
        state0=np.asarray(state0, dtype=float),
        earth=earth,
        integrator_tol=scenario.tolerances.integrator,
        entry=EntryRegion(
            latitude_rad=math.radians(entry.latitude_deg),
            longitude_rad=wrap_to_pi(math.radians(entry.longitude_deg)),
            latitude_tol_rad=math.radians(entry.latitude_tolerance_deg),
            longitude_tol_rad=math.radians(entry.longitude_tolerance_deg),
            altitude_m=entry.altitude_km * 1e3,
            fpa_min_rad=math.radians(entry.fpa_min_deg),
            fpa_max_rad=math.radians(entry.fpa_max_deg),
            fpa_target_rad=math.radians(entry.fpa_target_deg),
            pass_direction=entry.pass_direction,
        ),
        max_impulse_mps=scenario.vehicle.max_impulse_mps,
        horizon_s=settings.horizon_h * S_PER_HOUR,
        max_descent_revolutions=settings.max_descent_revolutions,
        solver=settings.solver,
        trajectory_step_s=settings.trajectory_step_s,
    )
