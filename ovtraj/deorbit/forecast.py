"""Ground-track forecast: where the preparation orbit's track passes the entry region.

The sub-satellite point is the geocentric latitude and longitude of the OV over a
spherical Earth rotating at ``omega`` (Earth-fixed longitude = inertial right
ascension minus the Earth rotation angle ``theta0 + omega t``). One propagation
under J2 covers the whole horizon with dense output; the track crosses the entry
latitude at the roots of ``z/|r| - sin(lat_E)``, which heyoka's event detection
finds inside its steps (no time grid). Near each crossing the track point nearest
the entry point (great-circle distance) is found by a bounded scalar minimisation
over a quarter of a revolution either side; that point is the pass's *virtual
entry point*. A pass goes through the region when its crossing of the entry
latitude lies in the box (the crossing is then a point of the track inside the
region) in the configured direction (an approach from the south-west needs a
northbound pass); only those passes are refined, the others keep their crossing.

A track whose highest latitude (the inclination, or its supplement) lies below the
entry latitude never crosses it: the forecast says so instead of searching.

Limitation: a pass counts when it crosses the entry point's latitude inside the
box. A track that clips a corner of the box without crossing that latitude there
(possible when the box reaches the orbit's highest latitude) is not counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from ovtraj.astro.elements import orbital_period
from ovtraj.astro.frames import ecef_to_geocentric, eci_to_ecef, great_circle_distance
from ovtraj.astro.propagation import LatitudeCrossing, OrbitPropagator, PropagationResult
from ovtraj.astro.vectors import cross
from ovtraj.deorbit.inputs import EntryRegion
from ovtraj.units import S_PER_HOUR


@dataclass(frozen=True)
class TrackPass:
    """One pass of the ground track by the entry point (times in s from the epoch)."""

    t_s: float  # virtual entry point: the track point nearest the entry point
    latitude_rad: float
    longitude_rad: float
    distance_m: float  # great-circle distance from the entry point, on the sphere R_E
    crossing_t_s: float  # when the track crosses the entry latitude
    crossing_longitude_rad: float
    northbound: bool
    in_region: bool  # the crossing lies in the box: the track passes through the region
    state: np.ndarray  # ECI state at t_s


@dataclass
class Forecast:
    passes: list[TrackPass]  # every crossing of the entry latitude, in time order
    trajectory: PropagationResult  # dense output over [0, horizon]
    reason: str | None = None  # why there is no pass, if there is none

    @property
    def in_region(self) -> list[TrackPass]:
        return [p for p in self.passes if p.in_region]


def subsatellite_point(
    state: np.ndarray, t_s: float | np.ndarray, earth_angle0_rad: float, omega: float, radius: float
) -> tuple[float | np.ndarray, float | np.ndarray]:
    """Geocentric latitude and longitude [rad] of ECI states at times ``t_s`` [s]."""
    state = np.asarray(state, dtype=float)
    theta = earth_angle0_rad + omega * np.asarray(t_s, dtype=float)
    lat, lon, _ = ecef_to_geocentric(eci_to_ecef(state[..., :3], theta), radius=radius)
    return lat, lon


def highest_latitude_rad(state: np.ndarray) -> float:
    """Highest geocentric latitude the orbit plane reaches [rad] (inclination or 180 - i)."""
    h = cross(state[:3], state[3:6])
    inclination = math.acos(max(-1.0, min(1.0, h[2] / float(np.linalg.norm(h)))))
    return min(inclination, math.pi - inclination)


def forecast_passes(
    propagator: OrbitPropagator,
    state0: np.ndarray,
    horizon_s: float,
    entry: EntryRegion,
    *,
    time_tolerance_s: float,
) -> Forecast:
    """Propagate over ``[0, horizon_s]`` and list the passes by the entry point."""
    reach = highest_latitude_rad(state0)
    result = propagator.propagate(
        state0,
        0.0,
        horizon_s,
        events=[LatitudeCrossing(entry.latitude_rad, "any")],
        dense=True,
    )
    if not result.ok:
        return Forecast([], result, f"forecast propagation failed: {result.message}")
    if abs(entry.latitude_rad) > reach:
        return Forecast(
            [],
            result,
            f"entry latitude {math.degrees(entry.latitude_rad):.3f} deg is beyond the "
            f"highest latitude of the orbit ({math.degrees(reach):.3f} deg, from its "
            "inclination): the ground track never crosses it",
        )
    r0 = float(np.linalg.norm(state0[:3]))
    period = float(orbital_period(r0, mu=propagator.earth.mu))
    track = _GroundTrack(propagator, result, entry)
    passes = []
    for hit, lat_c, lon_c, d_c in zip(result.hits, *track.crossings(), strict=True):
        lat_c, lon_c = float(lat_c), float(lon_c)
        northbound = bool(hit.state[5] > 0.0)
        through = entry.contains(lat_c, lon_c) and entry.accepts_direction(northbound)
        t_near, state, d_near, lat, lon = hit.t, hit.state, float(d_c), lat_c, lon_c
        if through:  # refine only the passes that matter: the others keep the crossing
            lo = max(0.0, hit.t - 0.25 * period)
            hi = min(horizon_s, hit.t + 0.25 * period)
            t_near, state, d_near, lat, lon = track.nearest(lo, hi, time_tolerance_s)
        passes.append(
            TrackPass(
                t_s=t_near,
                latitude_rad=float(lat),
                longitude_rad=float(lon),
                distance_m=d_near,
                crossing_t_s=hit.t,
                crossing_longitude_rad=lon_c,
                northbound=northbound,
                in_region=through,
                state=np.array(state, dtype=float),
            )
        )
    return Forecast(passes, result, _no_pass_reason(passes, entry, horizon_s))


class _GroundTrack:
    """The forecast's sub-satellite points and their great-circle distances to the entry
    point [m]."""

    def __init__(
        self, propagator: OrbitPropagator, result: PropagationResult, entry: EntryRegion
    ) -> None:
        self.ctx = propagator.context
        self.radius = propagator.earth.radius
        self.result = result
        self.entry = entry

    def point(self, state: np.ndarray, t: float | np.ndarray) -> tuple[Any, Any]:
        """Geocentric latitude and longitude [rad] of ``state`` at ``t`` [s]."""
        ctx = self.ctx
        return subsatellite_point(
            state, t, ctx.earth_angle0_rad, ctx.rotation_rate_rad_s, self.radius
        )

    def distance_to_entry(self, lat: Any, lon: Any) -> Any:
        entry = self.entry
        return great_circle_distance(
            lat, lon, entry.latitude_rad, entry.longitude_rad, radius=self.radius
        )

    def crossings(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude, longitude and distance of every crossing of the entry latitude.

        In one array call: a long horizon has ~100 crossings, and one-point calls were half
        the forecast's time."""
        hits = self.result.hits
        hit_states = np.array([hit.state for hit in hits]).reshape(-1, 6)
        hit_times = np.array([hit.t for hit in hits])
        lats_c, lons_c = self.point(hit_states, hit_times)
        distances_c = self.distance_to_entry(lats_c, lons_c)
        return np.atleast_1d(lats_c), np.atleast_1d(lons_c), np.atleast_1d(distances_c)

    def nearest(
        self, lo: float, hi: float, time_tolerance_s: float
    ) -> tuple[float, np.ndarray, float, Any, Any]:
        """The nearest approach to the entry point within ``[lo, hi]`` [s]: its time,
        state, distance [m] and sub-satellite point."""

        def distance(t: float) -> float:
            lat, lon = self.point(self.result.state_at(t), t)
            return float(self.distance_to_entry(lat, lon))

        best = minimize_scalar(
            distance, bounds=(lo, hi), method="bounded", options={"xatol": time_tolerance_s}
        )
        t_near, d_near = float(best.x), float(best.fun)
        state = self.result.state_at(t_near)
        lat, lon = self.point(state, t_near)
        return t_near, state, d_near, lat, lon


def _no_pass_reason(passes: list[TrackPass], entry: EntryRegion, horizon_s: float) -> str | None:
    """Why no pass is in the region (None when one is)."""
    if any(p.in_region for p in passes):
        return None
    return (
        f"no {entry.pass_direction} pass of the ground track crossing the entry latitude "
        "inside the entry region "
        f"within the {horizon_s / S_PER_HOUR:g} h horizon "
        f"({len(passes)} crossings of the entry latitude, nearest "
        f"{min((p.distance_m for p in passes), default=math.inf) / 1e3:.0f}"
        " km)"
    )
