"""The manoeuvre problem in SI, built from its YAML config, and its decision variables.

Seed 003 sec. 1.1: an upper stage in an initial orbit, a target; ``n`` impulses; the
decision variables are the impulse vectors and epochs (eq. 2); the end condition is an
interception (eq. 5: position), a rendezvous (eq. 6: position and velocity) or an orbit
transfer (eq. 7: a, e, i, RAAN, argp); the impulses stay within the budget (eq. 4); the
objective is the time of flight (eq. 1) or, as an option, the total delta-v.

The last leg is solved exactly (a Lambert arc, :mod:`ovtraj.studies.maneuver.lambert`), so the
end condition holds by construction and leaves the decision vector:

* rendezvous, transfer: impulses at ``t_1 = 0 < t_2 <= ... <= t_(n-1) < t_n = t_f``; the
  first ``n - 2`` impulses are free, ``dv_(n-1)`` starts the Lambert arc to the target at
  ``t_f`` and ``dv_n`` matches its velocity there;
* interception: impulses at ``t_1 = 0 <= ... <= t_n < t_f``; the first ``n - 1`` are free,
  ``dv_n`` starts the Lambert arc that meets the target at ``t_f`` (no final impulse);
* transfer: the arrival point is on the target's orbit at a free argument of latitude
  ``u_f``, and the arriving stage takes that orbit's velocity there.

Decision vector ``x = [dv_1 (3), ..., dv_m (3), f_1 .. f_k, t_f (, u_f)]``: ``m`` free
impulses (m/s, in ECI or local RSW axes), ``k`` epoch fractions in [0, 1] (sorted, the
epochs are ``f t_f``), the time of flight [s] and, for a transfer, ``u_f`` [rad]. As in
the seed, the first impulse is at the start of the manoeuvre (t = 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.angles import TWO_PI
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import coe_to_rv, mean_to_true_anomaly
from ovtraj.astro.rocket import dv_budget_seed, rocket_capacity
from ovtraj.config.base import ConfigError
from ovtraj.config.maneuver import (
    FiniteBurnConfig,
    LambertConfig,
    ManeuverConfig,
    OptimizerConfig,
    OrbitConfig,
    load_maneuver_config,
    maneuver_config_from_dict,
)
from ovtraj.config.physical import default_earth

__all__ = ["ManeuverProblem", "load_maneuver", "maneuver_from_dict", "orbit_state"]


def orbit_state(orbit: OrbitConfig, *, mu: float) -> NDArray[np.float64]:
    """ECI state (6,) [m, m/s] of the configured elements at t = 0."""
    e = orbit.eccentricity
    nu = float(mean_to_true_anomaly(math.radians(orbit.mean_anomaly_deg), e))
    r, v = coe_to_rv(
        orbit.semi_major_axis_km * 1e3,
        e,
        math.radians(orbit.inclination_deg),
        math.radians(orbit.raan_deg),
        math.radians(orbit.arg_perigee_deg),
        nu,
        mu=mu,
    )
    return np.concatenate([r, v])


@dataclass(frozen=True)
class ManeuverProblem:
    """A manoeuvre in SI (m, s, kg, rad); see the module notes for the variables."""

    config: ManeuverConfig
    source: str
    earth: EarthModel
    chaser_state: NDArray[np.float64]
    target_state: NDArray[np.float64]
    # stage
    initial_mass_kg: float
    thrust_n: float
    isp_n_s_kg: float
    max_burn_time_s: float
    dv_budget_mps: float  # seed eq. 14
    dv_capacity_mps: float  # rocket equation over t_e
    dv_limit_mps: float  # the cap that eq. 4 enforces (one of the two above)
    burn_time_limit: bool  # eq. 13 with eq. 15 durations
    # manoeuvre
    end_condition: str
    objective: str
    n_impulses: int
    tof_bounds_s: tuple[float, float]
    impulse_frame: str
    component_bound_mps: float
    j2: bool  # impulsive model
    min_radius_m: float
    optimizer: OptimizerConfig
    lambert: LambertConfig
    finite: FiniteBurnConfig
    integrator_tol: float

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def n_free_impulses(self) -> int:
        """Impulses the optimiser chooses; the rest follow from the exact last leg."""
        return self.n_impulses - (1 if self.end_condition == "interception" else 2)

    @property
    def n_fractions(self) -> int:
        """Free epochs (as fractions of t_f): every impulse but the first and a final one."""
        return self.n_free_impulses

    @property
    def has_final_latitude(self) -> bool:
        return self.end_condition == "transfer"

    @property
    def n_variables(self) -> int:
        return 3 * self.n_free_impulses + self.n_fractions + 1 + int(self.has_final_latitude)

    @property
    def tof_index(self) -> int:
        return 3 * self.n_free_impulses + self.n_fractions

    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Lower and upper bounds of the decision vector."""
        b = self.component_bound_mps
        lower = [-b] * (3 * self.n_free_impulses) + [0.0] * self.n_fractions
        upper = [b] * (3 * self.n_free_impulses) + [1.0] * self.n_fractions
        lower.append(self.tof_bounds_s[0])
        upper.append(self.tof_bounds_s[1])
        if self.has_final_latitude:
            lower.append(0.0)
            upper.append(TWO_PI)
        return np.array(lower), np.array(upper)


def maneuver_problem(config: ManeuverConfig, source: str = "") -> ManeuverProblem:
    """Convert a validated config to SI; refuses an orbit whose perigee is underground."""
    earth = default_earth()
    problems = []
    for name in ("chaser", "target"):
        orbit: OrbitConfig = getattr(config, name)
        perigee_km = orbit.semi_major_axis_km * (1.0 - orbit.eccentricity)
        if perigee_km * 1e3 <= earth.radius:
            problems.append(
                f"{name}: perigee radius {perigee_km:.1f} km (semi_major_axis_km x "
                f"(1 - eccentricity)) is inside the Earth, radius {earth.radius / 1e3:g} km"
            )
    if problems:
        raise ConfigError(problems, source)
    stage, man = config.stage, config.maneuver
    args = (stage.thrust_n, stage.max_burn_time_s, stage.initial_mass_kg)
    budget = dv_budget_seed(*args, stage.specific_impulse_n_s_kg)
    capacity = rocket_capacity(*args, stage.specific_impulse_n_s_kg)
    return ManeuverProblem(
        config=config,
        source=source,
        earth=earth,
        chaser_state=orbit_state(config.chaser, mu=earth.mu),
        target_state=orbit_state(config.target, mu=earth.mu),
        initial_mass_kg=stage.initial_mass_kg,
        thrust_n=stage.thrust_n,
        isp_n_s_kg=stage.specific_impulse_n_s_kg,
        max_burn_time_s=stage.max_burn_time_s,
        dv_budget_mps=budget,
        dv_capacity_mps=capacity,
        dv_limit_mps=budget if man.budget.dv_limit == "seed_eq14" else capacity,
        burn_time_limit=man.budget.burn_time_limit,
        end_condition=man.end_condition,
        objective=man.objective,
        n_impulses=man.impulses,
        tof_bounds_s=man.time_of_flight_bounds_s,
        impulse_frame=man.impulse_frame,
        component_bound_mps=man.impulse_component_bound_mps,
        j2=man.dynamics == "j2",
        min_radius_m=earth.radius + man.min_perigee_altitude_km * 1e3,
        optimizer=config.optimizer,
        lambert=config.lambert,
        finite=config.finite_burn,
        integrator_tol=config.integrator.tolerance,
    )


def maneuver_from_dict(data: Any, source: str = "") -> ManeuverProblem:
    """Validate a mapping (a parsed YAML file) and build the problem; :class:`ConfigError`."""
    return maneuver_problem(maneuver_config_from_dict(data, source), source)


def load_maneuver(path: str | Path) -> ManeuverProblem:
    """Read a manoeuvre YAML file (e.g. ``configs/cases/upper_stage_rendezvous.yaml``)."""
    return maneuver_problem(load_maneuver_config(path), str(path))
