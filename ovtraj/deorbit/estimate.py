"""Two-body estimate of a tangential deorbit burn (patent step 103).

A single retrograde impulse, tangential to the velocity, is applied at radius
``r0`` on the (near-circular) preparation orbit. It lowers the speed from
``v0`` to ``v1`` so that the descent ellipse reaches the entry interface radius
``re`` with the required flight-path angle ``gamma_e < 0``. The velocity after
the burn is horizontal and below the circular speed, so the burn point is the
apoapsis of the descent ellipse and the entry point lies on its descending
branch (true anomaly in (pi, 2 pi)).

Conventions
-----------
* SI units: metres, seconds, radians; ``mu`` in m^3/s^2. Plain floats, no
  configuration is read here: pass ``default_earth().mu`` (or any other Earth).
* The flight-path angle is measured from the local horizontal, positive when
  climbing (Curtis 2014, "Orbital Mechanics for Engineering Students", 3rd ed.,
  §2.4; Vallado 2013, "Fundamentals of Astrodynamics and Applications", 4th ed.,
  ch. 2).
* Two-body motion only: no J2, no drag above ``re``, no Earth rotation (the
  entry speed is inertial).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ovtraj.astro.elements import mean_motion


@dataclass(frozen=True)
class TangentialDeorbit:
    """Result of :func:`tangential_deorbit`.

    burn_radius_m, entry_radius_m: r0 and re [m].
    entry_fpa_rad: flight-path angle at entry [rad], negative (descending).
    speed_before_mps, speed_after_mps: inertial speed at the burn point before
        and after the impulse [m/s].
    dv_mps: speed_before - speed_after [m/s], the size of the retrograde impulse.
    semi_major_axis_m, eccentricity: the descent ellipse (apoapsis at r0).
    entry_speed_mps: inertial speed at the entry radius [m/s].
    central_angle_rad: angle swept from the burn point to the entry point,
        in (0, pi) [rad].
    time_of_flight_s: time from the burn to the entry point [s].
    """

    burn_radius_m: float
    entry_radius_m: float
    entry_fpa_rad: float
    speed_before_mps: float
    speed_after_mps: float
    dv_mps: float
    semi_major_axis_m: float
    eccentricity: float
    entry_speed_mps: float
    central_angle_rad: float
    time_of_flight_s: float


def tangential_deorbit(
    burn_radius_m: float,
    entry_radius_m: float,
    entry_fpa_rad: float,
    mu: float,
    speed_before_mps: float | None = None,
) -> TangentialDeorbit:
    """Tangential retrograde burn at ``burn_radius_m`` that enters at a given angle.

    The burn leaves a horizontal velocity ``v1`` at ``r0`` (:func:`_post_burn_speed_sq`),
    below the circular speed, so the burn point is the apoapsis of the descent ellipse
    (:func:`_descent_ellipse`); the entry point, its speed and the central angle from the
    burn follow from the orbit equation (:func:`_entry_speed_and_central_angle`), the time
    of flight from Kepler's equation (:func:`_time_of_flight_s`). dv = v0 - v1, with ``v0``
    the circular speed sqrt(mu/r0) unless ``speed_before_mps`` is given (the velocity
    before the burn is assumed horizontal, i.e. the burn point is an apsis or the orbit
    is circular).

    Units: radii in m, angles in rad, ``mu`` in m^3/s^2, speeds in m/s.

    Raises ``ValueError`` for non-positive radii or ``mu``, an entry radius not
    below the burn radius, a flight-path angle outside (-pi/2, 0), or a
    ``speed_before_mps`` below the required post-burn speed (the entry
    condition would need a prograde burn).
    """
    r0 = float(burn_radius_m)
    re = float(entry_radius_m)
    gamma = float(entry_fpa_rad)
    mu = float(mu)
    _check_geometry(r0, re, gamma, mu)
    v1_sq = _post_burn_speed_sq(r0, re, gamma, mu)
    v1 = math.sqrt(v1_sq)
    v0 = _speed_before(speed_before_mps, r0, mu, v1)
    a, e = _descent_ellipse(r0, v1_sq, mu)
    ve, delta = _entry_speed_and_central_angle(r0, re, gamma, mu, v1_sq)
    return TangentialDeorbit(
        burn_radius_m=r0,
        entry_radius_m=re,
        entry_fpa_rad=gamma,
        speed_before_mps=v0,
        speed_after_mps=v1,
        dv_mps=v0 - v1,
        semi_major_axis_m=a,
        eccentricity=e,
        entry_speed_mps=ve,
        central_angle_rad=delta,
        time_of_flight_s=_time_of_flight_s(a, e, delta, mu),
    )


def _check_geometry(r0: float, re: float, gamma: float, mu: float) -> None:
    """Raise ``ValueError`` naming the argument unless ``mu`` [m^3/s^2] and the radii [m]
    are positive and finite, ``re < r0`` and ``gamma`` [rad] lies in (-pi/2, 0)."""
    if not (math.isfinite(mu) and mu > 0.0):
        raise ValueError(f"mu must be positive and finite [m^3/s^2], got {mu}")
    if not (math.isfinite(r0) and r0 > 0.0):
        raise ValueError(f"burn_radius_m must be positive and finite [m], got {r0}")
    if not (math.isfinite(re) and re > 0.0):
        raise ValueError(f"entry_radius_m must be positive and finite [m], got {re}")
    if not re < r0:
        raise ValueError(f"entry_radius_m must lie in (0, burn_radius_m) = (0, {r0}) m, got {re} m")
    if not (-0.5 * math.pi < gamma < 0.0):
        raise ValueError(
            f"entry_fpa_rad must lie in (-pi/2, 0) rad (descending entry), got {gamma} rad"
        )


def _speed_before(speed_before_mps: float | None, r0: float, mu: float, v1: float) -> float:
    """The speed before the burn [m/s]: the circular speed at ``r0`` unless given; raises
    ``ValueError`` when a given one is not positive and finite or is below ``v1``."""
    if speed_before_mps is None:
        return math.sqrt(mu / r0)
    v0 = float(speed_before_mps)
    if not (math.isfinite(v0) and v0 > 0.0):
        raise ValueError(f"speed_before_mps must be positive and finite [m/s], got {v0}")
    if v1 > v0:
        raise ValueError(
            f"speed_before_mps must be at least the post-burn speed {v1:.6f} m/s, "
            f"got {v0} m/s: this entry condition needs a prograde burn of "
            f"{v1 - v0:.6f} m/s, not a retrograde deorbit burn"
        )
    return v0


def _post_burn_speed_sq(r0: float, re: float, gamma: float, mu: float) -> float:
    """v1^2 [m^2/s^2], the squared horizontal speed after the burn at ``r0`` that enters
    at ``re`` with the flight-path angle ``gamma``.

    Conservation of angular momentum and of energy between the burn point and the entry
    point (Curtis, 3rd ed., §2.4-2.5: h = r v_perp and v^2/2 - mu/r = const; Vallado,
    4th ed., ch. 1, the specific angular momentum and specific mechanical energy)::

        h = r0 v1 = re ve cos(gamma_e)
        v1^2/2 - mu/r0 = ve^2/2 - mu/re

    Eliminating ``ve``::

        v1^2 = 2 mu re cos^2(gamma_e) (r0 - re) / (r0 (r0^2 - re^2 cos^2(gamma_e)))

    which is always below the circular speed sqrt(mu/r0) for re < r0, so the burn point
    is the apoapsis. As gamma_e -> 0- it tends to the apoapsis speed
    sqrt(2 mu re / (r0 (r0 + re))) of the Hohmann-like ellipse from r0 down to re.
    """
    cos_g_sq = math.cos(gamma) ** 2
    # r0^2 - re^2 cos^2 > 0 since re < r0; factored to keep the digits.
    re_cos = re * math.cos(gamma)
    return 2.0 * mu * re * cos_g_sq * (r0 - re) / (r0 * (r0 - re_cos) * (r0 + re_cos))


def _descent_ellipse(r0: float, v1_sq: float, mu: float) -> tuple[float, float]:
    """Semi-major axis [m] and eccentricity of the descent ellipse, apoapsis at ``r0``.

    Vis-viva gives a = -mu / (2 (v1^2/2 - mu/r0)); with the semi-latus rectum
    p = h^2/mu and the apoapsis r0 = p / (1 - e), e = 1 - r0 v1^2 / mu (Curtis, 3rd ed.,
    §2.7).
    """
    energy = 0.5 * v1_sq - mu / r0
    a = -mu / (2.0 * energy)
    e = 1.0 - r0 * v1_sq / mu
    return a, e


def _entry_speed_and_central_angle(
    r0: float, re: float, gamma: float, mu: float, v1_sq: float
) -> tuple[float, float]:
    """The entry speed [m/s] and the central angle [rad] from the burn to the entry.

    With nu_e = pi + delta the true anomaly at entry, the orbit equation
    re = p / (1 + e cos nu_e) and the radial velocity v_r = (mu/h) e sin nu_e =
    ve sin(gamma_e) (Curtis, 3rd ed., §2.4) give::

        e cos(delta) = 1 - p/re,    e sin(delta) = -h ve sin(gamma_e) / mu

    so the central angle from the burn to the entry is delta = atan2(e sin delta,
    e cos delta) in (0, pi) (atan2 stays accurate where acos of the orbit equation would
    lose digits); ve follows from the energy (:func:`_post_burn_speed_sq`).
    """
    h = r0 * math.sqrt(v1_sq)
    semi_latus_rectum = h * h / mu
    ve = math.sqrt(v1_sq + 2.0 * mu * (r0 - re) / (r0 * re))
    # Central angle from the apoapsis: delta = nu_e - pi.
    e_sin_delta = -h * ve * math.sin(gamma) / mu
    e_cos_delta = 1.0 - semi_latus_rectum / re
    return ve, math.atan2(e_sin_delta, e_cos_delta)


def _time_of_flight_s(a: float, e: float, delta: float, mu: float) -> float:
    """Time [s] from the burn (the apoapsis) to the entry, ``delta`` [rad] later.

    Eccentric anomaly from the true anomaly (Vallado, 4th ed., Algorithm 5; Curtis,
    3rd ed., §3.4), written relative to the apoapsis E = pi + dE::

        sin(dE) = sqrt(1 - e^2) sin(delta) / (1 - e cos(delta))
        cos(dE) = (cos(delta) - e) / (1 - e cos(delta))

    and Kepler's equation M = E - e sin E (Vallado, 4th ed., §2.2; Curtis, 3rd ed.,
    §3.4) gives M - pi = dE + e sin(dE) and t = (M - pi) / n with n = sqrt(mu / a^3).
    """
    sin_d, cos_d = math.sin(delta), math.cos(delta)
    d_ecc_anomaly = math.atan2(math.sqrt((1.0 - e) * (1.0 + e)) * sin_d, cos_d - e)
    return (d_ecc_anomaly + e * math.sin(d_ecc_anomaly)) / mean_motion(a, mu=mu)


def descent_central_angle_rad(
    burn_radius_m: float, entry_radius_m: float, entry_fpa_rad: float, mu: float
) -> float:
    """The central angle [rad] of :func:`tangential_deorbit` alone, for callers that need
    only it over many burn radii (the pass forecast): the same operations, so the same
    bits, without the checks and the rest of the descent. Arguments as there, valid."""
    v1_sq = _post_burn_speed_sq(burn_radius_m, entry_radius_m, entry_fpa_rad, mu)
    return _entry_speed_and_central_angle(burn_radius_m, entry_radius_m, entry_fpa_rad, mu, v1_sq)[
        1
    ]
