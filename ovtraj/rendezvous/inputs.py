"""Build the rendezvous stage's input from a scenario."""

from __future__ import annotations

import math

import numpy as np

from ovtraj.astro.j2_elements import state_to_mean
from ovtraj.config.scenario import ParkingOrbitConfig, Scenario
from ovtraj.rendezvous.result import RendezvousInput
from ovtraj.target_state import circular_orbit_state, target_state


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
    return circular_orbit_state(
        parking.altitude_km * 1e3,
        float(target_mean.i) + math.radians(parking.inclination_offset_deg),
        float(target_mean.raan) + math.radians(parking.raan_offset_deg),
        math.radians(parking.arg_latitude_deg),
        element_set=parking.element_set,
        earth=earth,
    )


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
