"""TEME (the project's inertial frame) <-> EME2000, for CCSDS OEM/OPM export.

The project's ECI is SGP4's TEME, "true equator, mean equinox" of date
(``docs/conventions.md``, Frames; :mod:`ovtraj.astro.teme`). CCSDS messages are written
in EME2000: the mean equator and equinox of J2000.0 in the FK5 / IAU-76/80 realisation.
The two are related by precession and nutation, applied here with ERFA (pyerfa), not
with series written out in this module:

1. UTC -> TAI -> TT: ``erfa.utctai`` (it holds the leap-second table) and ``erfa.taitt``.
2. TEME -> true of date (TOD): TEME's x axis is the mean equinox, TOD's the true one,
   and both share the true equator and pole, so r_TOD = ROT3(-Eq_eq) r_TEME, with
   Eq_eq = GAST - GMST the equation of the equinoxes, IAU 1994 (``erfa.eqeq94``:
   Delta_psi cos(eps_A) from the IAU 1980 nutation plus the two kinematic terms of
   0.00264" sin(Omega) + 0.000063" sin(2 Omega)). ROT3 is the passive rotation about z
   (``erfa.rz``).
3. TOD -> EME2000: r_EME2000 = (N P)^T r_TOD, with N P = ``erfa.pnm80`` (IAU 1976
   precession, IAU 1980 nutation), which maps a mean-J2000 vector to true of date.

So r_EME2000 = pnm80(TT)^T ROT3(-eqeq94(TT)) r_TEME. This is the TEME definition of
Vallado (2013) sec. 3.7 (p. 233), the complete equation of the equinoxes included, and
reproduces Vallado's Example 3-15 / Table 3-6 TEME -> TOD -> J2000 figures to 0.1 mm
(``tests/test_eme2000.py``). Leaving the kinematic terms out, as some TEME codes do,
would move a 7000 km position by up to 0.09 m.

Neglected, with their measured size (LEO radius 7000 km unless stated):

* EOP nutation corrections (dPsi, dEps of IERS ``finals.all``): none are applied, so
  the result is EME2000 as the IAU-76/80 models alone place it, not corrected to the
  observed celestial pole. The Vallado example's dPsi = -0.052", dEps = -0.0039" move
  its 10 200 km position by 0.91 m (first-order bound (dEps, -dPsi sin eps) x |r| =
  1.05 m). Against the IAU 2006/2000A model (astropy 8 TEME -> GCRS, frame bias
  removed) this chain is 0.5 m off in 2000 and 1.0 m in 2026 for a 6778 km position,
  growing with the error of the IAU 1976 precession rate.
* The rotation rate of the transform: the velocity gets the same rotation as the
  position, without the d(M)/dt r term. TEME turns relative to EME2000 at the rate of
  precession plus nutation, at most 1.1e-11 rad/s (mean 8.2e-12, sampled 2000-2030),
  so the neglected term is at most 8e-5 m/s (0.08 mm/s) in LEO, 4.6e-4 m/s at GEO.
* TT is used where ``eqeq94`` asks for TDB: |TDB - TT| < 1.7 ms, a rotation < 2e-14 rad.
* UTC dates: erfa reads a UTC two-part Julian date on a leap-second day as a fraction
  of an 86401 s day, whereas :class:`ovtraj.astro.epoch.Epoch` ignores leap seconds
  (86400 s days). The instants then differ by up to 1 s, which moves the transform by
  at most 1.1e-11 rad (0.08 mm in LEO). Future leap seconds are unknown: erfa warns
  "dubious year" beyond its table's validity (from 2029 with pyerfa 2.0.1.5); one
  missing leap second is a 1 s error in TT, again below 0.1 mm. The warning is passed on.

References
----------
Vallado, D. A., Crawford, P., Hujsak, R. & Kelso, T. S., "Revisiting Spacetrack Report
#3", AIAA 2006-6753, 2006, sec. "Coordinate frames" (TEME).
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., Microcosm
Press, 2013, sec. 3.7 (IAU-76/FK5 reduction, TEME, p. 233), Example 3-15, Table 3-6.
IAU SOFA / ERFA: ``eraUtctai``, ``eraTaitt``, ``eraEqeq94``, ``eraPnm80``, ``eraRz``.
"""

from __future__ import annotations

import erfa
import numpy as np
from numpy.typing import ArrayLike

__all__ = ["eme2000_to_teme", "teme_to_eme2000", "teme_to_eme2000_matrix"]


def teme_to_eme2000_matrix(jd_utc1: ArrayLike, jd_utc2: ArrayLike) -> np.ndarray:
    """Rotation matrix M with r_EME2000 = M r_TEME, IAU-76/80 without EOP corrections.

    M = pnm80(TT)^T ROT3(-eqeq94(TT)) (see the module docstring for the method,
    sources and neglected terms).

    Parameters
    ----------
    jd_utc1, jd_utc2:
        UTC as a two-part (quasi) Julian date [day], as erfa takes it, e.g.
        ``epoch.jd1, epoch.jd2`` of an :class:`ovtraj.astro.epoch.Epoch`; scalars or
        arrays, broadcast together.

    Returns
    -------
    Orthonormal matrices, shape ``broadcast(jd_utc1, jd_utc2).shape + (3, 3)``.
    """
    tai1, tai2 = erfa.utctai(jd_utc1, jd_utc2)
    tt1, tt2 = erfa.taitt(tai1, tai2)
    # TEME -> TOD: passive rotation about the (common) true pole by -Eq_eq.
    tod_from_teme = erfa.rz(-erfa.eqeq94(tt1, tt2), np.eye(3))
    # pnm80 maps mean J2000 to true of date; its transpose maps TOD to EME2000.
    eme2000_from_tod = np.swapaxes(erfa.pnm80(tt1, tt2), -1, -2)
    return np.matmul(eme2000_from_tod, tod_from_teme)


def _as_vectors(name: str, value: ArrayLike) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim not in (1, 2) or array.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) or (N, 3), got {array.shape}")
    return array


def _rotate(matrix: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """matrix @ vector over broadcast leading axes: (..., 3, 3) x (..., 3) -> (..., 3)."""
    return np.einsum("...ij,...j->...i", matrix, vectors)


def teme_to_eme2000(
    jd_utc1: ArrayLike, jd_utc2: ArrayLike, r_teme: ArrayLike, v_teme: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """EME2000 (J2000, IAU-76/FK5) state of a TEME (project ECI) state.

    r_EME2000 = M r_TEME and v_EME2000 = M v_TEME with
    M = pnm80(TT)^T ROT3(-eqeq94(TT)) (Vallado 2013 sec. 3.7; Vallado et al. 2006).
    No EOP nutation corrections (about 1 m in LEO) and no d(M)/dt r term in the
    velocity (< 0.1 mm/s in LEO); see the module docstring for the measured sizes.

    Parameters
    ----------
    jd_utc1, jd_utc2:
        UTC two-part Julian date [day] (e.g. ``epoch.jd1, epoch.jd2``): scalars for one
        epoch, or arrays of N epochs (one per state row).
    r_teme:
        TEME position [m], shape (3,) or (N, 3).
    v_teme:
        TEME velocity [m/s], shape (3,) or (N, 3).

    Returns
    -------
    (r_eme2000 [m], v_eme2000 [m/s]):
        The same shape as the inputs (broadcast against the epochs: N epochs and one
        (3,) state give (N, 3)).

    Raises
    ------
    ValueError
        If ``r_teme`` or ``v_teme`` is not of shape (3,) or (N, 3).
    """
    r = _as_vectors("r_teme", r_teme)
    v = _as_vectors("v_teme", v_teme)
    matrix = teme_to_eme2000_matrix(jd_utc1, jd_utc2)
    return _rotate(matrix, r), _rotate(matrix, v)


def eme2000_to_teme(
    jd_utc1: ArrayLike, jd_utc2: ArrayLike, r_eme2000: ArrayLike, v_eme2000: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """TEME (project ECI) state of an EME2000 state: the inverse of :func:`teme_to_eme2000`.

    r_TEME = M^T r_EME2000, v_TEME = M^T v_EME2000 with the same M (orthonormal, so the
    transpose is the inverse; same neglected terms).

    Parameters
    ----------
    jd_utc1, jd_utc2:
        UTC two-part Julian date [day], scalars or arrays of N epochs.
    r_eme2000:
        EME2000 position [m], shape (3,) or (N, 3).
    v_eme2000:
        EME2000 velocity [m/s], shape (3,) or (N, 3).

    Returns
    -------
    (r_teme [m], v_teme [m/s]), the same shape as the inputs.

    Raises
    ------
    ValueError
        If ``r_eme2000`` or ``v_eme2000`` is not of shape (3,) or (N, 3).
    """
    r = _as_vectors("r_eme2000", r_eme2000)
    v = _as_vectors("v_eme2000", v_eme2000)
    matrix_t = np.swapaxes(teme_to_eme2000_matrix(jd_utc1, jd_utc2), -1, -2)
    return _rotate(matrix_t, r), _rotate(matrix_t, v)
