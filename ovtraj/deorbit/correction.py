"""SQP correction of the deorbit burn under J2 (patent step 103).

Decision variables (scaled): the shift of the burn epoch from the two-body
estimate, in units of ``time_scale_s``, and the impulse's radial, along-track and
cross-track components (RSW at the burn point), in units of ``dv_scale_mps``.
Each evaluation takes the pre-burn state from the forecast's dense output, adds
the impulse, and propagates under J2 to the entry altitude (a terminal event).

Objective: ``|dv|^2 / dv_scale^2`` (minimum impulse; the square keeps it smooth at
zero). Inequality constraints (``>= 0``), in degrees or scaled speeds:

* the entry point in the box: ``tol_lat -+ dlat`` and ``tol_lon -+ dlon``;
* the inertial entry flight-path angle in ``[fpa_min, fpa_max]``;
* the impulse within the OV's maximum: ``(dv_max^2 - |dv|^2) / dv_scale^2``;
* the entry altitude is reached: ``(r_entry - r_perigee) / 1 km`` with the
  osculating perigee right after the burn. When a trial impulse misses the
  entry altitude within the time limit, the entry constraints take the values
  at the lowest point of the arc (continuous in the variables) and this one
  reports the miss.

Gradients are forward differences (central ones cost twice the propagations for
the same converged burn, to 1e-12 m/s on the default case); the objective's and
the impulse limit's are exact. SLSQP is scipy's (Kraft 1988).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from ovtraj.astro.elements import orbital_period, perigee_radius_from_semi_latus_rectum
from ovtraj.astro.frames import ecef_to_geocentric, eci_to_ecef, flight_path_angle, rsw_basis
from ovtraj.astro.propagation import AltitudeCrossing, OrbitPropagator, PropagationResult
from ovtraj.config.deorbit import DeorbitSolverConfig
from ovtraj.deadline import Deadline
from ovtraj.deorbit.inputs import EntryRegion

CONSTRAINT_NAMES = (
    "latitude_upper",
    "latitude_lower",
    "longitude_upper",
    "longitude_lower",
    "fpa_above_min",
    "fpa_below_max",
    "impulse_limit",
    "reaches_entry",
)


@dataclass(frozen=True)
class Shot:
    """One burn and the descent it produces (times in s from the input epoch)."""

    burn_t_s: float
    dv_rsw_mps: np.ndarray
    dv_eci_mps: np.ndarray
    state_before: np.ndarray
    reached: bool
    entry_t_s: float
    entry_state: np.ndarray
    latitude_rad: float
    longitude_rad: float
    fpa_rad: float
    perigee_radius_m: float
    descent: PropagationResult = field(repr=False)


class DescentModel:
    """Burn at a time on the preparation orbit, then coast to the entry altitude."""

    def __init__(
        self,
        propagator: OrbitPropagator,
        preparation: PropagationResult,
        entry: EntryRegion,
        max_descent_s: float,
    ) -> None:
        self.propagator = propagator
        self.preparation = preparation
        self.entry = entry
        self.max_descent_s = max_descent_s
        self.entry_radius_m = propagator.earth.radius + entry.altitude_m
        self.propagations = 0

    def shoot(self, burn_t_s: float, dv_rsw_mps: NDArray, *, dense: bool = False) -> Shot:
        ctx = self.propagator.context
        before = self.preparation.state_at(burn_t_s)
        basis = rsw_basis(before[:3], before[3:])
        dv_eci = np.asarray(dv_rsw_mps, dtype=float) @ basis
        after = np.concatenate((before[:3], before[3:] + dv_eci))
        self.propagations += 1
        descent = self.propagator.propagate(
            after,
            burn_t_s,
            burn_t_s + self.max_descent_s,
            events=[AltitudeCrossing(self.entry.altitude_m, "descending", terminal=True)],
            dense=dense,
        )
        reached = descent.status == "terminal_event"
        if reached:
            t_end, end = descent.t, descent.state
        else:  # lowest point of the arc (two-body perigee time is close enough to aim)
            t_end, end = self._lowest_point(after, burn_t_s, descent)
        theta = ctx.earth_angle0_rad + ctx.rotation_rate_rad_s * t_end
        lat, lon, _ = ecef_to_geocentric(eci_to_ecef(end[:3], theta), radius=ctx.radius_m)
        return Shot(
            burn_t_s=float(burn_t_s),
            dv_rsw_mps=np.asarray(dv_rsw_mps, dtype=float),
            dv_eci_mps=dv_eci,
            state_before=before,
            reached=reached,
            entry_t_s=float(t_end),
            entry_state=np.array(end, dtype=float),
            latitude_rad=float(lat),
            longitude_rad=float(lon),
            fpa_rad=float(flight_path_angle(end[:3], end[3:])),
            perigee_radius_m=_perigee_radius(after, self.propagator.earth.mu),
            descent=descent,
        )

    def _lowest_point(
        self, after: NDArray, burn_t_s: float, descent: PropagationResult
    ) -> tuple[float, np.ndarray]:
        mu = self.propagator.earth.mu
        r, v = after[:3], after[3:]
        energy = 0.5 * float(v @ v) - mu / float(np.linalg.norm(r))
        if energy >= 0.0 or not descent.ok:
            return descent.t, descent.state
        a = -mu / (2.0 * energy)
        period = float(orbital_period(a, mu=mu))
        # The arc starts near apoapsis: its lowest point is about half a period later.
        t_low = min(burn_t_s + 0.5 * period, descent.t)
        state = self.propagator.propagate(after, burn_t_s, t_low).state
        return t_low, state


def _perigee_radius(state: NDArray, mu: float) -> float:
    """Osculating perigee radius p / (1 + |e|) [m], with p = h^2 / mu and the eccentricity
    vector e = v x h / mu - r / |r|; on scalars (~50 calls per mission evaluation)."""
    rx, ry, rz, vx, vy, vz = state.tolist()
    r_norm = math.sqrt(rx * rx + ry * ry + rz * rz)
    hx, hy, hz = ry * vz - rz * vy, rz * vx - rx * vz, rx * vy - ry * vx
    ex = (vy * hz - vz * hy) / mu - rx / r_norm
    ey = (vz * hx - vx * hz) / mu - ry / r_norm
    ez = (vx * hy - vy * hx) / mu - rz / r_norm
    p = (hx * hx + hy * hy + hz * hz) / mu
    return perigee_radius_from_semi_latus_rectum(p, math.sqrt(ex * ex + ey * ey + ez * ez))


@dataclass
class Correction:
    """Outcome of :func:`correct_burn`."""

    shot: Shot
    success: bool
    iterations: int
    message: str
    constraints: dict[str, float]  # final values (>= 0 is met), degrees or scaled
    max_violation: float
    # The limit that stopped SLSQP (iterations or wall time), naming its config key.
    limit: str | None = None


def constraint_values(
    shot: Shot, entry: EntryRegion, entry_radius_m: float, dv_max: float, dv_scale: float
) -> NDArray:
    """The constraint vector of a shot (order of ``CONSTRAINT_NAMES``, ``>= 0`` met)."""
    d_lat, d_lon = entry.offsets(shot.latitude_rad, shot.longitude_rad)
    dv_sq = float(shot.dv_rsw_mps @ shot.dv_rsw_mps)
    return np.array(
        [
            math.degrees(entry.latitude_tol_rad - d_lat),
            math.degrees(entry.latitude_tol_rad + d_lat),
            math.degrees(entry.longitude_tol_rad - d_lon),
            math.degrees(entry.longitude_tol_rad + d_lon),
            math.degrees(shot.fpa_rad - entry.fpa_min_rad),
            math.degrees(entry.fpa_max_rad - shot.fpa_rad),
            (dv_max**2 - dv_sq) / dv_scale**2,
            (entry_radius_m - shot.perigee_radius_m) / 1e3,
        ]
    )


def correct_burn(
    model: DescentModel,
    burn_t0_s: float,
    dv0_rsw_mps: NDArray,
    *,
    dv_max_mps: float,
    t_min_s: float,
    t_max_s: float,
    settings: DeorbitSolverConfig,
    deadline: Deadline | None = None,
) -> Correction:
    """SLSQP from the two-body estimate; never raises on a numerical failure.

    SLSQP stops at ``settings.max_iterations`` or at ``deadline``; ``limit`` then names
    the limit (the stage does not accept such a correction).
    """
    deadline = deadline or Deadline.unlimited()
    problem = _ScaledBurn(model, burn_t0_s, dv_max_mps, settings)
    ts, vs = settings.time_scale_s, settings.dv_scale_mps
    lo_t = max(-settings.burn_window_s, t_min_s - burn_t0_s) / ts
    hi_t = min(settings.burn_window_s, t_max_s - burn_t0_s) / ts
    bound_v = settings.impulse_bound_factor * dv_max_mps / vs
    bounds = [(lo_t, hi_t)] + [(-bound_v, bound_v)] * 3
    z0 = np.r_[0.0, np.asarray(dv0_rsw_mps, dtype=float) / vs]
    z0 = np.clip(z0, [b[0] for b in bounds], [b[1] for b in bounds])
    z, success, iterations, message, status = _slsqp(problem, z0, bounds, settings, deadline)
    limit = None
    if deadline.expired():
        limit = deadline.reason(iterations, "SLSQP iterations")
    elif status == _SLSQP_ITERATION_LIMIT:
        limit = f"deorbit.solver.max_iterations = {settings.max_iterations} reached"
    t, dv = problem.unscale(z)
    shot = model.shoot(t, dv)
    final = constraint_values(shot, model.entry, model.entry_radius_m, dv_max_mps, vs)
    violation = float(max(0.0, -float(np.min(final))))
    return Correction(
        shot=shot,
        success=success,
        iterations=iterations,
        message=message,
        constraints=dict(zip(CONSTRAINT_NAMES, (float(c) for c in final), strict=True)),
        max_violation=violation,
        limit=limit,
    )


class _ScaledBurn:
    """The burn's unknowns scaled for SLSQP, ``z = (dt / time_scale, dv / dv_scale)``
    around ``burn_t0_s``, and its constraints (cached per point) with their
    forward-difference Jacobian."""

    def __init__(
        self,
        model: DescentModel,
        burn_t0_s: float,
        dv_max_mps: float,
        settings: DeorbitSolverConfig,
    ) -> None:
        self.model = model
        self.burn_t0_s = burn_t0_s
        self.dv_max_mps = dv_max_mps
        self.settings = settings
        self._cache: dict[bytes, NDArray] = {}

    def unscale(self, z: NDArray) -> tuple[float, NDArray]:
        """The burn epoch [s] and impulse (RSW, m/s) of ``z``."""
        s = self.settings
        dv = np.asarray(z[1:], dtype=float) * s.dv_scale_mps
        return self.burn_t0_s + float(z[0]) * s.time_scale_s, dv

    def values(self, z: NDArray) -> NDArray:
        key = np.asarray(z, dtype=float).tobytes()
        if key not in self._cache:
            t, dv = self.unscale(z)
            shot = self.model.shoot(t, dv)
            self._cache[key] = constraint_values(
                shot,
                self.model.entry,
                self.model.entry_radius_m,
                self.dv_max_mps,
                self.settings.dv_scale_mps,
            )
        return self._cache[key]

    def jacobian(self, z: NDArray) -> NDArray:
        h = self.settings.finite_difference_step
        z = np.asarray(z, dtype=float)
        columns = []
        for k in range(len(z)):
            step = np.zeros_like(z)
            step[k] = h
            columns.append((self.values(z + step) - self.values(z)) / h)
        jac = np.array(columns).T
        jac[6] = np.r_[0.0, -2.0 * z[1:]]  # impulse limit: exact
        return jac


def _slsqp(
    problem: _ScaledBurn,
    z0: NDArray,
    bounds: list[tuple[float, float]],
    settings: DeorbitSolverConfig,
    deadline: Deadline,
) -> tuple[NDArray, bool, int, str, int]:
    """The least squared impulse from ``z0`` within the constraints: the solution, success,
    iterations, message and SLSQP status (-1, ``z0`` kept, on a numerical failure)."""
    try:
        with np.errstate(all="ignore"):
            result = minimize(
                lambda z: float(z[1:] @ z[1:]),
                z0,
                jac=lambda z: np.r_[0.0, 2.0 * z[1:]],
                method="SLSQP",
                bounds=bounds,
                constraints=[{"type": "ineq", "fun": problem.values, "jac": problem.jacobian}],
                options={"maxiter": settings.max_iterations, "ftol": settings.ftol},
                callback=lambda *_: deadline.stop_if_expired(),
            )
        return (
            result.x,
            bool(result.success),
            int(result.nit),
            str(result.message),
            int(result.status),
        )
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as err:
        return z0, False, 0, f"numerical failure: {type(err).__name__}: {err}", -1


# scipy's SLSQP status at ``maxiter``.
_SLSQP_ITERATION_LIMIT = 9
