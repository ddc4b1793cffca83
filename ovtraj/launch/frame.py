"""The launch frame: Earth-fixed, centred on the ground point below the drop.

Axes (the launch coordinate system of Chinese launch-vehicle practice, patent
step 101): ``x`` horizontal along the launch azimuth ``A`` (from north,
clockwise), ``y`` up along the geocentric vertical (spherical Earth), ``z = x × y``
(to the right of the downrange direction). The frame turns with the Earth, so
the equations of motion in it carry the transport (centrifugal) and Coriolis
terms; the geocentric position of a point is ``R0 + r`` with ``R0 = (0, R_E, 0)``.

In Earth-fixed axes, with the local north ``N``, east ``E`` and up ``U`` unit vectors
at the drop point (:func:`ovtraj.astro.frames.local_north_east_up`)::

    x = cos A N + sin A E,   y = U,   z = cos A E - sin A N

so the Earth's rotation vector has launch-frame components
``omega (cos A cos phi, sin phi, -sin A cos phi)`` (phi the geocentric latitude).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ovtraj.astro.frames import local_north_east_up


def launch_frame_axes(latitude_rad: float, longitude_rad: float, azimuth_rad: ArrayLike) -> NDArray:
    """Rows ``x, y, z`` of the launch frame in Earth-fixed axes, shape ``(..., 3, 3)``."""
    north, east, up = local_north_east_up(latitude_rad, longitude_rad)
    az = np.asarray(azimuth_rad, dtype=float)[..., None]
    x = np.cos(az) * north + np.sin(az) * east
    z = np.cos(az) * east - np.sin(az) * north
    y = np.broadcast_to(up, x.shape)
    return np.stack([x, y, z], axis=-2)


def earth_rate_in_launch_frame(
    latitude_rad: float, azimuth_rad: ArrayLike, omega_rad_s: float
) -> NDArray:
    """Earth rotation vector [rad/s] in launch-frame components, shape ``(..., 3)``."""
    az = np.asarray(azimuth_rad, dtype=float)
    c = np.cos(latitude_rad)
    return omega_rad_s * np.stack(
        [np.cos(az) * c, np.full(az.shape, np.sin(latitude_rad)), -np.sin(az) * c], axis=-1
    )


def launch_to_ecef(
    position: ArrayLike,
    velocity: ArrayLike,
    axes: ArrayLike,
    *,
    radius_m: float,
) -> tuple[NDArray, NDArray]:
    """Earth-fixed position [m] and Earth-relative velocity [m/s] of a launch-frame state.

    ``position`` is relative to the frame origin on the sphere; ``axes`` from
    :func:`launch_frame_axes` (matching leading shape, or one frame for all).
    """
    r = np.asarray(position, dtype=float).copy()
    r[..., 1] += radius_m
    axes = np.asarray(axes, dtype=float)
    r_ecef = np.einsum("...ij,...i->...j", axes, r)
    v_ecef = np.einsum("...ij,...i->...j", axes, np.asarray(velocity, dtype=float))
    return r_ecef, v_ecef


def ecef_to_launch(
    r_ecef: ArrayLike, v_ecef: ArrayLike, axes: ArrayLike, *, radius_m: float
) -> tuple[NDArray, NDArray]:
    """Inverse of :func:`launch_to_ecef`."""
    axes = np.asarray(axes, dtype=float)
    r = np.einsum("...ij,...j->...i", axes, np.asarray(r_ecef, dtype=float))
    v = np.einsum("...ij,...j->...i", axes, np.asarray(v_ecef, dtype=float))
    r[..., 1] -= radius_m
    return r, v
