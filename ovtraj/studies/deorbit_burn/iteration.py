"""Iteration on the burn-start argument of latitude (seed sec. 2.4, eq. 27, fig. 1).

Each pass flies the whole trajectory with the fpa cut-off (strategy 2): the burn ends when
the predicted entry flight-path angle reaches gamma_E, so the burn size needs no search and
the only error left is the entry argument of latitude u. The burn start is then moved::

    u_open <- u_open - k_u (u - u_E),        0.1 <= k_u <= 0.9       (seed eq. 27)

until |u - u_E| is within the tolerance. The entry u moves with u_open at a rate close to 1
(measured 1.008 on the published case), so the error shrinks by about |1 - k_u| per pass.
The passes stop at ``guidance.max_iterations`` and at the solve's wall-time deadline
(``guidance.time_limit_s``); either is an unconverged outcome whose reason names it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.deadline import Deadline
from ovtraj.studies.deorbit_burn.flight import FlightOutcome, FlightSimulator
from ovtraj.studies.deorbit_burn.powered import ThrustSettings

__all__ = ["IterationOutcome", "IterationRecord", "iterate_burn_start"]

PLANNING_STRATEGY = 2


@dataclass(frozen=True)
class IterationRecord:
    """One pass: the burn start and what it gave (errors are actual minus target)."""

    iteration: int
    u_open_deg: float
    dv_mps: float
    burn_duration_s: float
    entry_u_error_deg: float
    entry_fpa_error_deg: float
    entry_speed_error_mps: float
    along_track_error_km: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class IterationOutcome:
    """The passes, the last flight, and whether |u - u_E| met the tolerance."""

    history: tuple[IterationRecord, ...]
    flight: FlightOutcome
    converged: bool
    reason: str | None

    @property
    def iterations(self) -> int:
        return len(self.history)


def _record(k: int, flight: FlightOutcome, entry_radius_m: float) -> IterationRecord:
    return IterationRecord(
        iteration=k,
        u_open_deg=math.degrees(flight.u_open_rad),
        dv_mps=flight.dv_mps,
        burn_duration_s=flight.burn_duration_s,
        entry_u_error_deg=math.degrees(flight.u_error_rad),
        entry_fpa_error_deg=math.degrees(flight.fpa_error_rad),
        entry_speed_error_mps=flight.speed_error_mps,
        along_track_error_km=flight.u_error_rad * entry_radius_m / 1e3,
    )


def iterate_burn_start(
    simulator: FlightSimulator,
    state0: np.ndarray,
    mass_kg: float,
    thrust: ThrustSettings,
    u_open0: float,
    *,
    gain: float,
    tolerance_rad: float,
    max_iterations: int,
    deadline: Deadline | None = None,
) -> IterationOutcome:
    """Seed eq. 27 from ``u_open0`` [rad]; ``state0`` (6,) at t = 0 [m, m/s], mass [kg].

    Stops when |u - u_E| <= ``tolerance_rad`` (converged), when a flight fails (its reason
    is returned), after ``max_iterations`` passes, or at ``deadline`` (checked between
    passes).
    """
    deadline = deadline or Deadline.unlimited()
    entry_radius = simulator.problem.entry.radius_m
    history: list[IterationRecord] = []
    u_open = wrap_to_two_pi(u_open0)
    flight: FlightOutcome | None = None
    for k in range(1, max_iterations + 1):
        if flight is not None and deadline.expired():
            return IterationOutcome(tuple(history), flight, False, deadline.reason(k - 1))
        flight = simulator.fly(state0, mass_kg, u_open, thrust, PLANNING_STRATEGY)
        history.append(_record(k, flight, entry_radius))
        if not flight.ok:
            return IterationOutcome(tuple(history), flight, False, flight.reason)
        if abs(flight.u_error_rad) <= tolerance_rad:
            return IterationOutcome(tuple(history), flight, True, None)
        u_open = wrap_to_two_pi(u_open - gain * flight.u_error_rad)
    assert flight is not None
    return IterationOutcome(
        tuple(history),
        flight,
        False,
        f"guidance.max_iterations = {max_iterations} reached: the entry u error "
        f"{math.degrees(flight.u_error_rad):.4g} deg is still above the tolerance "
        f"{math.degrees(tolerance_rad):g} deg (guidance.u_tolerance_deg)",
    )
