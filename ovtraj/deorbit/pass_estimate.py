"""The first pass through the entry region of a circular J2 orbit, in closed form.

A low-fidelity stand-in for :func:`ovtraj.deorbit.forecast.forecast_passes`: no
integration, vectorised over many orbits at once. The orbit is circular in mean elements
and moves with the J2 secular rates only (Brouwer 1959, :func:`secular_rates`):
``u(t) = u0 + u_dot t`` and ``raan(t) = raan0 + raan_dot t``. Over a spherical Earth its
ground track reaches the geocentric latitude ``phi`` where ``sin u = sin phi / sin i``:
northbound at ``u = asin(sin phi / sin i)`` (``cos u > 0``), southbound at ``pi`` minus
that; the longitude there is ``raan + atan2(cos i sin u, cos u) - theta(t)`` with the Earth
angle ``theta(t) = theta0 + omega_E t`` (Vallado 2013, ch. 3 and 11: ground tracks).

As the stage does, a crossing counts when its longitude is inside the entry box and its
direction is accepted, and when the deorbit burn, one descent central angle before it
(the two-body tangential estimate at the entry angle the stage aims for), does not
precede the start by more than the burn window.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ovtraj.astro.angles import TWO_PI, wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import mean_motion
from ovtraj.astro.j2_elements import secular_rates
from ovtraj.deorbit.estimate import descent_central_angle_rad, tangential_deorbit
from ovtraj.deorbit.inputs import EntryRegion


def descent_angle_rad(radius_m: ArrayLike, entry: EntryRegion, earth: EarthModel) -> NDArray:
    """Central angle [rad] from the tangential burn at ``radius_m`` to the entry interface
    at the entry angle the stage aims for (``fpa_target_rad``), two-body."""
    entry_radius = earth.radius + entry.altitude_m
    radii, index = np.unique(np.atleast_1d(np.asarray(radius_m, dtype=float)), return_inverse=True)
    # The checks of the whole descent at the smallest and the largest radius (sorted, a NaN
    # last): every radius between passes them too.
    for r in radii[[0, -1]] if radii.size else ():
        tangential_deorbit(float(r), entry_radius, entry.fpa_target_rad, earth.mu)
    angles = [
        descent_central_angle_rad(float(r), entry_radius, entry.fpa_target_rad, earth.mu)
        for r in radii
    ]
    return np.asarray(angles)[index]


def first_pass_s(
    t0_s: ArrayLike,
    u0_rad: ArrayLike,
    raan0_rad: ArrayLike,
    inclination_rad: float,
    radius_m: ArrayLike,
    *,
    entry: EntryRegion,
    earth: EarthModel,
    earth_angle_at_zero_rad: float,
    horizon_s: float,
    burn_window_s: float,
    longitude_shift_rad: float = 0.0,
) -> NDArray:
    """Time [s, the clock of ``t0_s``] of each orbit's first pass through the entry region
    within ``horizon_s`` after ``t0_s``; NaN when there is none.

    Every argument but the scalars broadcasts to one shape (m,): the orbits' start times,
    mean arguments of latitude and right ascensions there [rad], and radii [m]. The Earth
    angle is ``earth_angle_at_zero_rad`` at t = 0 of that clock. ``longitude_shift_rad``
    is added to every crossing's longitude before the box is checked (a measured bias of
    this estimate against the stage, :class:`ovtraj.pipeline.pass_model.PassModel`).
    """
    t0, u0, raan0, radius = np.broadcast_arrays(
        *(np.atleast_1d(np.asarray(x, dtype=float)) for x in (t0_s, u0_rad, raan0_rad, radius_m))
    )
    sin_i = math.sin(inclination_rad)
    ratio = math.sin(entry.latitude_rad) / sin_i
    if abs(ratio) > 1.0:  # the ground track never reaches the entry latitude
        return np.full(t0.shape, np.nan)
    raan_dot, argp_dot, m_dot = secular_rates(
        radius, 0.0, inclination_rad, mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    u_dot = np.asarray(argp_dot) + np.asarray(m_dot)
    north = math.asin(ratio)
    crossings = [
        u
        for u, northbound in ((north, True), (math.pi - north, False))
        if entry.accepts_direction(northbound)
    ]
    # Crossings k = 0, 1, ... of each chosen argument of latitude, one per revolution.
    revolutions = int(np.ceil(horizon_s * float(np.max(u_dot)) / TWO_PI)) + 1
    k = np.arange(revolutions)[None, :]
    lead = descent_angle_rad(radius, entry, earth) / mean_motion(radius, mu=earth.mu)
    best = np.full(t0.shape, np.inf)
    for u in crossings:
        du = wrap_to_two_pi(u - u0)[:, None] + TWO_PI * k
        t = du / u_dot[:, None]  # since t0
        absolute = t0[:, None] + t
        longitude = (
            raan0[:, None]
            + raan_dot[:, None] * t
            + math.atan2(math.cos(inclination_rad) * math.sin(u), math.cos(u))
            - (earth_angle_at_zero_rad + earth.rotation_rate_rad_s * absolute)
        )
        shifted = longitude + longitude_shift_rad
        offset = wrap_to_pi(shifted - entry.longitude_rad)
        usable = (
            (np.abs(offset) <= entry.longitude_tol_rad)
            & (t <= horizon_s)
            & (t - lead[:, None] + burn_window_s >= 0.0)
        )
        first = np.where(usable, absolute, np.inf).min(axis=1)
        best = np.minimum(best, first)
    return np.where(np.isfinite(best), best, np.nan)
