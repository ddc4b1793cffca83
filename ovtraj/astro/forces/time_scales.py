"""Time arguments of the force model: TT Julian centuries since J2000 and the day of year.

heyoka's Earth-orientation, space-weather and ephemeris expressions take the time as TT
Julian centuries since J2000.0 (JD 2451545.0 TT); the thermospheric models take the UTC
day of the year. Both are the origin's value (a runtime parameter, so one compiled
integrator serves every epoch) plus the integration time ``t`` [s]. UTC -> TAI -> TT by
ERFA (``eraUtctai`` holds the leap seconds, ``eraTaitt`` adds 32.184 s).
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import erfa

from ovtraj.astro.epoch import Epoch
from ovtraj.units import DAYS_PER_JULIAN_CENTURY, J2000_JD, S_PER_DAY, S_PER_JULIAN_CENTURY

__all__ = [
    "day_of_year",
    "tt_centuries",
    "tt_centuries_expression",
]


def tt_centuries(epoch: Epoch) -> float:
    """TT Julian centuries since J2000.0 of a UTC epoch."""
    tai1, tai2 = erfa.utctai(epoch.jd1, epoch.jd2)
    tt1, tt2 = erfa.taitt(tai1, tai2)
    return float(((tt1 - J2000_JD) + tt2) / DAYS_PER_JULIAN_CENTURY)


def day_of_year(epoch: Epoch) -> float:
    """Days [day] from 1 January 00:00 UTC of the epoch's year (0 on 1 January at midnight)."""
    moment = epoch.to_datetime()
    start = datetime(moment.year, 1, 1, tzinfo=UTC)
    return (moment - start).total_seconds() / S_PER_DAY


def tt_centuries_expression(origin_tt: Any, time: Any) -> Any:
    """TT centuries at ``time`` [s] after an origin of ``origin_tt`` centuries (expressions)."""
    return origin_tt + time / S_PER_JULIAN_CENTURY
