"""Powered flight under J2: constant thrust, mass flow, burn angle held in the orbital frame.

The equations of motion of the burn (seed eq. 11, lost in extraction; the standard form)::

    r' = v
    v' = g_J2(r) + (F / m) T_hat
    m' = -F / (Isp g0)

with g_J2 the point-mass plus J2 field (:func:`ovtraj.astro.propagation.gravity.
two_body_j2_acceleration`, Vallado 2013 eq. 8-30) and the thrust held at a fixed attitude in
the orbital (radial, along-track, cross-track) frame: the burn angle theta from the negative
along-track direction in the orbit plane, positive towards the radial (away from the Earth),
plus an out-of-plane (yaw) pointing error psi::

    T_hat = cos(psi) (-cos(theta) t_hat + sin(theta) r_hat) + sin(psi) h_hat

with r_hat = r / |r|, h_hat = (r x v) / |r x v| and t_hat = h_hat x r_hat. On the circular
waiting orbit t_hat is the velocity direction, so theta is the seed's angle from -v at
ignition; holding it in the orbital frame (rather than on the turning velocity) makes a
very short burn the impulse of seed eqs. 9-10 (the velocity turns by ~0.5 deg during the
deorbit burn).

The system is compiled once per thread and tolerance by heyoka (Biscani & Izzo, MNRAS 2021;
the reasons and the caching follow :mod:`ovtraj.astro.propagation.taylor`); mu, R, J2, thrust,
mass flow, the pointing angles and the entry radius are runtime parameters, so one integrator
serves the nominal burn, every dispersed burn and the coast (thrust 0). A terminal event
stops the integration at the entry radius (descending).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import heyoka as hy
import numpy as np

from ovtraj.astro.constants import EarthConstants
from ovtraj.astro.propagation.gravity import two_body_j2_acceleration

__all__ = ["BurnArc", "PoweredFlight", "ThrustSettings"]

_STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz", "m")
_PARAMS = (
    "mu",
    "radius",
    "j2",
    "thrust",
    "mass_flow",
    "cos_theta",
    "sin_theta",
    "cos_psi",
    "sin_psi",
    "entry_radius",
)


@dataclass(frozen=True)
class ThrustSettings:
    """Thrust [N], mass flow [kg/s], burn angle theta and yaw error psi [rad]."""

    thrust_n: float
    mass_flow_kg_s: float
    burn_angle_rad: float
    yaw_rad: float = 0.0


@dataclass
class BurnArc:
    """A propagated powered arc: from t0 to t1 [s]; ``entry`` if it reached the entry radius.

    ``states(t)`` gives the (n, 7) states (r [m], v [m/s], m [kg]) at times inside [t0, t1].
    """

    t0: float
    t1: float
    state: np.ndarray
    entry: bool
    _dense: Any

    def states(self, t: np.ndarray) -> np.ndarray:
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), self.t0, self.t1)
        # heyoka returns a view of its buffer: copy before the next call.
        return np.array(self._dense(t), dtype=float).reshape(len(t), -1)[:, :7]

    def state_at(self, t: float) -> np.ndarray:
        return np.array(self._dense(min(max(float(t), self.t0), self.t1))[:7])


def _build(tol: float) -> Any:
    x, y, z, vx, vy, vz, m = hy.make_vars(*_STATE_NAMES)
    par = {name: hy.par[k] for k, name in enumerate(_PARAMS)}
    gx, gy, gz = two_body_j2_acceleration(
        x, y, z, mu=par["mu"], radius=par["radius"], j2=par["j2"], sqrt=hy.sqrt
    )
    hx, hy_, hz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    r_norm = hy.sqrt(x * x + y * y + z * z)
    h_norm = hy.sqrt(hx * hx + hy_ * hy_ + hz * hz)
    # h x r, the along-track (transverse) direction times |h| |r|
    tx, ty, tz = hy_ * z - hz * y, hz * x - hx * z, hx * y - hy_ * x
    accel = par["thrust"] / m
    along = -par["cos_psi"] * par["cos_theta"] * accel / (h_norm * r_norm)
    radial = par["cos_psi"] * par["sin_theta"] * accel / r_norm
    cross_track = par["sin_psi"] * accel / h_norm
    system = [
        (x, vx),
        (y, vy),
        (z, vz),
        (vx, gx + along * tx + radial * x + cross_track * hx),
        (vy, gy + along * ty + radial * y + cross_track * hy_),
        (vz, gz + along * tz + radial * z + cross_track * hz),
        (m, -par["mass_flow"]),
    ]
    entry = hy.t_event(
        r_norm - par["entry_radius"],
        direction=hy.event_direction.negative,
    )
    return hy.taylor_adaptive(
        system,
        np.r_[7e6, 0.0, 0.0, 0.0, 7.5e3, 0.0, 1.0],
        tol=tol,
        t_events=[entry],
        compact_mode=False,
    )


class _Cache(threading.local):
    def __init__(self) -> None:
        self.integrators: dict[float, Any] = {}


_CACHE = _Cache()


def _integrator(tol: float) -> Any:
    ta = _CACHE.integrators.get(tol)
    if ta is None:
        ta = _build(tol)
        _CACHE.integrators[tol] = ta
    return ta


class PoweredFlight:
    """Propagates burns (and thrust-free arcs) of the 7-element state (r, v, m) under J2."""

    def __init__(self, earth: EarthConstants, *, tol: float, entry_radius_m: float) -> None:
        if not 0.0 < tol < 1e-3:
            raise ValueError(f"tol must be in (0, 1e-3), got {tol}")
        self.earth = earth
        self.tol = float(tol)
        self.entry_radius_m = float(entry_radius_m)

    def _pars(self, thrust: ThrustSettings) -> list[float]:
        e = self.earth
        return [
            e.mu,
            e.radius,
            e.j2,
            thrust.thrust_n,
            thrust.mass_flow_kg_s,
            math.cos(thrust.burn_angle_rad),
            math.sin(thrust.burn_angle_rad),
            math.cos(thrust.yaw_rad),
            math.sin(thrust.yaw_rad),
            self.entry_radius_m,
        ]

    def burn(self, state0: np.ndarray, t0: float, t1: float, thrust: ThrustSettings) -> BurnArc:
        """Propagate from ``t0`` to ``t1`` [s] with dense output; stops early at the entry radius.

        Raises ``FloatingPointError`` when heyoka reports a non-finite state.
        """
        ta = _integrator(self.tol)
        ta.pars[:] = self._pars(thrust)
        ta.time = float(t0)
        ta.state[:] = np.asarray(state0, dtype=float)
        ta.reset_cooldowns()
        outcome, *_, c_output, _ = ta.propagate_until(float(t1), c_output=True)
        code = int(outcome)
        if outcome != hy.taylor_outcome.time_limit and code != -1:
            raise FloatingPointError(f"powered flight stopped at t = {ta.time:.3f} s: {outcome}")
        return BurnArc(
            t0=float(t0),
            t1=float(ta.time),
            state=np.array(ta.state),
            entry=code == -1,
            _dense=c_output,
        )
