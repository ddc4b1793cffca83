"""Powered flight: two-body + J2 gravity, constant thrust, mass flow (seed 003 eq. 12).

    r' = v
    v' = -mu r / r^3 + a_J2(r) + (F / m) u
    m' = -F / c
    w' = F / m

with thrust ``F`` [N] along the inertial unit vector ``u`` (held fixed during a burn,
as the seed's "thrust along dv, kept by the attitude"), ``c`` the specific impulse in
N s/kg (effective exhaust speed, m/s) and ``a_J2`` the perturbation ``a_p`` of eq. 12
(Vallado, 4th ed., eq. 8-30; zero J2 gives the two-body problem). ``w`` is the velocity
gained from thrust, ``integral F / m dt``: for a constant ``F`` it equals the rocket
equation ``c ln(m0 / m1)`` (tests check that the integration keeps it).

The heyoka integrator is compiled once per thread and tolerance (like
:mod:`ovtraj.astro.propagation.taylor`); mu, R, J2, F, c and u are runtime parameters,
so coasting (F = 0) and burning use the same compiled code.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.propagation.gravity import two_body_j2_acceleration

__all__ = ["Burn", "BurnFlight", "Flight", "fly"]

_STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz", "m", "w")
# Parameter slots: mu, R, J2, F, c, ux, uy, uz.
_N_PARS = 8


@dataclass(frozen=True)
class Burn:
    """A constant-thrust burn: start [s from t = 0], duration [s], inertial direction (3,)."""

    start_s: float
    duration_s: float
    direction: NDArray[np.float64]


@dataclass(frozen=True)
class BurnFlight:
    """What one burn did: masses before and after [kg], velocity gained [m/s], states."""

    start_s: float
    duration_s: float
    direction: NDArray[np.float64]
    mass_before_kg: float
    mass_after_kg: float
    dv_mps: float  # integral of F / m over the burn
    state_before: NDArray[np.float64]  # (6,) at ignition
    state_after: NDArray[np.float64]  # (6,) at cut-off


@dataclass(frozen=True)
class Flight:
    """A flown sequence of burns: the final state and mass, and each burn."""

    t_end_s: float
    state: NDArray[np.float64]  # (6,) at t_end
    mass_kg: float
    burns: tuple[BurnFlight, ...]
    ok: bool
    message: str = ""


class _Cache(threading.local):
    def __init__(self) -> None:
        self.integrators: dict[float, hy.taylor_adaptive] = {}


_CACHE = _Cache()


def _integrator(tol: float) -> hy.taylor_adaptive:
    ta = _CACHE.integrators.get(tol)
    if ta is None:
        x, y, z, vx, vy, vz, m, _w = hy.make_vars(*_STATE_NAMES)
        mu, radius, j2, thrust, isp, ux, uy, uz = (hy.par[i] for i in range(_N_PARS))
        ax, ay, az = two_body_j2_acceleration(x, y, z, mu=mu, radius=radius, j2=j2, sqrt=hy.sqrt)
        accel = thrust / m
        ta = hy.taylor_adaptive(
            [
                (x, vx),
                (y, vy),
                (z, vz),
                (vx, ax + accel * ux),
                (vy, ay + accel * uy),
                (vz, az + accel * uz),
                (m, -thrust / isp),
                (_w, accel),
            ],
            np.r_[np.ones(7), 0.0],
            tol=tol,
            compact_mode=False,
        )
        _CACHE.integrators[tol] = ta
    return ta


def fly(
    state0: NDArray[np.float64],
    mass0_kg: float,
    burns: Sequence[Burn],
    t_end_s: float,
    *,
    earth: EarthModel,
    j2: bool,
    thrust_n: float,
    isp_n_s_kg: float,
    tol: float,
    t0_s: float = 0.0,
) -> Flight:
    """Fly from ``state0`` (6,) [m, m/s] at ``t0_s`` through ``burns`` to ``t_end_s``.

    Burns are flown in order of their start; a burn that would start before the previous
    one ended starts when it ends (an optimiser's intermediate point may overlap them).
    ``t_end_s`` before the last cut-off integrates back to it (same reason). Never
    raises on a numerical failure: ``ok`` is False with a message.
    """
    ta = _integrator(tol)
    pars = np.zeros(_N_PARS)
    pars[:3] = [earth.mu, earth.radius, earth.j2 if j2 else 0.0]
    pars[4] = isp_n_s_kg
    ta.time = float(t0_s)
    ta.state[:] = np.r_[np.asarray(state0, dtype=float), mass0_kg, 0.0]
    flown: list[BurnFlight] = []

    def advance(t: float) -> str:
        outcome = ta.propagate_until(float(t))[0]
        if outcome != hy.taylor_outcome.time_limit:
            return f"integration stopped at t = {ta.time:.3f} s: {outcome}"
        return ""

    for burn in sorted(burns, key=lambda b: b.start_s):
        start = max(float(burn.start_s), float(ta.time))
        pars[3] = 0.0
        ta.pars[:] = pars
        message = advance(start)
        before = np.array(ta.state)
        direction = np.asarray(burn.direction, dtype=float)
        direction = direction / np.linalg.norm(direction)
        pars[3] = thrust_n
        pars[5:8] = direction
        ta.pars[:] = pars
        message = message or advance(start + max(float(burn.duration_s), 0.0))
        after = np.array(ta.state)
        flown.append(
            BurnFlight(
                start_s=start,
                duration_s=max(float(burn.duration_s), 0.0),
                direction=direction,
                mass_before_kg=float(before[6]),
                mass_after_kg=float(after[6]),
                dv_mps=float(after[7] - before[7]),
                state_before=before[:6],
                state_after=after[:6],
            )
        )
        if message:
            return Flight(float(ta.time), after[:6], float(after[6]), tuple(flown), False, message)
    pars[3] = 0.0
    ta.pars[:] = pars
    message = advance(t_end_s)
    final = np.array(ta.state)
    ok = not message and bool(np.all(np.isfinite(final)))
    return Flight(float(ta.time), final[:6], float(final[6]), tuple(flown), ok, message)
