"""SGP4's TEME frame and the project's inertial frame (ECI).

SGP4 gives positions and velocities in TEME, "true equator, mean equinox": its z
axis is the true (nutated) pole of date and its x axis lies in the true equator at
an angle GMST (IAU-82) from the Greenwich meridian. That is how TEME is tied to the
Earth: the pseudo-Earth-fixed frame (PEF) follows from TEME by one rotation about z
through GMST,

    r_PEF = ROT3(theta_GMST) r_TEME,
    v_PEF = ROT3(theta_GMST) v_TEME - omega_E x r_PEF

(Vallado, Crawford, Hujsak & Kelso 2006, "Revisiting Spacetrack Report #3",
AIAA 2006-6753, sec. "Coordinate frames" and eq. for TEME -> PEF; Vallado 2013,
sec. 3.7.5; Hoots & Roehrich 1980, Spacetrack Report No. 3, where GMST of the
same IAU-82 formula turns the elements' frame to the Earth), with polar motion the
only step left from PEF to the ITRF.

The project's ECI (``docs/conventions.md``) is defined by the
same relation: its Earth-fixed frame is ECI rotated about z by GMST (IAU-82, UT1 =
UTC), with precession, nutation and polar motion neglected. Reading the Earth-fixed
frame as PEF, the rotation from TEME to ECI is therefore

    r_ECI = ROT3(-theta) r_PEF = ROT3(-theta) ROT3(theta) r_TEME = r_TEME,

the identity, and so for the velocity (the omega_E x r terms of both frames cancel).
The functions below compose the two published steps with the project's own GMST and
frame code instead of returning their input, so that the chain is explicit and a
change of the project's Earth-fixed convention (GAST, a true-equinox frame) would
show up here. A true-of-date frame (TOD) would differ from ours by the equation of
the equinoxes about z (up to ~1.2 s of time, ~17 arcsec); ours is not TOD because
its Earth rotation angle is GMST, not GAST.

The check against an independent implementation (astropy's TEME -> ITRS) is in
``tests/test_target_sources.py`` and ``docs/validation.md``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ovtraj.astro.epoch import Epoch, gmst_rad
from ovtraj.astro.frames import ecef_to_eci_state, eci_to_ecef
from ovtraj.units import S_PER_DAY

__all__ = ["teme_gmst_rad", "teme_to_eci", "teme_to_pef"]


def teme_gmst_rad(epoch: Epoch, t_s: ArrayLike) -> np.ndarray:
    """GMST (IAU-82, UT1 = UTC) [rad] at ``epoch`` + ``t_s`` [s], the angle TEME turns by.

    Evaluated at each instant (Vallado eq. 3-47 through :func:`ovtraj.astro.epoch.gmst_rad`),
    as SGP4's own ``gstime`` does, rather than linearised from the epoch.
    """
    t = np.asarray(t_s, dtype=float)
    return np.asarray(gmst_rad(np.full(t.shape, epoch.jd1), epoch.jd2 + t / S_PER_DAY))


def teme_to_pef(
    r_teme: ArrayLike, v_teme: ArrayLike, theta: ArrayLike, *, omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pseudo-Earth-fixed state from a TEME state (Vallado et al. 2006, TEME -> PEF).

    r_PEF = ROT3(theta) r_TEME, v_PEF = ROT3(theta) v_TEME - omega x r_PEF.

    Parameters
    ----------
    r_teme, v_teme:
        TEME position [m] and velocity [m/s], shape (..., 3).
    theta:
        GMST (IAU-82) [rad], broadcast against the leading axes.
    omega:
        Earth rotation rate [rad/s].
    """
    r_pef = eci_to_ecef(r_teme, theta)
    v_rotated = eci_to_ecef(v_teme, theta)
    omega_cross_r = np.stack(
        [-omega * r_pef[..., 1], omega * r_pef[..., 0], np.zeros_like(r_pef[..., 2])], axis=-1
    )
    return r_pef, v_rotated - omega_cross_r


def teme_to_eci(
    r_teme: ArrayLike, v_teme: ArrayLike, theta: ArrayLike, *, omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """The project's ECI state (m, m/s) of a TEME state: TEME -> PEF -> ECI.

    TEME -> PEF by :func:`teme_to_pef` (GMST ``theta``), then PEF, the project's
    Earth-fixed frame, back to ECI with the same angle through
    :func:`ovtraj.astro.frames.ecef_to_eci_state`. The composition is the identity to
    rounding (see the module notes): the project's ECI is TEME of date.
    """
    r_pef, v_pef = teme_to_pef(r_teme, v_teme, theta, omega=omega)
    return ecef_to_eci_state(r_pef, v_pef, theta, omega=omega)
