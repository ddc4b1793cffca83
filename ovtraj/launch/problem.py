"""The maximum-payload ascent as an optimisation problem on the unit cube.

Design vector (patent step 101, ten variables): launch azimuth (as an offset from
the in-plane azimuth of the chosen opportunity), alpha_1, t_12, alpha_2, t_23,
the coast t_h, the stage-2 pitch rate, the stage-3 ignition pitch, the stage-3
pitch rate and the payload mass. Optimisers see it scaled to ``[0, 1]^10`` by
the configured bounds.

Constraints, scaled by the insertion tolerances so that ``|c| <= 1`` means met:

* equalities: altitude ``|R| - (R_E + h)``, inertial speed minus the circular
  speed ``sqrt(mu / (R_E + h))``, inertial flight-path angle, and the mean
  (first-order J2) inclination minus the target's mean inclination;
* inequalities ``>= 0``: ``1 - q_max / q_limit`` and ``1 - n_max / n_limit``, divided
  by the path-limit tolerance (a fraction), so that ``>= -1`` means met.

The ascending node is not a constraint: the trajectory relative to the Earth does
not depend on the launch epoch (zonal gravity, co-rotating air), so the epoch is
chosen afterwards to put the node on the target's (:mod:`ovtraj.launch.stage`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.elements import eccentricity_vector
from ovtraj.astro.j2_elements import state_to_mean
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.launch.ascent import AscentModel, AscentOutcome, simulate
from ovtraj.units import RAD_PER_DEG

ANGLE_VARIABLES = frozenset(
    {
        "azimuth_offset_deg",
        "alpha_1_deg",
        "alpha_2_deg",
        "pitch_rate_2_deg_s",
        "pitch_3_deg",
        "pitch_rate_3_deg_s",
    }
)
EQUALITY_NAMES = ("altitude", "speed", "flight_path_angle", "inclination")
INEQUALITY_NAMES = ("dynamic_pressure", "axial_load")


@dataclass(frozen=True)
class InsertionTarget:
    """Target orbit at insertion (SI) and the tolerances that scale its constraints."""

    altitude_m: float
    inclination_rad: float  # mean (first-order J2)
    altitude_tol_m: float
    speed_tol_mps: float
    flight_path_angle_tol_rad: float
    inclination_tol_rad: float
    path_limit_fraction: float


@dataclass
class Evaluation:
    """Objective and scaled constraints of a batch of scaled designs."""

    x: NDArray
    outcome: AscentOutcome
    payload_kg: NDArray
    equality: NDArray  # (N, 4), |c| <= 1 is met
    inequality: NDArray  # (N, 2), >= -1 is met (0 is exactly at the limit)
    errors: dict[str, NDArray]

    @property
    def violation(self) -> NDArray:
        """Largest scaled constraint violation of each row (0 when every constraint holds)."""
        eq = np.max(np.maximum(np.abs(self.equality) - 1.0, 0.0), axis=1)
        ineq = np.max(np.maximum(-self.inequality - 1.0, 0.0), axis=1)
        return np.maximum(eq, ineq)

    @property
    def residual(self) -> NDArray:
        """Largest scaled residual of each row: ``max |c_eq|`` or a path-limit shortfall."""
        eq = np.max(np.abs(self.equality), axis=1)
        ineq = np.max(np.maximum(-self.inequality, 0.0), axis=1)
        return np.maximum(eq, ineq)


class LaunchProblem:
    """Scaled design -> simulated ascent -> objective and constraints, for whole batches."""

    def __init__(
        self,
        model: AscentModel,
        target: InsertionTarget,
        lower: NDArray,
        upper: NDArray,
        nominal_azimuth_rad: float,
    ) -> None:
        self.model = model
        self.target = target
        self.lower = np.asarray(lower, dtype=float)  # configuration units
        self.upper = np.asarray(upper, dtype=float)
        self.nominal_azimuth_rad = nominal_azimuth_rad
        self.trajectories = 0
        self.batches = 0
        earth = model.earth
        self._radius_target = earth.radius + target.altitude_m
        self._circular_speed = math.sqrt(earth.mu / self._radius_target)
        self._to_si = np.array(
            [RAD_PER_DEG if name in ANGLE_VARIABLES else 1.0 for name in DESIGN_VARIABLES]
        )

    @property
    def dimension(self) -> int:
        return len(DESIGN_VARIABLES)

    def to_config_units(self, x: NDArray) -> NDArray:
        return self.lower + np.asarray(x) * (self.upper - self.lower)

    def to_scaled(self, values: NDArray) -> NDArray:
        return (np.asarray(values) - self.lower) / (self.upper - self.lower)

    def to_si(self, x: NDArray) -> NDArray:
        """Scaled designs -> SI design rows with the absolute azimuth (ascent columns)."""
        design = self.to_config_units(np.atleast_2d(x)) * self._to_si
        design[:, 0] += self.nominal_azimuth_rad
        return design

    def evaluate(self, x: NDArray, *, keep_history: bool = False) -> Evaluation:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        outcome = simulate(self.model, self.to_si(x), keep_history=keep_history)
        self.trajectories += len(x)
        self.batches += 1
        earth = self.model.earth
        r, v = outcome.r_ecef, outcome.v_inertial_ecef_axes
        r_norm = np.linalg.norm(r, axis=1)
        v_norm = np.linalg.norm(v, axis=1)
        fpa = np.arcsin(np.clip(np.einsum("ij,ij->i", r, v) / (r_norm * v_norm), -1.0, 1.0))
        # Inclination does not depend on the rotation about the pole between Earth-fixed
        # axes and the inertial frame at insertion, so the Earth-fixed axes serve here.
        inclination = _mean_inclination(r, v, earth.mu, earth.radius, earth.j2)
        errors = {
            "altitude_m": r_norm - self._radius_target,
            "speed_mps": v_norm - self._circular_speed,
            "flight_path_angle_rad": fpa,
            "inclination_rad": inclination - self.target.inclination_rad,
        }
        t = self.target
        equality = np.stack(
            [
                errors["altitude_m"] / t.altitude_tol_m,
                errors["speed_mps"] / t.speed_tol_mps,
                errors["flight_path_angle_rad"] / t.flight_path_angle_tol_rad,
                errors["inclination_rad"] / t.inclination_tol_rad,
            ],
            axis=1,
        )
        launcher = self.model.launcher
        inequality = (
            np.stack(
                [
                    1.0 - outcome.max_dynamic_pressure_pa / launcher.max_dynamic_pressure_pa,
                    1.0 - outcome.max_axial_load_g / launcher.max_axial_load_g,
                ],
                axis=1,
            )
            / t.path_limit_fraction
        )
        return Evaluation(
            x=x,
            outcome=outcome,
            payload_kg=outcome.payload_kg.copy(),
            equality=equality,
            inequality=inequality,
            errors=errors,
        )


# Eccentricity below which the mean (Brouwer, near-circular) inclination is used; far
# from a circular orbit the osculating one steers the search just as well.
_MEAN_ELEMENTS_MAX_ECCENTRICITY = 0.5


def _mean_inclination(r: NDArray, v: NDArray, mu: float, radius: float, j2: float) -> NDArray:
    """Mean inclination [rad] of near-circular rows, osculating inclination of the others."""
    h = np.cross(r, v)
    inclination = np.arccos(np.clip(h[:, 2] / np.linalg.norm(h, axis=1), -1.0, 1.0))
    e_vec = eccentricity_vector(r, v, mu)
    near_circular = np.linalg.norm(e_vec, axis=1) < _MEAN_ELEMENTS_MAX_ECCENTRICITY
    if np.any(near_circular):
        try:
            mean = state_to_mean(r[near_circular], v[near_circular], mu=mu, radius=radius, j2=j2)
            inclination[near_circular] = np.asarray(mean.i)
        except (ValueError, RuntimeError):
            pass  # keep the osculating values of this batch
    return inclination
