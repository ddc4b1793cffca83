"""Atmospheric drag: thermospheric density (NRLMSISE-00 or JB2008) and the cannonball force.

Density: heyoka's thermoNETs, neural fits of NRLMSISE-00 (Picone et al., JGR 107, 2002)
and of JB2008 (Bowman et al., AIAA 2008-6438) over 180-1000 km (Izzo, Acciarini &
Biscani, "NeuralODEs for VLEO simulations", 2024), of the geodetic altitude [km],
latitude and longitude (WGS-84, Hirvonen-Moritz iterations) and the space-weather indices.

Force (Montenbruck & Gill 2000, eq. 3.97): a = -1/2 rho (C_D A / m) |v_r| v_r, with the
velocity relative to an atmosphere that turns with the Earth, v_r = v - omega_E x r.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import heyoka as hy

from ovtraj.units import M_PER_KM

__all__ = ["SpaceWeather", "drag_acceleration", "geodetic", "thermosphere_density"]


@dataclass(frozen=True)
class SpaceWeather:
    """The indices as expressions: F10.7 of the previous day and its 81-day centred mean
    [sfu], the daily Ap; for JB2008 also S10.7, M10.7, Y10.7, their means [sfu] and
    dDst/dT [nT/h]."""

    f107: Any
    f107a: Any
    ap: Any
    jb08: tuple[Any, ...] = ()


def geodetic(
    r_itrs: Sequence[Any], *, equatorial_radius_m: float, eccentricity_squared: float
) -> list[Any]:
    """[altitude m, latitude rad, longitude rad] of an Earth-fixed position [m]."""
    return list(
        hy.model.cart2geo(
            list(r_itrs), ecc2=eccentricity_squared, R_eq=equatorial_radius_m, n_iters=4
        )
    )


def thermosphere_density(
    geodetic_coordinates: Sequence[Any], day_of_year: Any, weather: SpaceWeather, model: str
) -> Any:
    """Density [kg/m^3] by the ``model`` thermoNET (``nrlmsise00`` or ``jb08``)."""
    altitude_m, latitude, longitude = geodetic_coordinates
    where = [altitude_m / M_PER_KM, latitude, longitude]
    if model == "nrlmsise00":
        return hy.model.nrlmsise00_tn(where, weather.f107, weather.f107a, weather.ap, day_of_year)
    if model == "jb08":
        s107, s107a, m107, m107a, y107, y107a, ddst = weather.jb08
        return hy.model.jb08_tn(
            where,
            weather.f107,
            weather.f107a,
            s107,
            s107a,
            m107,
            m107a,
            y107,
            y107a,
            ddst,
            day_of_year,
        )
    raise ValueError(f"unknown density model {model!r} (nrlmsise00 or jb08)")


def drag_acceleration(
    r: Sequence[Any], v: Sequence[Any], density: Any, ballistic_m2_kg: Any, omega_rad_s: float
) -> list[Any]:
    """Drag acceleration [m/s^2] in the inertial frame of ``r`` [m] and ``v`` [m/s] (z along
    the Earth's axis), ``ballistic_m2_kg`` = C_D A / m."""
    x, y, _ = r
    relative = [v[0] + omega_rad_s * y, v[1] - omega_rad_s * x, v[2]]
    speed = hy.sqrt(sum(c * c for c in relative))
    factor = -0.5 * density * ballistic_m2_kg * speed
    return [factor * c for c in relative]
