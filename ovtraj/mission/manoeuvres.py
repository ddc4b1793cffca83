"""A plan's manoeuvres as an analyst tabulates them: epoch, dV in the local frame, the burn's
duration and the propellant it burns.

The plan holds every impulse with its ECI vector and its radial, along-track and
cross-track components (RTN, Vallado's RSW) at the burn state (:mod:`.plan`). The OV
flies them as impulses; what a finite burn of the scenario's engine would take is
computed here with the rocket equation (:mod:`ovtraj.astro.rocket`): constant thrust
``vehicle.thrust_n``, exhaust speed ``vehicle.isp_s`` x ``earth.g0_m_s2``, each burn
from the mass the earlier ones left, starting at the OV's wet mass in orbit
``vehicle.mass_kg`` (as the CCSDS OPM export counts its burnt masses). The launcher
inserts the OV into its parking orbit (no OV burn), and the plan holds no mid-course
correction: those only the closed-loop flights make (``ovtraj fly --fidelity high``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ovtraj.astro.rocket import burn_durations, mass_after
from ovtraj.config import Scenario
from ovtraj.mission.plan import MissionPlan

__all__ = ["PropellantBudget", "manoeuvre_table", "propellant_budget"]


def manoeuvre_table(plan: MissionPlan, scenario: Scenario) -> pd.DataFrame:
    """One row per impulse of ``plan`` in time order: ``name``, ``epoch_utc``, ``t_s``,
    ``dv_radial_mps``, ``dv_along_track_mps``, ``dv_cross_track_mps``, ``dv_mps``,
    ``mass_before_kg``, ``duration_s`` and ``propellant_kg`` (see the module notes);
    ``scenario``: the plan's own (:func:`ovtraj.config.scenario_from_dict` of
    ``plan.scenario``)."""
    vehicle = scenario.vehicle
    exhaust_speed = vehicle.isp_s * scenario.earth.g0_m_s2
    burns = plan.impulses()
    dv = np.array([burn.dv_mps for burn in burns])
    durations, masses = burn_durations(dv, vehicle.mass_kg, vehicle.thrust_n, exhaust_speed)
    burnt = masses - mass_after(masses, durations, vehicle.thrust_n, exhaust_speed)
    return pd.DataFrame(
        {
            "name": [burn.name for burn in burns],
            "epoch_utc": [burn.epoch_utc for burn in burns],
            "t_s": [burn.t_s for burn in burns],
            "dv_radial_mps": [burn.dv_radial_mps for burn in burns],
            "dv_along_track_mps": [burn.dv_along_track_mps for burn in burns],
            "dv_cross_track_mps": [burn.dv_cross_track_mps for burn in burns],
            "dv_mps": dv,
            "mass_before_kg": masses,
            "duration_s": durations,
            "propellant_kg": burnt,
        }
    )


@dataclass(frozen=True)
class PropellantBudget:
    """The propellant the plan's burns take against what the OV carries [kg]."""

    used_kg: float
    loaded_kg: float  # vehicle.mass_kg - vehicle.dry_mass_kg

    @property
    def margin_kg(self) -> float:
        return self.loaded_kg - self.used_kg


def propellant_budget(table: pd.DataFrame, scenario: Scenario) -> PropellantBudget:
    """The propellant of :func:`manoeuvre_table`'s burns against the load of ``scenario``'s
    vehicle (wet minus dry mass)."""
    vehicle = scenario.vehicle
    return PropellantBudget(
        used_kg=float(table["propellant_kg"].sum()),
        loaded_kg=vehicle.mass_kg - vehicle.dry_mass_kg,
    )
