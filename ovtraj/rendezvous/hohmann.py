"""Two-body Hohmann transfer between coplanar circular orbits, and its lead angle."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ovtraj.astro.angles import principal_angle
from ovtraj.astro.elements import orbital_period


@dataclass(frozen=True)
class HohmannTransfer:
    """Impulses (signed: positive along the velocity), transfer time and geometry.

    dv1_mps, dv2_mps: tangential impulses at departure and arrival [m/s]
        (negative for a transfer to a lower orbit).
    transfer_time_s: half the period of the transfer ellipse [s].
    transfer_sma_m: semi-major axis of the transfer ellipse [m].
    """

    r1_m: float
    r2_m: float
    dv1_mps: float
    dv2_mps: float
    transfer_time_s: float
    transfer_sma_m: float

    @property
    def total_dv_mps(self) -> float:
        return abs(self.dv1_mps) + abs(self.dv2_mps)


def hohmann(r1_m: float, r2_m: float, mu: float) -> HohmannTransfer:
    """Hohmann transfer from a circular orbit of radius ``r1_m`` to one of ``r2_m``.

    a_t = (r1 + r2) / 2; dv1 = sqrt(mu/r1) (sqrt(2 r2 / (r1 + r2)) - 1);
    dv2 = sqrt(mu/r2) (1 - sqrt(2 r1 / (r1 + r2))); T = pi sqrt(a_t^3 / mu)
    (Vallado, 4th ed., Algorithm 36 and eqs. 6-2 to 6-4; Curtis, 3rd ed., sec. 6.3).

    Units: radii in m, ``mu`` in m^3/s^2; impulses in m/s, time in s.
    """
    if not (r1_m > 0 and r2_m > 0 and mu > 0):
        raise ValueError(f"r1_m, r2_m and mu must be positive, got {r1_m}, {r2_m}, {mu}")
    dv1, dv2 = hohmann_impulses_mps(r1_m, r2_m, mu)
    return HohmannTransfer(
        r1_m=r1_m,
        r2_m=r2_m,
        dv1_mps=float(dv1),
        dv2_mps=float(dv2),
        transfer_time_s=float(hohmann_time_s(r1_m, r2_m, mu)),
        transfer_sma_m=0.5 * (r1_m + r2_m),
    )


def hohmann_impulses_mps(
    r1_m: ArrayLike, r2_m: ArrayLike, mu: float
) -> tuple[np.ndarray, np.ndarray]:
    """The signed impulses (dv1, dv2) [m/s] of :func:`hohmann` (arrays broadcast):
    dv1 = sqrt(mu/r1) (sqrt(r2/a_t) - 1), dv2 = sqrt(mu/r2) (1 - sqrt(r1/a_t)),
    a_t = (r1 + r2) / 2. Radii in m, ``mu`` in m^3/s^2; no check of their signs."""
    r1, r2 = np.asarray(r1_m, dtype=float), np.asarray(r2_m, dtype=float)
    a_t = 0.5 * (r1 + r2)
    dv1 = np.sqrt(mu / r1) * (np.sqrt(r2 / a_t) - 1.0)
    dv2 = np.sqrt(mu / r2) * (1.0 - np.sqrt(r1 / a_t))
    return dv1, dv2


def hohmann_time_s(r1_m: ArrayLike, r2_m: ArrayLike, mu: float) -> np.ndarray:
    """Hohmann transfer time [s] between circular radii [m] (arrays broadcast): half the
    period of the transfer ellipse, T = pi sqrt(a_t^3 / mu), a_t = (r1 + r2) / 2 (as
    :func:`hohmann`). Halving the period is exact: the same float as pi sqrt(a_t^3 / mu)."""
    a_t = 0.5 * (np.asarray(r1_m, dtype=float) + np.asarray(r2_m, dtype=float))
    return 0.5 * orbital_period(a_t, mu=mu)


def lead_angle(transfer: HohmannTransfer, target_rate_rad_s: float) -> float:
    """Angle [rad] by which the target must lead the chaser at the first burn.

    The chaser sweeps pi during the transfer while the target sweeps
    ``target_rate * T``, so the lead is pi - target_rate * T (Vallado, 4th ed.,
    eq. 6-29, with the target's mean angular rate), wrapped to (-pi, pi]:
    negative when the target must trail (transfer to a lower orbit).
    """
    return principal_angle(math.pi - target_rate_rad_s * transfer.transfer_time_s)
