"""Phase angle between two near-coplanar orbits and the wait before the first burn."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ovtraj.astro.angles import principal_angle, wrap_to_two_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import FloatOrArray, NonsingularElements
from ovtraj.astro.j2_elements import secular_rates, state_to_mean
from ovtraj.astro.vectors import cross
from ovtraj.rendezvous.hohmann import HohmannTransfer, hohmann, lead_angle


def phase_angle(chaser_state: np.ndarray, target_position: np.ndarray) -> float:
    """Angle [rad, (-pi, pi]] from the chaser to the target, positive along the motion.

    Measured about the chaser's angular momentum, so the target's small
    out-of-plane offset does not enter.
    """
    r, v = chaser_state[:3], chaser_state[3:6]
    h = cross(r, v)
    h_hat = h / np.linalg.norm(h)
    return math.atan2(float(h_hat @ cross(r, target_position)), float(r @ target_position))


def plane_difference(state_a: np.ndarray, state_b: np.ndarray) -> float:
    """Angle [rad] between the orbital planes (angular momentum directions)."""
    ha = cross(state_a[:3], state_a[3:6])
    hb = cross(state_b[:3], state_b[3:6])
    c = float(ha @ hb / (np.linalg.norm(ha) * np.linalg.norm(hb)))
    return math.acos(min(1.0, max(-1.0, c)))


def mean_argument_of_latitude_rate(mean: NonsingularElements, earth: EarthModel) -> float:
    """Secular rate [rad/s] of the mean argument of latitude, d(M + argp)/dt, under J2."""
    e = math.hypot(float(mean.ex), float(mean.ey))
    _, argp_dot, m_dot = secular_rates(
        float(mean.a), e, float(mean.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    return float(argp_dot + m_dot)


def first_wait(phase0: ArrayLike, lead: ArrayLike, relative_rate: ArrayLike) -> FloatOrArray:
    """Smallest t >= 0 with phase0 - relative_rate * t = lead (mod 2 pi).

    ``relative_rate`` is the chaser's angular rate minus the target's [rad/s];
    the target's lead over the chaser decreases at that rate. Floats or arrays
    (broadcast); a float for floats.
    """
    phase0, lead, rate = (np.asarray(v, dtype=float) for v in (phase0, lead, relative_rate))
    gap = np.where(rate > 0, phase0 - lead, lead - phase0)
    wait = wrap_to_two_pi(gap) / np.abs(rate)
    return float(wait) if wait.ndim == 0 else wait


def refine_wait(
    wait_s: float,
    lead: float,
    relative_rate: float,
    phase_at: Callable[[float], float],
    *,
    iterations: int,
) -> float:
    """Newton steps on the propagated phase: phase(t) = lead, slope -relative_rate."""
    for _ in range(iterations):
        error = principal_angle(phase_at(wait_s) - lead)
        wait_s = max(0.0, wait_s + error / relative_rate)
    return wait_s


@dataclass(frozen=True)
class SecularPhasing:
    """The phasing as J2's secular rates predict it, before any propagation.

    ``mean_chaser``, ``mean_target``: Brouwer mean elements of the two states;
    ``transfer``: the two-body Hohmann between their mean semi-major axes;
    ``relative_rate``: chaser minus target rate of the mean argument of latitude [rad/s];
    ``lead``: the target's lead at the burn, pi minus its J2 sweep over the Hohmann time
    [rad]; ``phase0``: its lead at the start [rad]; ``wait_s``: the first wait >= 0 until
    the lead is reached [s] (``inf`` for equal rates).
    """

    mean_chaser: NonsingularElements
    mean_target: NonsingularElements
    transfer: HohmannTransfer
    relative_rate: float
    lead: float
    phase0: float
    wait_s: float


def secular_phasing(
    chaser_state: np.ndarray,
    target_state: np.ndarray,
    earth: EarthModel,
    *,
    mean_chaser: NonsingularElements | None = None,
) -> SecularPhasing:
    """The rendezvous stage's first estimate of the wait (its step 2 before the Newton
    steps on the propagated phase): mean elements, Hohmann, J2 rates, lead, first wait.
    States: ECI position [m] and velocity [m/s] at the same epoch; ``mean_chaser``: the
    chaser state's mean elements when the caller has them (each costs ~0.4 ms)."""

    def mean(state: np.ndarray) -> NonsingularElements:
        return state_to_mean(state[:3], state[3:6], mu=earth.mu, radius=earth.radius, j2=earth.j2)

    mean_c = mean(chaser_state) if mean_chaser is None else mean_chaser
    mean_t = mean(target_state)
    transfer = hohmann(float(mean_c.a), float(mean_t.a), earth.mu)
    rate_t = mean_argument_of_latitude_rate(mean_t, earth)
    relative_rate = mean_argument_of_latitude_rate(mean_c, earth) - rate_t
    lead = lead_angle(transfer, rate_t)
    phase0 = phase_angle(chaser_state, target_state[:3])
    wait = math.inf if relative_rate == 0.0 else first_wait(phase0, lead, relative_rate)
    return SecularPhasing(mean_c, mean_t, transfer, relative_rate, lead, phase0, float(wait))
