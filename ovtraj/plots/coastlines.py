"""Coastlines for the ground-track map, and the +-180 deg longitude wrap of map lines.

The coastlines are Natural Earth's 1:110m land boundaries (Natural Earth 4.1.0, public
domain, https://www.naturalearthdata.com/), as redistributed in TopoJSON by the npm
package ``world-atlas`` 2.0.2 (``land-110m.json``; packaging ISC, M. Bostock). They ship
with ovtraj as ``coastlines_110m.json`` in the reference data (``ovtraj.paths.reference_dir``;
``data/reference/`` in a checkout, ``ovtraj/reference/`` in the wheel), converted once by
``tools/make_coastlines.py``: nothing is downloaded at run time.

The file holds polylines of longitude east [deg, -180..180] and geodetic latitude [deg];
the antimeridian cut edges of the source polygons are left out and no polyline jumps
across +-180 deg. The ground track's latitude is geocentric (spherical Earth): the
difference, at most 0.19 deg, is below this map's resolution.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from ovtraj.paths import reference_dir

__all__ = [
    "COASTLINE_FILE",
    "Coastlines",
    "draw_coastlines",
    "load_coastlines",
    "split_at_wrap",
    "with_breaks",
]

COASTLINE_FILE = "coastlines_110m.json"
FORMAT = "ovtraj.coastlines/1"


@dataclass(frozen=True)
class Coastlines:
    """Polylines (longitude, latitude) [deg] and the file's header (source, licence, ...)."""

    polylines: tuple[tuple[np.ndarray, np.ndarray], ...]
    header: dict[str, Any]

    @property
    def points(self) -> int:
        return sum(len(lon) for lon, _ in self.polylines)


@functools.lru_cache(maxsize=1)
def load_coastlines() -> Coastlines:
    """The shipped coastlines (read once per process; the arrays are read only)."""
    path = reference_dir() / COASTLINE_FILE
    data = json.loads(path.read_text(encoding="utf-8"))
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: not an {FORMAT} file (format {data.get('format')!r})")
    lines = []
    for line in data["polylines"]:
        lon = np.array(line["lon"], dtype=float)
        lat = np.array(line["lat"], dtype=float)
        lon.flags.writeable = lat.flags.writeable = False
        lines.append((lon, lat))
    header = {key: value for key, value in data.items() if key != "polylines"}
    return Coastlines(tuple(lines), header)


def split_at_wrap(lon: np.ndarray, lat: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """A line of longitude [deg, -180..180] and latitude [deg] cut where it wraps.

    Wherever two consecutive points are more than 180 deg of longitude apart the line
    crosses the antimeridian: it is cut there, the first piece ending on its side's edge
    (+180 or -180) and the next starting on the other edge, both at the latitude
    interpolated linearly at the crossing. NaN points also cut the line. Pieces with
    fewer than two distinct points are dropped.
    """
    lon = np.asarray(lon, dtype=float)
    lat = np.asarray(lat, dtype=float)
    if lon.shape != lat.shape or lon.ndim != 1:
        raise ValueError(f"lon and lat must be 1-D of one length, got {lon.shape}, {lat.shape}")
    pieces: list[tuple[np.ndarray, np.ndarray]] = []
    run_lon: list[float] = []
    run_lat: list[float] = []

    def close() -> None:
        if len(run_lon) >= 2 and (np.ptp(run_lon) > 0.0 or np.ptp(run_lat) > 0.0):
            pieces.append((np.array(run_lon), np.array(run_lat)))
        run_lon.clear()
        run_lat.clear()

    for k in range(len(lon)):
        x, y = lon[k], lat[k]
        if not (np.isfinite(x) and np.isfinite(y)):
            close()
            continue
        if run_lon and abs(x - run_lon[-1]) > 180.0:
            x0, y0 = run_lon[-1], run_lat[-1]
            edge = 180.0 if x0 > x else -180.0  # eastward across +180 or westward across -180
            unwrapped = x + 2.0 * edge
            y_edge = y0 + (edge - x0) / (unwrapped - x0) * (y - y0)
            run_lon.append(edge)
            run_lat.append(y_edge)
            close()
            run_lon.append(-edge)
            run_lat.append(y_edge)
        run_lon.append(x)
        run_lat.append(y)
    close()
    return pieces


def with_breaks(pieces: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Pieces joined into one (longitude, latitude) pair with NaN between them (one plot call)."""
    if not pieces:
        return np.empty(0), np.empty(0)
    gap = np.array([np.nan])
    lon = np.concatenate([part for x, _ in pieces for part in (x, gap)][:-1])
    lat = np.concatenate([part for _, y in pieces for part in (y, gap)][:-1])
    return lon, lat


def draw_coastlines(ax: Any, centre: float = 0.0, **style: Any) -> None:
    """The shipped coastlines on a longitude-latitude axes, thin grey under everything.

    ``centre`` [deg]: the map's central longitude; the lines are drawn in
    ``[centre - 180, centre + 180]`` and cut at its edges.
    """
    coast = load_coastlines()
    pieces = [
        (x + centre, y)
        for lon, lat in coast.polylines
        for x, y in split_at_wrap((lon - centre + 180.0) % 360.0 - 180.0, lat)
    ]
    lon, lat = with_breaks(pieces)
    options = {"color": "0.55", "lw": 0.6, "zorder": 1.0}
    options.update(style)
    ax.plot(lon, lat, **options)
