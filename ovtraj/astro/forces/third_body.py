"""The Sun and the Moon: their geocentric positions and their pull on a satellite.

Positions in TEME [m]: the Sun from VSOP2013 (Simon et al., A&A 557, 2013), the
heliocentric Earth-Moon barycentre in the ICRS, reversed (the Earth's 4,700 km offset from
the barycentre is left out: 3e-5 rad of the Sun's direction); the Moon from ELP2000-82B
(Chapront-Touzé & Chapront 1983) in the FK5 J2000 frame, rotated to the ICRS. Both are
turned from the ICRS to TEME of date through the ITRS by heyoka's IAU 2006/2000A
precession-nutation, ERA and EOP and its ITRS -> TEME rotation. Time in TDB is taken as TT
(|TDB - TT| < 1.7 ms).

Pull (Montenbruck & Gill 2000, eq. 3.37): the body's attraction on the satellite less
its attraction on the Earth, a = mu (s - r)/|s - r|^3 - mu s/|s|^3.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import heyoka as hy

from ovtraj.units import JULIAN_CENTURIES_PER_MILLENNIUM, M_PER_KM

__all__ = ["icrs_to_teme", "moon_position", "sun_position", "third_body_acceleration"]


def icrs_to_teme(
    vector: Sequence[Any], tt: Any, eop: hy.eop_data, precession_threshold: float
) -> list[Any]:
    """TEME components of an ICRS vector at TT centuries ``tt``."""
    itrs = hy.model.rot_icrs_itrs(list(vector), tt, precession_threshold, eop)
    return list(hy.model.rot_itrs_teme(itrs, tt, eop))


def sun_position(
    tt: Any,
    *,
    astronomical_unit_m: float,
    threshold: float,
    eop: hy.eop_data,
    precession_threshold: float,
) -> list[Any]:
    """Geocentric Sun [m] in TEME at TT centuries ``tt`` (VSOP2013 truncated at
    ``threshold``)."""
    millennia = tt / JULIAN_CENTURIES_PER_MILLENNIUM
    barycentre_au = hy.model.vsop2013_cartesian_icrf(3, millennia, thresh=threshold)[:3]
    sun_icrs = [-astronomical_unit_m * c for c in barycentre_au]
    return icrs_to_teme(sun_icrs, tt, eop, precession_threshold)


def moon_position(
    tt: Any, *, threshold: float, eop: hy.eop_data, precession_threshold: float
) -> list[Any]:
    """Geocentric Moon [m] in TEME at TT centuries ``tt`` (ELP2000 truncated at
    ``threshold``)."""
    moon_fk5 = [M_PER_KM * c for c in hy.model.elp2000_cartesian_fk5(tt, thresh=threshold)]
    moon_icrs = hy.model.rot_fk5j2000_icrs(moon_fk5)
    return icrs_to_teme(moon_icrs, tt, eop, precession_threshold)


def third_body_acceleration(r: Sequence[Any], body: Sequence[Any], mu: float) -> list[Any]:
    """Acceleration [m/s^2] of a satellite at ``r`` [m] relative to the Earth by a body at
    ``body`` [m] of gravitational parameter ``mu`` [m^3/s^2]."""
    d = [body[i] - r[i] for i in range(3)]
    d3 = hy.sqrt(sum(c * c for c in d)) ** 3
    s3 = hy.sqrt(sum(c * c for c in body)) ** 3
    return [mu * (d[i] / d3 - body[i] / s3) for i in range(3)]
