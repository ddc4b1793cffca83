"""Build the rendezvous stage's input from a scenario."""

from __future__ import annotations

import math

import numpy as np

from ovtraj.astro.elements import (
    NonsingularElements,
    coe_to_rv,
)
from ovtraj.astro.j2_elements import mean_to_state, state_to_mean
from ovtraj.config.scenario import ParkingOrbitConfig, Scenario
from ovtraj.rendezvous.result import RendezvousInput
from ovtraj.targets import target_state


def parking_state(
    parking: ParkingOrbitConfig, target: np.ndarray, scenario: Scenario
) -> np.ndarray:
    """ECI state of the OV's circular parking orbit, in the target's plane plus offsets.

    The plane is the target's mean plane at the epoch (the plane a launch aims at).
    """
    earth = scenario.earth
    target_mean = state_to_mean(
        target[:3], target[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    a = earth.radius + parking.altitude_km * 1e3
    i = float(target_mean.i) + math.radians(parking.inclination_offset_deg)
    raan = float(target_mean.raan) + math.radians(parking.raan_offset_deg)
    u = math.radians(parking.arg_latitude_deg)
    if parking.element_set == "mean":
        r, v = mean_to_state(
            NonsingularElements(a=a, ex=0.0, ey=0.0, i=i, raan=raan, u=u),
            mu=earth.mu,
            radius=earth.radius,
            j2=earth.j2,
        )
    else:
        r, v = coe_to_rv(a, 0.0, i, raan, 0.0, u, mu=earth.mu)
    return np.r_[r, v]


def rendezvous_input(scenario: Scenario) -> RendezvousInput:
    """The stand-alone rendezvous problem of a scenario: parking orbit to target."""
    target = target_state(scenario.target.orbit, scenario)
    return RendezvousInput(
        epoch=scenario.epoch,
        t0_s=0.0,
        chaser_state=parking_state(scenario.parking_orbit, target, scenario),
        target_state=target,
        settings=scenario.rendezvous,
        miss_tolerance_m=scenario.tolerances.miss_distance_m,
        max_impulse_mps=scenario.vehicle.max_impulse_mps,
        integrator_tol=scenario.tolerances.integrator,
        earth=scenario.earth,
    )
