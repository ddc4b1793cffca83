"""Initial burn parameters from mean elements: the two-orbit intersection (seed sec. 2.1).

Where two coplanar orbits meet they share the argument of latitude u and the radius (seed
eq. 5)::

    p_0 / (1 + e0x cos u + e0y sin u) = p_f / (1 + efx cos u + efy sin u)

with ex = e cos(argp), ey = e sin(argp), p = a (1 - e^2), index 0 the waiting orbit and f
the transfer orbit. Cross-multiplied it is linear in cos u and sin u (seed eq. 6)::

    k1 cos u + k2 sin u = k3,
    k1 = p_0 efx - p_f e0x,   k2 = p_0 efy - p_f e0y,   k3 = p_f - p_0

so u = atan2(k2, k1) +- acos(k3 / sqrt(k1^2 + k2^2)): two roots when |k3| < sqrt(k1^2 + k2^2),
none when the orbits do not meet (no single-burn solution; for a circular waiting orbit this
is seed eq. 4). The root that precedes the entry point by the smaller angle is the burn point
(the seed picks "the intersection nearer the entry point").

At the burn point the radial and transverse speeds before (seed eq. 7) and after (eq. 8) the
impulse are v_r = sqrt(mu/p)(ex sin u - ey cos u), v_t = sqrt(mu/p)(1 + ex cos u + ey sin u)
of each orbit (Curtis 2014, 3rd ed., eqs. 2.31, 2.49 rotated by argp). The impulse is
dv = sqrt((v_fr - v_0r)^2 + (v_ft - v_0t)^2) (eq. 9), and the burn angle theta (eq. 10) the
angle of the impulse from the negative along-track direction in the orbital frame,
theta = atan2(v_fr - v_0r, -(v_ft - v_0t)), positive when the thrust leans away from the Earth
(on the circular waiting orbit the along-track direction is the velocity: the seed's angle
"between the thrust and the negative velocity").

All angles in rad, lengths in m, speeds in m/s, mu in m^3/s^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import fsolve

from ovtraj.astro.angles import TWO_PI, wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.elements import NonsingularElements, perigee_radius_from_semi_latus_rectum
from ovtraj.deorbit.estimate import tangential_deorbit
from ovtraj.studies.deorbit_burn.problem import EntryTarget

__all__ = [
    "ImpulsiveBurn",
    "IntersectionCoefficients",
    "burn_angle",
    "impulsive_burn",
    "impulsive_burn_at_angle",
    "in_plane_elements",
    "intersection_coefficients",
    "intersection_roots",
    "orbit_speeds",
]


@dataclass(frozen=True)
class IntersectionCoefficients:
    """k1, k2, k3 of seed eq. 6 [m]."""

    k1: float
    k2: float
    k3: float

    @property
    def solvable(self) -> bool:
        """The orbits meet: |k3| <= sqrt(k1^2 + k2^2)."""
        return abs(self.k3) <= math.hypot(self.k1, self.k2)


@dataclass(frozen=True)
class ImpulsiveBurn:
    """The impulsive burn at the intersection (seed eqs. 6-10).

    u_rad: burn point [rad]; radius_m: its radius [m]; speeds before (v0r, v0t) and after
    (vfr, vft) [m/s]; dv_mps: eq. 9; burn_angle_rad: eq. 10; central_angle_rad: from the
    burn point to the entry point, in [0, 2 pi).
    """

    u_rad: float
    radius_m: float
    v0r: float
    v0t: float
    vfr: float
    vft: float
    dv_mps: float
    burn_angle_rad: float
    central_angle_rad: float


def in_plane_elements(el: NonsingularElements) -> tuple[float, float, float]:
    """(a [m], ex, ey) of an element set: what the in-plane formulas of this module take."""
    return float(el.a), float(el.ex), float(el.ey)


def intersection_coefficients(
    p0: float, e0x: float, e0y: float, pf: float, efx: float, efy: float
) -> IntersectionCoefficients:
    """k1, k2, k3 of seed eq. 6 from the two orbits' p [m] and eccentricity vectors."""
    return IntersectionCoefficients(
        k1=p0 * efx - pf * e0x,
        k2=p0 * efy - pf * e0y,
        k3=pf - p0,
    )


def intersection_roots(k: IntersectionCoefficients) -> tuple[float, float] | None:
    """Both roots u in [0, 2 pi) of k1 cos u + k2 sin u = k3, or None if there are none."""
    amplitude = math.hypot(k.k1, k.k2)
    if amplitude == 0.0 or not k.solvable:
        return None
    centre = math.atan2(k.k2, k.k1)
    half = math.acos(max(-1.0, min(1.0, k.k3 / amplitude)))
    return wrap_to_two_pi(centre - half), wrap_to_two_pi(centre + half)


def orbit_speeds(p: float, ex: float, ey: float, u: float, mu: float) -> tuple[float, float]:
    """Radial and transverse speed [m/s] on the orbit (p, ex, ey) at u (seed eqs. 7-8)."""
    scale = math.sqrt(mu / p)
    return (
        scale * (ex * math.sin(u) - ey * math.cos(u)),
        scale * (1.0 + ex * math.cos(u) + ey * math.sin(u)),
    )


def burn_angle(dvr: float, dvt: float) -> float:
    """Angle [rad] of the impulse (dvr, dvt) from the negative along-track direction (eq. 10).

    theta = atan2(dv_r, -dv_t): the angle in the orbital frame, positive when the impulse
    leans away from the Earth. On a circular orbit -t_hat is -v_hat, the seed's reference.
    """
    return math.atan2(dvr, -dvt)


def impulsive_burn(
    waiting: tuple[float, float, float],
    transfer: tuple[float, float, float],
    entry_u: float,
    mu: float,
) -> ImpulsiveBurn | None:
    """The impulsive burn from the waiting to the transfer orbit (seed eqs. 6-10).

    ``waiting`` and ``transfer`` are (a [m], ex, ey) (mean elements, same plane); ``entry_u``
    [rad] the entry argument of latitude. Returns None when the orbits do not meet.
    """
    a0, e0x, e0y = waiting
    af, efx, efy = transfer
    p0 = a0 * (1.0 - e0x * e0x - e0y * e0y)
    pf = af * (1.0 - efx * efx - efy * efy)
    roots = intersection_roots(intersection_coefficients(p0, e0x, e0y, pf, efx, efy))
    if roots is None:
        return None
    # The root that precedes the entry by the smaller angle.
    u = min(roots, key=lambda root: wrap_to_two_pi(entry_u - root))
    v0r, v0t = orbit_speeds(p0, e0x, e0y, u, mu)
    vfr, vft = orbit_speeds(pf, efx, efy, u, mu)
    return ImpulsiveBurn(
        u_rad=u,
        radius_m=p0 / (1.0 + e0x * math.cos(u) + e0y * math.sin(u)),
        v0r=v0r,
        v0t=v0t,
        vfr=vfr,
        vft=vft,
        dv_mps=math.hypot(vfr - v0r, vft - v0t),
        burn_angle_rad=burn_angle(vfr - v0r, vft - v0t),
        central_angle_rad=wrap_to_two_pi(entry_u - u),
    )


def _entry_after_impulse(
    waiting: tuple[float, float, float],
    u: float,
    dv: float,
    theta: float,
    entry_radius: float,
    mu: float,
) -> tuple[float, float, float, float, float]:
    """Two-body entry (fpa [rad], u [rad], speed [m/s]) after an impulse dv at angle theta.

    Also returns (v0r, v0t) before the impulse. fpa and u are NaN if the new orbit does not
    reach the entry radius.
    """
    a0, e0x, e0y = waiting
    p0 = a0 * (1.0 - e0x * e0x - e0y * e0y)
    r = p0 / (1.0 + e0x * math.cos(u) + e0y * math.sin(u))
    v0r, v0t = orbit_speeds(p0, e0x, e0y, u, mu)
    # dv along -t_hat cos(theta) + r_hat sin(theta), the orbital frame of eq. 10
    vr = v0r + dv * math.sin(theta)
    vt = v0t - dv * math.cos(theta)
    p = (r * vt) ** 2 / mu
    e_cos_fb, e_sin_fb = p / r - 1.0, vr * math.sqrt(p / mu)
    e = math.hypot(e_cos_fb, e_sin_fb)
    cos_fe = (p / entry_radius - 1.0) / e if e > 0.0 else math.inf
    f_b = math.atan2(e_sin_fb, e_cos_fb)
    if cos_fe > 1.0:
        # Perigee above r_E. Continued past grazing (where the entry is the perigee, fpa 0)
        # with the perigee's u and minus the relative perigee height, so that a root finder
        # sees one continuous function.
        perigee = perigee_radius_from_semi_latus_rectum(p, e)
        return (entry_radius - perigee) / entry_radius, u + wrap_to_two_pi(-f_b), math.nan, v0r, v0t
    if cos_fe < -1.0:
        return math.nan, math.nan, math.nan, v0r, v0t
    f_e = TWO_PI - math.acos(cos_fe)  # descending branch
    u_e = u + wrap_to_two_pi(f_e - f_b)
    fpa = math.atan2(e * math.sin(f_e), 1.0 + e * math.cos(f_e))
    v_e = math.sqrt(vr * vr + vt * vt + 2.0 * mu * (1.0 / entry_radius - 1.0 / r))
    return fpa, u_e, v_e, v0r, v0t


def impulsive_burn_at_angle(
    waiting: tuple[float, float, float],
    theta: float,
    entry: EntryTarget,
    mu: float,
) -> ImpulsiveBurn | None:
    """Two-body impulse at a given burn angle that meets the entry fpa and u (not the speed).

    The burn point u and size dv solve fpa(u, dv) = gamma_E and u_entry(u, dv) = u_E (scipy
    ``fsolve``), started from the tangential two-body estimate (patent step 103, energy and
    angular momentum, :func:`ovtraj.deorbit.estimate.tangential_deorbit`). At the eq. 10
    angle this is the intersection solution. ``waiting`` = (a [m], ex, ey); theta [rad].
    Returns None if no solution is found.
    """
    a0, e0x, e0y = waiting
    estimate = tangential_deorbit(a0, entry.radius_m, entry.fpa_rad, mu)
    # The tangential component does most of the work: dv ~ dv_tangential / cos(theta).
    start = np.array(
        [entry.u_rad - estimate.central_angle_rad, estimate.dv_mps / max(math.cos(theta), 0.2)]
    )

    def residual(x: np.ndarray) -> np.ndarray:
        fpa, u_e, _, _, _ = _entry_after_impulse(
            waiting, float(x[0]), float(x[1]), theta, entry.radius_m, mu
        )
        if not math.isfinite(fpa):
            return np.array([1.0, 1.0]) * (1.0 + abs(float(x[1])))  # hyperbolic: far off
        du = wrap_to_pi(u_e - entry.u_rad)
        return np.array([fpa - entry.fpa_rad, du])

    solution, _, status, _ = fsolve(residual, start, full_output=True, xtol=1e-12)
    if status != 1 or np.max(np.abs(residual(solution))) > 1e-9:
        return None
    u, dv = wrap_to_two_pi(float(solution[0])), float(solution[1])
    if dv <= 0.0:
        return None
    _, u_e, _, v0r, v0t = _entry_after_impulse(waiting, u, dv, theta, entry.radius_m, mu)
    dvr, dvt = dv * math.sin(theta), -dv * math.cos(theta)
    p0 = a0 * (1.0 - e0x * e0x - e0y * e0y)
    return ImpulsiveBurn(
        u_rad=u,
        radius_m=p0 / (1.0 + e0x * math.cos(u) + e0y * math.sin(u)),
        v0r=v0r,
        v0t=v0t,
        vfr=v0r + dvr,
        vft=v0t + dvt,
        dv_mps=dv,
        burn_angle_rad=theta,
        central_angle_rad=wrap_to_two_pi(u_e - u),
    )
