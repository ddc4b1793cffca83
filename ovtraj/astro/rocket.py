"""The stage's delta-v budget and the burn time of an impulse (seed 003, eqs. 13-15).

Constant thrust ``F`` [N] and specific impulse ``c`` [N s/kg], which is the effective
exhaust speed in m/s (the seed gives it in N s/kg: 4354.2 N s/kg = 444 s x g0), so the
mass flow is ``F / c`` [kg/s] (seed eq. 12, third line).

* Eq. 14, the seed's budget: ``dv_max = F t_e / (m0 - F t_e / c)``, the total impulse
  ``F t_e`` divided by the mass left after ``t_e`` seconds of burning. It over-states
  what the stage can do: every second of thrust is credited with the *final* mass.
* The rocket equation (Tsiolkovsky; Curtis, *Orbital Mechanics for Engineering
  Students*, 3rd ed., eq. 6.1) gives the true capacity ``c ln(m0 / (m0 - F t_e / c))``,
  which is what eq. 13 (``sum t_j <= t_e``) allows once each burn's duration is given
  by eq. 15.
* Eq. 15, the burn time of an impulse ``dv`` from mass ``m0``:
  ``dt = m0 c / F (1 - exp(-|dv| / c))`` (the rocket equation solved for the time).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "burn_duration",
    "burn_durations",
    "dv_budget_seed",
    "mass_after",
    "rocket_capacity",
]


def _check_engine(thrust_n: float, isp_n_s_kg: float) -> None:
    if not (thrust_n > 0.0 and isp_n_s_kg > 0.0):
        raise ValueError(f"thrust and Isp must be positive, got {thrust_n}, {isp_n_s_kg}")


def dv_budget_seed(
    thrust_n: float, burn_time_s: float, initial_mass_kg: float, isp_n_s_kg: float
) -> float:
    """Seed eq. 14: ``F t_e / (m0 - F t_e / c)`` [m/s].

    thrust_n [N], burn_time_s (``t_e``, the engine's working time) [s],
    initial_mass_kg [kg], isp_n_s_kg (``c``) [N s/kg = m/s]. Raises when the
    propellant burnt in ``t_e`` is not less than ``m0``.
    """
    _check_engine(thrust_n, isp_n_s_kg)
    final_mass = initial_mass_kg - thrust_n * burn_time_s / isp_n_s_kg
    if final_mass <= 0.0:
        raise ValueError(
            f"{burn_time_s:g} s of burning consume {thrust_n * burn_time_s / isp_n_s_kg:.1f} kg, "
            f"not less than the initial mass {initial_mass_kg:g} kg"
        )
    return thrust_n * burn_time_s / final_mass


def rocket_capacity(
    thrust_n: float, burn_time_s: float, initial_mass_kg: float, isp_n_s_kg: float
) -> float:
    """Ideal delta-v of ``burn_time_s`` of thrust: ``c ln(m0 / (m0 - F t / c))`` [m/s]."""
    _check_engine(thrust_n, isp_n_s_kg)
    final_mass = initial_mass_kg - thrust_n * burn_time_s / isp_n_s_kg
    if final_mass <= 0.0:
        raise ValueError("the burn consumes the whole initial mass")
    return isp_n_s_kg * float(np.log(initial_mass_kg / final_mass))


def mass_after(
    mass_kg: ArrayLike, duration_s: ArrayLike, thrust_n: float, isp_n_s_kg: float
) -> NDArray[np.float64]:
    """Mass [kg] after ``duration_s`` of constant thrust: ``m - F t / c``."""
    return np.asarray(mass_kg, dtype=float) - thrust_n * np.asarray(duration_s) / isp_n_s_kg


def burn_duration(
    dv_mps: ArrayLike, mass_kg: ArrayLike, thrust_n: float, isp_n_s_kg: float
) -> NDArray[np.float64]:
    """Seed eq. 15: ``m0 c / F (1 - exp(-|dv| / c))`` [s] for an impulse of |dv| [m/s]."""
    _check_engine(thrust_n, isp_n_s_kg)
    dv = np.abs(np.asarray(dv_mps, dtype=float))
    return np.asarray(mass_kg, dtype=float) * isp_n_s_kg / thrust_n * -np.expm1(-dv / isp_n_s_kg)


def burn_durations(
    dv_mps: ArrayLike, initial_mass_kg: float, thrust_n: float, isp_n_s_kg: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Eq. 15 for a sequence of impulses (last axis), each from the mass the previous left.

    Returns the durations [s] and the masses before each burn [kg], same shape as
    ``dv_mps``; the mass after burn k is the mass before burn k + 1.
    """
    dv = np.abs(np.asarray(dv_mps, dtype=float))
    # The mass after k impulses follows the rocket equation on their running sum.
    spent = np.cumsum(dv, axis=-1) - dv
    masses = initial_mass_kg * np.exp(-spent / isp_n_s_kg)
    return burn_duration(dv, masses, thrust_n, isp_n_s_kg), masses
