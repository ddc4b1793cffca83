"""The scenario's space target as a Cartesian state (shared by every stage's inputs)."""

from __future__ import annotations

import math

import numpy as np

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import (
    ClassicalElements,
    NonsingularElements,
    classical_to_nonsingular,
    coe_to_rv,
)
from ovtraj.astro.j2_elements import mean_to_state
from ovtraj.config.scenario import OrbitElementsConfig, Scenario


def target_state(orbit: OrbitElementsConfig | None, scenario: Scenario) -> np.ndarray:
    """ECI state (m, m/s) of the target at the scenario epoch.

    ``orbit`` given (the hand-typed ``scenario.target.orbit``): the state of those
    classical elements, osculating or first-order J2 mean. ``orbit`` None, for a
    target given by a TLE / OMM / URL: the initial state of the project's J2 orbit
    fitted to the element set's SGP4 ephemeris (``docs/targets.md``), computed once
    per process. Raises :class:`~ovtraj.config.ConfigError` when SGP4 cannot reach
    the fit span or the fit stopped at a limit.
    """
    if orbit is None:
        return _fitted_state(scenario)
    earth = scenario.earth
    coe = ClassicalElements(
        a=orbit.semi_major_axis_km * 1e3,
        e=orbit.eccentricity,
        i=math.radians(orbit.inclination_deg),
        raan=math.radians(orbit.raan_deg),
        argp=math.radians(orbit.arg_perigee_deg),
        nu=math.radians(orbit.true_anomaly_deg),
    )
    if orbit.element_set == "mean":
        r, v = mean_to_state(
            classical_to_nonsingular(coe), mu=earth.mu, radius=earth.radius, j2=earth.j2
        )
    else:
        r, v = coe_to_rv(coe.a, coe.e, coe.i, coe.raan, coe.argp, coe.nu, mu=earth.mu)
    return np.r_[r, v]


def _fitted_state(scenario: Scenario) -> np.ndarray:
    from ovtraj.config.base import ConfigError
    from ovtraj.target_sources import fitted_target

    if not scenario.target.has_source:
        raise ConfigError(["target.orbit: required (the target has no TLE / OMM / URL source)"])
    fit = fitted_target(scenario)
    if not fit.converged:
        raise ConfigError([f"target: the fit of the mean elements to SGP4 stopped: {fit.reason}"])
    return fit.state.copy()


def circular_orbit_state(
    altitude_m: float,
    inclination_rad: float,
    raan_rad: float,
    arg_latitude_rad: float,
    *,
    element_set: str,
    earth: EarthModel,
) -> np.ndarray:
    """ECI state of a circular orbit: ``mean`` (first-order J2, mean e = 0) or osculating."""
    a = earth.radius + altitude_m
    i, raan, u = inclination_rad, raan_rad, arg_latitude_rad
    if element_set == "mean":
        r, v = mean_to_state(
            NonsingularElements(a=a, ex=0.0, ey=0.0, i=i, raan=raan, u=u),
            mu=earth.mu,
            radius=earth.radius,
            j2=earth.j2,
        )
    else:
        r, v = coe_to_rv(a, 0.0, i, raan, 0.0, u, mu=earth.mu)
    return np.r_[r, v]
