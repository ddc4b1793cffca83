"""Lambert's problem, zero revolutions, by universal variables; compiled, many arcs at once.

Given two positions ``r1``, ``r2`` [m] and a time of flight ``tof`` [s], find the
two-body arc joining them: the velocities ``v1`` at ``r1`` and ``v2`` at ``r2`` [m/s].
Universal-variable formulation of Bate, Mueller & White (1971, sec. 5.3) as written by
Curtis (*Orbital Mechanics for Engineering Students*, 3rd ed., Algorithm 5.2,
eqs. 5.35-5.46) and Vallado (4th ed., Algorithm 58):

    A    = t_m sqrt(r1 r2 (1 + cos dnu))            (t_m = +1 short way, -1 long way)
    y(z) = r1 + r2 + A (z S(z) - 1) / sqrt(C(z))
    F(z) = (y / C)^(3/2) S + A sqrt(y) - sqrt(mu) tof = 0
    f = 1 - y / r1,  g = A sqrt(y / mu),  g_dot = 1 - y / r2
    v1 = (r2 - f r1) / g,  v2 = (g_dot r2 - r1) / g

with the Stumpff functions C, S. For zero revolutions the time of flight grows
monotonically with z on (-inf, 4 pi^2) (where y > 0), so F is solved by Newton's
method kept inside a bracket that every step shrinks (bisection when Newton leaves it):
every arc converges or is reported as failed. The arc turns in the sense of a reference
angular momentum ``h_ref`` (prograde relative to the chaser's orbit).

Failures: a 180-degree transfer (A = 0, no unique plane), a non-positive time of flight,
and arcs so short that they need tens of km/s (the root sits where tof ~ sqrt(y) -> 0
and cannot be resolved in double precision). Arcs near 180 degrees are solved, with
velocities that lose digits as 1 / (pi - dnu).

The solver is compiled with numba (one arc per loop pass, each stopping on its own):
the differential evolution solves a Lambert arc for every individual of every
generation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = ["LambertSolution", "lambert"]

_FOUR_PI2 = 4.0 * math.pi**2
# Below this |z| the Stumpff functions come from their series (four terms: error < 1e-16).
_SERIES_Z = 1e-3
# Hyperbolic side: cosh(sqrt(-z)) overflows near -z = 5e5; far beyond any useful arc.
_MIN_Z = -4.0e5
_MAX_ITERATIONS = 200
# The top of the bracket sits this close under 4 pi^2, where the time of flight is infinite.
_TOP_MARGIN = 1e-9
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class LambertSolution:
    """Velocities at both ends (S, 3) [m/s], which arcs converged (S,), iterations (S,)."""

    v1: NDArray[np.float64]
    v2: NDArray[np.float64]
    ok: NDArray[np.bool_]
    iterations: NDArray[np.int64]


@njit(cache=True)
def _stumpff(z: float) -> tuple[float, float]:
    """Stumpff functions C(z), S(z) (Curtis, 3rd ed., eqs. 3.52-3.53)."""
    if z > _SERIES_Z:
        sz = math.sqrt(z)
        return (1.0 - math.cos(sz)) / z, (sz - math.sin(sz)) / (sz * sz * sz)
    if z < -_SERIES_Z:
        sz = math.sqrt(-z)
        return (math.cosh(sz) - 1.0) / -z, (math.sinh(sz) - sz) / (sz * sz * sz)
    return (
        0.5 - z / 24.0 + z * z / 720.0 - z**3 / 40320.0,
        1.0 / 6.0 - z / 120.0 + z * z / 5040.0 - z**3 / 362880.0,
    )


@njit(cache=True)
def _time_function(z: float, a: float, r_sum: float) -> tuple[float, float, float]:
    """sqrt(mu) tof(z), its derivative (Curtis eq. 5.43) and y(z); NaN where y <= 0."""
    c, s = _stumpff(z)
    y = r_sum + a * (z * s - 1.0) / math.sqrt(c)
    if y <= 0.0:
        return math.nan, math.nan, y
    chi3 = (y / c) ** 1.5
    value = chi3 * s + a * math.sqrt(y)
    if abs(z) < _SERIES_Z:
        # The general form is 0/0 at z = 0: its limit.
        slope = math.sqrt(2.0) / 40.0 * y**1.5 + 0.125 * a * (math.sqrt(y) + a * math.sqrt(0.5 / y))
    else:
        slope = chi3 * ((c - 1.5 * s / c) / (2.0 * z) + 0.75 * s * s / c) + 0.125 * a * (
            3.0 * s / c * math.sqrt(y) + a * math.sqrt(c / y)
        )
    return value, slope, y


@njit(cache=True)
def _solve(
    r1: np.ndarray, r2: np.ndarray, tof: np.ndarray, h_ref: np.ndarray, mu: float, rtol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = r1.shape[0]
    v1 = np.full((n, 3), np.nan)
    v2 = np.full((n, 3), np.nan)
    ok = np.zeros(n, dtype=np.bool_)
    iterations = np.zeros(n, dtype=np.int64)
    for k in range(n):
        x1, y1, z1 = r1[k, 0], r1[k, 1], r1[k, 2]
        x2, y2, z2 = r2[k, 0], r2[k, 1], r2[k, 2]
        r1n = math.sqrt(x1 * x1 + y1 * y1 + z1 * z1)
        r2n = math.sqrt(x2 * x2 + y2 * y2 + z2 * z2)
        if not (tof[k] > 0.0 and r1n > 0.0 and r2n > 0.0):
            continue
        cos_dnu = min(1.0, max(-1.0, (x1 * x2 + y1 * y2 + z1 * z2) / (r1n * r2n)))
        cx, cy, cz = y1 * z2 - z1 * y2, z1 * x2 - x1 * z2, x1 * y2 - y1 * x2
        sense = 1.0 if cx * h_ref[k, 0] + cy * h_ref[k, 1] + cz * h_ref[k, 2] >= 0.0 else -1.0
        a = sense * math.sqrt(r1n * r2n * (1.0 + cos_dnu))
        r_sum = r1n + r2n
        if not abs(a) > 1e-9 * r_sum:
            continue
        target = math.sqrt(mu) * tof[k]
        # Bracket: widen into the hyperbolic range until tof(lo) is short enough.
        lo, hi = -_FOUR_PI2, _FOUR_PI2 * (1.0 - _TOP_MARGIN)
        while True:
            value, _, _ = _time_function(lo, a, r_sum)
            if math.isnan(value) or value <= target or lo <= _MIN_Z:
                break
            lo = max(4.0 * lo, _MIN_Z)
        value, _, _ = _time_function(lo, a, r_sum)
        if not math.isnan(value) and value > target:
            continue  # would need more than the widest hyperbolic bracket
        z = 0.0
        done = False
        it = 0
        while it < _MAX_ITERATIONS:
            it += 1
            value, slope, _ = _time_function(z, a, r_sum)
            if math.isnan(value):
                lo = z
                z = 0.5 * (lo + hi)
                continue
            residual = value - target
            if abs(residual) <= rtol * target:
                done = True
                break
            if residual < 0.0:
                lo = z
            else:
                hi = z
            if hi - lo <= 4.0 * _EPS * max(1.0, abs(z)):
                break
            newton = z - residual / slope
            z = newton if lo < newton < hi else 0.5 * (lo + hi)
        iterations[k] = it
        if not done:
            continue
        c, s = _stumpff(z)
        y = r_sum + a * (z * s - 1.0) / math.sqrt(c)
        f = 1.0 - y / r1n
        g = a * math.sqrt(y / mu)
        g_dot = 1.0 - y / r2n
        good = True
        for j in range(3):
            v1[k, j] = (r2[k, j] - f * r1[k, j]) / g
            v2[k, j] = (g_dot * r2[k, j] - r1[k, j]) / g
            good = good and math.isfinite(v1[k, j]) and math.isfinite(v2[k, j])
        ok[k] = good
        if not good:
            v1[k, :] = np.nan
            v2[k, :] = np.nan
    return v1, v2, ok, iterations


def lambert(
    r1: ArrayLike,
    r2: ArrayLike,
    tof: ArrayLike,
    *,
    mu: float,
    h_ref: ArrayLike,
    rtol: float = 1e-13,
) -> LambertSolution:
    """Zero-revolution Lambert arcs from ``r1`` to ``r2`` [m] in ``tof`` [s].

    ``r1``, ``r2``, ``h_ref`` are (S, 3) or (3,), ``tof`` (S,) or a scalar. ``h_ref``
    picks the sense of motion: the arc's angular momentum has a positive projection on
    it. ``mu`` [m^3/s^2]; ``rtol`` is the relative tolerance on the time of flight.
    Arcs that cannot be solved (module notes) have ``ok = False`` and NaN velocities.
    """
    r1, r2, h_ref = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (r1, r2, h_ref))
    r1, r2, h_ref = np.broadcast_arrays(r1, r2, h_ref)
    tof = np.broadcast_to(np.asarray(tof, dtype=float), r1.shape[:1])
    v1, v2, ok, iterations = _solve(
        np.ascontiguousarray(r1),
        np.ascontiguousarray(r2),
        np.ascontiguousarray(tof),
        np.ascontiguousarray(h_ref),
        float(mu),
        float(rtol),
    )
    return LambertSolution(v1=v1, v2=v2, ok=ok, iterations=iterations)
