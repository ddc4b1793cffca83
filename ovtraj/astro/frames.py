"""Reference frames: ECI <-> Earth-fixed, geocentric coordinates, local frames.

* ECI: Earth-centred inertial, equator and equinox of date (SPEC). The
  Earth-fixed frame (ECEF) is the ECI frame rotated about z by the Earth
  rotation angle theta (GMST, see :mod:`ovtraj.astro.epoch`); precession,
  nutation and polar motion are neglected.
* Geocentric coordinates use a **spherical Earth** of radius ``radius``
  (SPEC): altitude = |r| - radius, latitude is the geocentric latitude.
* Local frames: RSW (radial, along-track, cross-track; Vallado sec. 3.3) and
  north/east/up.

All functions take arrays of shape (..., 3) (or (...) for angles) and
broadcast over the leading axes; scalars and single vectors work too.
Angles in rad, lengths in m, speeds in m/s.

References
----------
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed.,
2013: sec. 3.3 (RSW frame), sec. 3.4 (ROT3 rotation), sec. 3.7 (velocity
through the Earth rotation, v_ECI = ROT3(-theta) (v_PEF + omega x r_PEF)),
eq. 2-98 (flight-path angle).
Curtis, H. D., *Orbital Mechanics for Engineering Students*, 3rd ed., 2014:
sec. 1.5-1.6 (time derivatives in a rotating frame, relative motion),
sec. 2.5 (flight-path angle).
Sinnott, R. W., "Virtues of the Haversine", *Sky and Telescope* 68 (2), 1984.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.astro.vectors import cross

__all__ = [
    "ecef_to_eci",
    "ecef_to_eci_state",
    "ecef_to_geocentric",
    "eci_to_ecef",
    "eci_to_ecef_state",
    "eci_to_rsw",
    "flight_path_angle",
    "geocentric_to_ecef",
    "great_circle_distance",
    "heading",
    "local_north_east_up",
    "relative_velocity_state",
    "rsw_basis",
    "rsw_to_eci",
    "spherical_to_ecef_state",
]


def _scalar_or_array(value: np.ndarray) -> float | np.ndarray:
    return float(value) if np.ndim(value) == 0 else value


def _vectors(x: ArrayLike) -> np.ndarray:
    array = np.asarray(x, dtype=float)
    if array.ndim == 0 or array.shape[-1] != 3:
        raise ValueError(f"expected vectors of shape (..., 3), got shape {array.shape}")
    return array


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _rotate_about_z(vec: np.ndarray, angle: ArrayLike) -> np.ndarray:
    """Components of ``vec`` in axes turned by ``angle`` about z (Vallado ROT3, sec. 3.4)."""
    if vec.shape == (3,) and np.ndim(angle) == 0:
        # One vector: scalar arithmetic, a tenth of the broadcasting path's cost (the
        # ground-track searches call this thousands of times per mission evaluation).
        cos_s, sin_s = math.cos(angle), math.sin(angle)
        x_s, y_s = float(vec[0]), float(vec[1])
        return np.array([cos_s * x_s + sin_s * y_s, -sin_s * x_s + cos_s * y_s, float(vec[2])])
    cos_a, sin_a = np.cos(angle), np.sin(angle)
    x, y, z = vec[..., 0], vec[..., 1], vec[..., 2]
    x_new = cos_a * x + sin_a * y
    y_new = -sin_a * x + cos_a * y
    x_new, y_new, z = np.broadcast_arrays(x_new, y_new, z)
    return np.stack([x_new, y_new, z], axis=-1)


def _omega_cross(omega: float, r: np.ndarray) -> np.ndarray:
    """omega_vec x r for a rotation of rate ``omega`` about z."""
    return np.stack([-omega * r[..., 1], omega * r[..., 0], np.zeros_like(r[..., 2])], axis=-1)


def eci_to_ecef(r_eci: ArrayLike, theta: ArrayLike) -> np.ndarray:
    """Earth-fixed components of an ECI vector.

    Parameters
    ----------
    r_eci:
        Vector(s) in ECI axes, shape (..., 3), any unit.
    theta:
        Earth rotation angle (GMST) [rad], broadcast against ``r_eci[..., 0]``.

    Returns
    -------
    ROT3(theta) r_eci, shape (..., 3) (Vallado sec. 3.4).
    """
    return _rotate_about_z(_vectors(r_eci), theta)


def ecef_to_eci(r_ecef: ArrayLike, theta: ArrayLike) -> np.ndarray:
    """ECI components of an Earth-fixed vector, ROT3(-theta) r_ecef.

    Inverse of :func:`eci_to_ecef`; same shapes and units.
    """
    return _rotate_about_z(_vectors(r_ecef), -np.asarray(theta, dtype=float))


def eci_to_ecef_state(
    r: ArrayLike, v: ArrayLike, theta: ArrayLike, *, omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """Earth-fixed position and velocity from an ECI state.

    The Earth-fixed velocity is the time derivative seen from the rotating
    frame, v_ecef = ROT3(theta) (v - omega_vec x r) (Vallado sec. 3.7 with
    precession, nutation and polar motion dropped; Curtis sec. 1.5).

    Parameters
    ----------
    r, v:
        ECI position [m] and velocity [m/s], shape (..., 3).
    theta:
        Earth rotation angle [rad].
    omega:
        Earth rotation rate [rad/s].

    Returns
    -------
    (r_ecef [m], v_ecef [m/s]).
    """
    r, v = _vectors(r), _vectors(v)
    return eci_to_ecef(r, theta), eci_to_ecef(v - _omega_cross(omega, r), theta)


def ecef_to_eci_state(
    r_ecef: ArrayLike, v_ecef: ArrayLike, theta: ArrayLike, *, omega: float
) -> tuple[np.ndarray, np.ndarray]:
    """ECI position and velocity from an Earth-fixed state (inverse of :func:`eci_to_ecef_state`).

    v_eci = ROT3(-theta) v_ecef + omega_vec x r_eci.

    Parameters
    ----------
    r_ecef, v_ecef:
        Earth-fixed position [m] and velocity relative to the Earth [m/s].
    theta:
        Earth rotation angle [rad].
    omega:
        Earth rotation rate [rad/s].

    Returns
    -------
    (r_eci [m], v_eci [m/s]).
    """
    r_eci = ecef_to_eci(r_ecef, theta)
    return r_eci, ecef_to_eci(v_ecef, theta) + _omega_cross(omega, r_eci)


def relative_velocity_state(r_eci: ArrayLike, v_eci: ArrayLike, *, omega: float) -> np.ndarray:
    """Velocity relative to the rotating Earth, expressed in ECI axes [m/s].

    v_rel = v - omega_vec x r (Curtis sec. 1.6). This is the velocity that
    drives aerodynamics and that :func:`heading` and :func:`flight_path_angle`
    describe in the reentry phase.
    """
    r_eci, v_eci = _vectors(r_eci), _vectors(v_eci)
    return v_eci - _omega_cross(omega, r_eci)


def ecef_to_geocentric(
    r_ecef: ArrayLike, *, radius: float
) -> tuple[float | np.ndarray, float | np.ndarray, float | np.ndarray]:
    """Geocentric latitude, longitude and altitude over a spherical Earth.

    Parameters
    ----------
    r_ecef:
        Earth-fixed position [m], shape (..., 3).
    radius:
        Spherical Earth radius [m].

    Returns
    -------
    (lat [rad] in [-pi/2, pi/2], lon [rad] in (-pi, pi], alt = |r| - radius [m]).
    The latitude equals asin(z / |r|); it is computed as atan2(z, rho), which
    keeps full precision near the poles.
    """
    r_ecef = _vectors(r_ecef)
    if r_ecef.shape == (3,):  # one position: scalar arithmetic (see _rotate_about_z)
        x_s, y_s, z_s = (float(c) for c in r_ecef)
        lon_s = math.atan2(y_s, x_s)
        return (
            math.atan2(z_s, math.hypot(x_s, y_s)),
            math.pi if lon_s == -math.pi else lon_s,
            math.sqrt(x_s * x_s + y_s * y_s + z_s * z_s) - radius,
        )
    x, y, z = r_ecef[..., 0], r_ecef[..., 1], r_ecef[..., 2]
    lat = np.arctan2(z, np.hypot(x, y))
    lon = np.arctan2(y, x)
    # atan2 gives -pi for y = -0.0; the convention is the half-open (-pi, pi].
    lon = np.where(lon == -np.pi, np.pi, lon)
    alt = np.linalg.norm(r_ecef, axis=-1) - radius
    return _scalar_or_array(lat), _scalar_or_array(lon), _scalar_or_array(alt)


def geocentric_to_ecef(
    lat: ArrayLike, lon: ArrayLike, alt: ArrayLike, *, radius: float
) -> np.ndarray:
    """Earth-fixed position [m] of geocentric latitude, longitude [rad] and altitude [m].

    Spherical Earth: r = (radius + alt) * (cos lat cos lon, cos lat sin lon, sin lat).
    Inputs broadcast together; the result has shape (..., 3).
    """
    lat, lon = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    r = radius + np.asarray(alt, dtype=float)
    x, y, z = np.broadcast_arrays(
        r * np.cos(lat) * np.cos(lon), r * np.cos(lat) * np.sin(lon), r * np.sin(lat)
    )
    return np.stack([x, y, z], axis=-1)


def local_north_east_up(lat: ArrayLike, lon: ArrayLike) -> np.ndarray:
    """Local north, east and up unit vectors in Earth-fixed axes.

    Parameters
    ----------
    lat, lon:
        Geocentric latitude and longitude [rad] (spherical Earth), broadcast.

    Returns
    -------
    Array of shape (..., 3, 3) whose rows are N, E, U. Note that (N, E, U) in
    this order is a left-handed triad (N x E = -U); use (E, N, U) or
    (N, E, -U) = NED where a right-handed basis is needed.
    """
    lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=float), np.asarray(lon, dtype=float))
    sin_lat, cos_lat = np.sin(lat), np.cos(lat)
    sin_lon, cos_lon = np.sin(lon), np.cos(lon)
    north = np.stack([-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat], axis=-1)
    east = np.stack([-sin_lon, cos_lon, np.zeros_like(lon)], axis=-1)
    up = np.stack([cos_lat * cos_lon, cos_lat * sin_lon, sin_lat], axis=-1)
    return np.stack([north, east, up], axis=-2)


def spherical_to_ecef_state(
    lat: ArrayLike,
    lon: ArrayLike,
    alt: ArrayLike,
    speed: ArrayLike,
    fpa: ArrayLike,
    heading_angle: ArrayLike,
    *,
    radius: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Earth-fixed position [m] and Earth-relative velocity [m/s] of an entry state.

    The spherical state of the atmospheric phases (Vinh, Busemann & Culp, *Hypersonic
    and Planetary Entry Flight Mechanics*, 1980, ch. 2): geocentric latitude and
    longitude [rad], altitude over the sphere [m], speed relative to the Earth [m/s],
    flight-path angle above the local horizontal and heading clockwise from north
    [rad]. The velocity is ``V (cos(gamma) (cos(psi) N + sin(psi) E) + sin(gamma) U)``
    in the local north/east/up axes (:func:`local_north_east_up`). Inverse of
    :func:`ecef_to_geocentric`, :func:`flight_path_angle` and :func:`heading` on the
    Earth-relative velocity; inputs broadcast, results have shape (..., 3).
    """
    basis = local_north_east_up(lat, lon)
    speed, fpa = np.asarray(speed, dtype=float), np.asarray(fpa, dtype=float)
    psi = np.asarray(heading_angle, dtype=float)
    horizontal = speed * np.cos(fpa)
    components = np.stack(
        np.broadcast_arrays(
            horizontal * np.cos(psi), horizontal * np.sin(psi), speed * np.sin(fpa)
        ),
        axis=-1,
    )
    velocity = np.einsum("...i,...ij->...j", components, basis)
    return geocentric_to_ecef(lat, lon, alt, radius=radius), velocity


def rsw_basis(r: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Unit vectors of the RSW frame (Vallado sec. 3.3), in the axes of ``r`` and ``v``.

    R = r / |r| (radial), W = h / |h| with h = r x v (cross-track, orbit
    normal), S = W x R (along-track, completes the right-handed triad).

    Parameters
    ----------
    r, v:
        Position [m] and velocity [m/s], shape (..., 3).

    Returns
    -------
    Array of shape (..., 3, 3) whose rows are R, S, W.

    Raises
    ------
    ValueError
        If r x v = 0 somewhere (rectilinear motion: no orbit plane).
    """
    r, v = _vectors(r), _vectors(v)
    if r.shape == (3,) and v.shape == (3,):
        return _rsw_basis_single(r, v)
    h = cross(r, v)
    if np.any(np.linalg.norm(h, axis=-1) == 0.0):
        raise ValueError("RSW frame undefined: r x v = 0 (rectilinear motion or zero vector)")
    radial = _unit(r)
    cross_track = _unit(h)
    along_track = cross(cross_track, radial)
    radial, along_track, cross_track = np.broadcast_arrays(radial, along_track, cross_track)
    return np.stack([radial, along_track, cross_track], axis=-2)


def _rsw_basis_single(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:func:`rsw_basis` of one state on scalars (a fifth of the broadcasting path's
    cost: the deorbit correction builds one per shot, ~50 per mission evaluation)."""
    rx, ry, rz = r.tolist()
    vx, vy, vz = v.tolist()
    hx, hy, hz = ry * vz - rz * vy, rz * vx - rx * vz, rx * vy - ry * vx
    h_norm = math.sqrt(hx * hx + hy * hy + hz * hz)
    if h_norm == 0.0:
        raise ValueError("RSW frame undefined: r x v = 0 (rectilinear motion or zero vector)")
    r_norm = math.sqrt(rx * rx + ry * ry + rz * rz)
    rx, ry, rz = rx / r_norm, ry / r_norm, rz / r_norm
    wx, wy, wz = hx / h_norm, hy / h_norm, hz / h_norm
    return np.array(
        [[rx, ry, rz], [wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx], [wx, wy, wz]]
    )


def eci_to_rsw(vec: ArrayLike, r: ArrayLike, v: ArrayLike) -> np.ndarray:
    """RSW components of ``vec`` (given in the axes of ``r``, ``v``), shape (..., 3)."""
    return np.einsum("...ij,...j->...i", rsw_basis(r, v), _vectors(vec))


def rsw_to_eci(vec_rsw: ArrayLike, r: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Components in the axes of ``r`` and ``v`` of a vector given in RSW.

    Inverse of :func:`eci_to_rsw`; shape (..., 3).
    """
    return np.einsum("...ji,...j->...i", rsw_basis(r, v), _vectors(vec_rsw))


def flight_path_angle(r: ArrayLike, v: ArrayLike) -> float | np.ndarray:
    """Angle of the velocity above the local horizontal [rad], in [-pi/2, pi/2].

    gamma = asin(r . v / (|r| |v|)) (Vallado eq. 2-98 geometry, Curtis
    sec. 2.5), evaluated as atan2(r . v, |r x v|), which is exact near
    +-pi/2. Pass the Earth-relative velocity for the reentry (relative)
    flight-path angle, the inertial one for the orbital angle.
    """
    r, v = _vectors(r), _vectors(v)
    if r.shape == (3,) and v.shape == (3,):  # one state: scalar arithmetic
        rx, ry, rz = r.tolist()
        vx, vy, vz = v.tolist()
        hx, hy, hz = ry * vz - rz * vy, rz * vx - rx * vz, rx * vy - ry * vx
        return math.atan2(rx * vx + ry * vy + rz * vz, math.sqrt(hx * hx + hy * hy + hz * hz))
    return _scalar_or_array(np.arctan2(_dot(r, v), np.linalg.norm(cross(r, v), axis=-1)))


def heading(r_eci: ArrayLike, v_rel_eci: ArrayLike) -> float | np.ndarray:
    """Heading (azimuth) of the horizontal velocity, clockwise from local north [rad].

    East is +pi/2. The local north and east are those of the geocentric
    latitude and longitude of ``r_eci`` over a spherical Earth; they only
    depend on the z axis being the Earth's axis, so ``r`` and ``v`` may be
    given in ECI or in Earth-fixed axes (both the same). At the poles,
    where north is undefined, the longitude convention atan2(0, 0) = 0 is
    used.

    Parameters
    ----------
    r_eci:
        Position [m], shape (..., 3).
    v_rel_eci:
        Velocity relative to the Earth in the same axes [m/s]
        (see :func:`relative_velocity_state`).

    Returns
    -------
    psi [rad] in [0, 2pi).
    """
    r_eci, v_rel_eci = _vectors(r_eci), _vectors(v_rel_eci)
    lat = np.arctan2(r_eci[..., 2], np.hypot(r_eci[..., 0], r_eci[..., 1]))
    lon = np.arctan2(r_eci[..., 1], r_eci[..., 0])
    basis = local_north_east_up(lat, lon)
    v_north = _dot(basis[..., 0, :], v_rel_eci)
    v_east = _dot(basis[..., 1, :], v_rel_eci)
    return _scalar_or_array(wrap_to_two_pi(np.arctan2(v_east, v_north)))


def great_circle_distance(
    lat1: ArrayLike, lon1: ArrayLike, lat2: ArrayLike, lon2: ArrayLike, *, radius: float
) -> float | np.ndarray:
    """Great-circle distance [m] between two points on a sphere (haversine; Sinnott 1984).

    Parameters
    ----------
    lat1, lon1, lat2, lon2:
        Geocentric latitudes and longitudes [rad], broadcast together.
    radius:
        Sphere radius [m].
    """
    if all(isinstance(a, (float, int)) for a in (lat1, lon1, lat2, lon2)):
        # Four numbers: scalar arithmetic (see _rotate_about_z).
        half_sum = (
            math.sin((lat2 - lat1) / 2.0) ** 2
            + math.cos(lat1) * math.cos(lat2) * math.sin((lon2 - lon1) / 2.0) ** 2
        )
        return 2.0 * radius * math.asin(math.sqrt(min(max(half_sum, 0.0), 1.0)))
    lat1, lon1, lat2, lon2 = (np.asarray(a, dtype=float) for a in (lat1, lon1, lat2, lon2))
    haversine = (
        np.sin((lat2 - lat1) / 2.0) ** 2
        + np.cos(lat1) * np.cos(lat2) * np.sin((lon2 - lon1) / 2.0) ** 2
    )
    # Rounding can push the haversine a hair past 1 for antipodal points.
    return _scalar_or_array(2.0 * radius * np.arcsin(np.sqrt(np.clip(haversine, 0.0, 1.0))))
