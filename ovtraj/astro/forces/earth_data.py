"""The Earth orientation (IERS EOP) and space-weather (CelesTrak) tables heyoka ships.

heyoka 7.13 bundles IERS ``finals2000A.all`` (UT1-UTC, polar motion, celestial pole
offsets) and CelesTrak's ``SW-All.csv`` (daily Ap, F10.7 and its 81-day centred mean).
Its expressions interpolate them linearly by day and give NaN outside the tables, so a
flight beyond their last day must be caught before it is flown:

* :func:`earth_orientation_data`: the bundled EOP, with the last day's values held for
  ``extrapolation_days`` more days (a mission is planned weeks ahead of the data; the
  held UT1-UTC drifts from the truth by at most ~2 ms a day, IERS Bulletin A);
* :func:`space_weather_span`: the days the bundled space weather covers, which a flight
  under the ``bundled`` source must lie within.
"""

from __future__ import annotations

from functools import lru_cache

import heyoka as hy
import numpy as np

from ovtraj.units import JD_MINUS_MJD

__all__ = ["earth_orientation_data", "earth_orientation_span", "space_weather_span"]


@lru_cache(maxsize=4)
def earth_orientation_data(extrapolation_days: float) -> hy.eop_data:
    """The bundled EOP, its last row repeated daily for ``extrapolation_days`` [day]."""
    bundled = hy.eop_data()
    table = np.array(bundled.table)
    extra_days = int(np.floor(extrapolation_days))
    if extra_days <= 0:
        return bundled
    last = table[-1]
    extra = np.repeat(last[None], extra_days)
    extra["mjd"] = last["mjd"] + np.arange(1, extra_days + 1, dtype=float)
    return hy.eop_data(
        data=np.concatenate([table, extra]),
        timestamp=f"{bundled.timestamp}+held{extra_days}d",
        identifier=f"ovtraj_held_{bundled.identifier}",
    )


def earth_orientation_span(extrapolation_days: float) -> tuple[float, float]:
    """First and last JD (UTC) [day] :func:`earth_orientation_data` covers."""
    mjd = np.asarray(earth_orientation_data(extrapolation_days).table["mjd"])
    return float(mjd[0] + JD_MINUS_MJD), float(mjd[-1] + JD_MINUS_MJD)


@lru_cache(maxsize=1)
def space_weather_span() -> tuple[float, float]:
    """First and last JD (UTC) [day] of the bundled space weather."""
    mjd = np.asarray(hy.sw_data().table["mjd"])
    return float(mjd[0] + JD_MINUS_MJD), float(mjd[-1] + JD_MINUS_MJD)
