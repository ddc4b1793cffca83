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


def target_state(orbit: OrbitElementsConfig, scenario: Scenario) -> np.ndarray:
    """ECI state (m, m/s) of an orbit given by classical elements at the scenario epoch."""
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
