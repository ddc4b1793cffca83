"""SGP4 ephemeris of an element set in the project's inertial frame.

``sgp4`` (Rhodes' Python/C++ wrapper of Vallado's SGP4, Vallado et al. 2006)
gives TEME positions [km] and velocities [km/s] at UTC Julian dates; they are
rotated into the project's ECI by :func:`ovtraj.astro.teme.teme_to_eci` (the
identity, see that module) with GMST at each instant.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from sgp4.api import SGP4_ERRORS

from ovtraj.astro.epoch import Epoch
from ovtraj.astro.teme import teme_gmst_rad, teme_to_eci
from ovtraj.element_sets.elements import SourceElements
from ovtraj.errors import ConfigError
from ovtraj.units import M_PER_KM, S_PER_DAY

__all__ = ["sgp4_eci"]


def sgp4_eci(
    elements: SourceElements, epoch: Epoch, t_s: ArrayLike, *, omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """ECI positions [m] and velocities [m/s], shape (n, 3), at ``epoch`` + ``t_s`` [s].

    Raises :class:`ConfigError` when SGP4 cannot reach one of the instants (a
    decayed orbit, an eccentricity driven out of [0, 1)), naming the instant and
    SGP4's reason.
    """
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    jd = np.full(t.shape, epoch.jd1)
    fraction = epoch.jd2 + t / S_PER_DAY
    codes, r_km, v_kms = elements.satrec.sgp4_array(jd, fraction)
    bad = np.flatnonzero(codes)
    if bad.size:
        k = int(bad[0])
        code = int(codes[k])
        when = epoch.plus_seconds(float(t[k])).iso()
        raise ConfigError(
            [
                f"SGP4 cannot propagate {elements.label()} to {when}: "
                f"{SGP4_ERRORS.get(code, 'unknown error')} (error {code})"
            ],
            elements.where,
        )
    theta = teme_gmst_rad(epoch, t)
    return teme_to_eci(
        np.asarray(r_km) * M_PER_KM, np.asarray(v_kms) * M_PER_KM, theta, omega=omega
    )
