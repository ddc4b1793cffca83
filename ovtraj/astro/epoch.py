"""UTC epochs, Julian dates and Greenwich mean sidereal time.

Time scale: every epoch is a UTC instant and UT1 = UTC is accepted (SPEC,
"Conventions"); the difference (< 0.9 s) moves the Earth by < 0.004 deg.
Leap seconds are ignored: a day is always 86400 s, so ``plus_seconds`` and
``seconds_since`` count uniform UTC-based seconds, exactly like
:mod:`datetime`. Across a leap second the true elapsed SI time differs by 1 s
from what these functions return.

An :class:`Epoch` holds a two-part Julian date (``jd1`` = the Julian date of
the preceding 0 h UTC, ``jd2`` = the fraction of the day in [0, 1)) so that
instants a century apart are still resolved to about 10 ps; a single float
Julian date only resolves about 40 microseconds.

References
----------
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed.,
Microcosm Press, 2013: Algorithm 14 (Julian date), eq. 3-42 (Julian
centuries), eq. 3-47 (IAU-82 GMST).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
from numpy.typing import ArrayLike

from ovtraj.astro.angles import TWO_PI, wrap_to_two_pi
from ovtraj.units import DAYS_PER_JULIAN_CENTURY, J2000_JD, S_PER_DAY, S_PER_HOUR

__all__ = [
    "Epoch",
    "earth_rotation_angle",
    "gmst_rad",
    "julian_date",
]

# IAU-82 GMST polynomial in T_UT1, result in seconds of time (Vallado eq. 3-47):
#   GMST = 67310.54841 + (876600 h + 8640184.812866) T + 0.093104 T^2 - 6.2e-6 T^3
# The 876600 h = 36525 days part of the T coefficient is a whole number of
# turns per day; it is applied through the day fraction of the Julian date
# (see gmst_rad) instead of as a ~3e9 s product that would lose precision.
_IAU82_GMST_S0 = 67310.54841
_IAU82_GMST_S1_EXCESS = 8640184.812866
_IAU82_GMST_S2 = 0.093104
_IAU82_GMST_S3 = -6.2e-6

# Algorithm 14 ignores the Gregorian century rule, so it is right only between
# 1900 March 1 and 2100 February 28 (Vallado, remark after Alg. 14).
_JULIAN_DATE_FIRST_VALID = (1900, 3, 1)
_JULIAN_DATE_LAST_VALID = (2100, 2, 28)
# Additive constant of Algorithm 14 (Julian date of the calendar's origin).
_ALG14_JD_OFFSET = 1721013.5

# 0 h UTC of 2000-01-01; anchor of the Julian date <-> datetime conversion.
_JD_2000_MIDNIGHT = J2000_JD - 0.5
_DATETIME_2000_MIDNIGHT = datetime(2000, 1, 1, tzinfo=UTC)

_ISO_FORMAT_HINT = (
    "ISO 8601 date-time, e.g. '2026-03-01T12:00:00Z', '2026-03-01T14:00:00+02:00' "
    "or '2026-03-01T12:00:00' (naive = UTC)"
)


def _date_key(year: ArrayLike, month: ArrayLike, day: ArrayLike) -> np.ndarray:
    """yyyymmdd as one integer, so that calendar dates compare in order."""
    return (np.asarray(year) * 100 + np.asarray(month)) * 100 + np.asarray(day)


def _as_float_or_array(value: np.ndarray) -> float | np.ndarray:
    return float(value) if np.ndim(value) == 0 else value


def julian_date(
    year: ArrayLike,
    month: ArrayLike,
    day: ArrayLike,
    hour: ArrayLike = 0,
    minute: ArrayLike = 0,
    second: ArrayLike = 0.0,
) -> tuple[float | np.ndarray, float | np.ndarray]:
    """Two-part Julian date of a calendar date and time (Vallado Alg. 14).

    Parameters
    ----------
    year, month, day:
        Gregorian calendar date; valid from 1900-03-01 to 2100-02-28.
    hour, minute, second:
        Time of day [h], [min], [s]; values past 24 h / 60 min / 60 s simply
        carry into the day fraction.

    Returns
    -------
    (jd_day, day_fraction):
        ``jd_day`` is the Julian date of 0 h of the given day [day] (it ends
        in .5), ``day_fraction`` the time of day as a fraction of a day. Their
        sum is Vallado's JD; keeping them apart keeps sub-microsecond precision.

    Raises
    ------
    ValueError
        If the month is not 1..12, the day not 1..31, or the date is outside
        the range in which Algorithm 14 is exact.
    """
    year_a, month_a, day_a = (np.asarray(x) for x in (year, month, day))
    if np.any((month_a < 1) | (month_a > 12)) or np.any((day_a < 1) | (day_a > 31)):
        raise ValueError(f"invalid calendar date: year={year}, month={month}, day={day}")
    date_key = _date_key(year_a, month_a, day_a)
    if np.any(
        (date_key < _date_key(*_JULIAN_DATE_FIRST_VALID))
        | (date_key > _date_key(*_JULIAN_DATE_LAST_VALID))
    ):
        raise ValueError(
            f"date {year}-{month}-{day} is outside the validity of Vallado Alg. 14 "
            f"(1900-03-01 to 2100-02-28)"
        )
    # Vallado's INT() truncates toward zero; all arguments are positive here.
    jd_day = (
        367.0 * year_a
        - np.trunc(7.0 * (year_a + np.trunc((month_a + 9.0) / 12.0)) / 4.0)
        + np.trunc(275.0 * month_a / 9.0)
        + day_a
        + _ALG14_JD_OFFSET
    )
    day_fraction = (
        (np.asarray(second, dtype=float) / 60.0 + np.asarray(minute, dtype=float)) / 60.0
        + np.asarray(hour, dtype=float)
    ) / 24.0
    jd_day, day_fraction = np.broadcast_arrays(jd_day, day_fraction)
    return _as_float_or_array(jd_day.astype(float)), _as_float_or_array(day_fraction)


def gmst_rad(jd1: ArrayLike, jd2: ArrayLike = 0.0) -> float | np.ndarray:
    """Greenwich mean sidereal time, IAU-82 (Vallado eq. 3-47).

    Parameters
    ----------
    jd1, jd2:
        Two-part Julian date (UT1, here taken equal to UTC) [day]; only the
        sum matters, the split preserves precision. Broadcast together.

    Returns
    -------
    GMST [rad] in [0, 2pi); a float for scalar input, else an array.
    """
    jd1_from_j2000 = np.asarray(jd1, dtype=float) - J2000_JD
    jd2 = np.asarray(jd2, dtype=float)
    t_ut1 = (jd1_from_j2000 + jd2) / DAYS_PER_JULIAN_CENTURY
    # Whole days are whole turns of the 876600 h term; only the day fraction,
    # taken part by part, contributes (see the module constants).
    day_fraction = np.mod(jd1_from_j2000, 1.0) + np.mod(jd2, 1.0)
    gmst_s = (
        S_PER_DAY * day_fraction
        + _IAU82_GMST_S0
        + t_ut1 * (_IAU82_GMST_S1_EXCESS + t_ut1 * (_IAU82_GMST_S2 + t_ut1 * _IAU82_GMST_S3))
    )
    return _as_float_or_array(wrap_to_two_pi(gmst_s * (TWO_PI / S_PER_DAY)))


@dataclass(frozen=True, order=True)
class Epoch:
    """A UTC instant as a two-part Julian date (UT1 = UTC accepted, leap seconds ignored).

    The parts are normalised on construction: ``jd1`` becomes the Julian date
    of the preceding 0 h UTC (it ends in .5) and ``jd2`` the fraction of the
    day in [0, 1). ``Epoch(2451545.0, 0.0)`` therefore stores
    ``(2451544.5, 0.5)``, equal epochs compare equal and ordering is
    chronological.
    """

    jd1: float
    jd2: float

    def __post_init__(self) -> None:
        jd1, jd2 = float(self.jd1), float(self.jd2)
        if not (math.isfinite(jd1) and math.isfinite(jd2)):
            raise ValueError(f"Julian date parts must be finite, got ({jd1}, {jd2})")
        midnight = math.floor(jd1 - 0.5) + 0.5
        fraction = (jd1 - midnight) + jd2
        carry = math.floor(fraction)
        fraction -= carry
        if fraction >= 1.0:  # a tiny negative fraction rounds up to 1.0
            fraction -= 1.0
            carry += 1
        object.__setattr__(self, "jd1", midnight + carry)
        object.__setattr__(self, "jd2", fraction)

    @classmethod
    def from_datetime(cls, dt: datetime) -> Epoch:
        """Epoch of a :class:`datetime`; a naive datetime is taken as UTC."""
        if dt.tzinfo is not None:
            dt = dt.astimezone(UTC)
        jd_day, _ = julian_date(dt.year, dt.month, dt.day)
        seconds_of_day = dt.hour * S_PER_HOUR + dt.minute * 60 + dt.second + dt.microsecond * 1e-6
        return cls(jd_day, seconds_of_day / S_PER_DAY)

    @classmethod
    def from_iso(cls, text: str) -> Epoch:
        """Epoch of an ISO 8601 date-time string.

        ``Z`` and ``+hh:mm`` offsets are converted to UTC; a string without an
        offset is UTC. Fractions of a second beyond microseconds are dropped.

        Raises
        ------
        ValueError
            If ``text`` is not an ISO 8601 date-time (the message names the
            text and the expected format) or lies outside 1900-03-01..2100-02-28.
        """
        try:
            dt = datetime.fromisoformat(text.strip())
        except ValueError as err:
            raise ValueError(
                f"cannot parse epoch {text!r}: {err}; expected {_ISO_FORMAT_HINT}"
            ) from err
        try:
            return cls.from_datetime(dt)
        except ValueError as err:
            raise ValueError(f"epoch {text!r} is not supported: {err}") from err

    def to_datetime(self) -> datetime:
        """The epoch as a timezone-aware UTC :class:`datetime`, rounded to 1 microsecond."""
        days_from_2000 = self.jd1 - _JD_2000_MIDNIGHT  # a whole number after normalisation
        microseconds = round(self.jd2 * S_PER_DAY * 1e6)
        return _DATETIME_2000_MIDNIGHT + timedelta(
            days=round(days_from_2000), microseconds=microseconds
        )

    def iso(self, digits: int = 6) -> str:
        """ISO 8601 UTC text with ``digits`` decimals of the second (rounded), e.g.
        ``'2026-03-01T12:00:00.000000Z'`` (6, microseconds: :meth:`to_datetime`'s)."""
        units = 10**digits
        ticks = round(self.jd2 * S_PER_DAY * units)  # jd2: the day's fraction
        seconds, fraction = divmod(ticks, units)
        midnight = _DATETIME_2000_MIDNIGHT + timedelta(days=round(self.jd1 - _JD_2000_MIDNIGHT))
        whole = (midnight + timedelta(seconds=seconds)).strftime("%Y-%m-%dT%H:%M:%S")
        return f"{whole}.{fraction:0{digits}d}Z" if digits else f"{whole}Z"

    def plus_seconds(self, seconds: float) -> Epoch:
        """The epoch ``seconds`` [s] later (earlier if negative), leap seconds ignored."""
        # Whole days go to jd1 exactly; only the remainder is rounded into jd2.
        whole_days, remainder_s = divmod(float(seconds), S_PER_DAY)
        return Epoch(self.jd1 + whole_days, self.jd2 + remainder_s / S_PER_DAY)

    def seconds_since(self, other: Epoch) -> float:
        """Seconds [s] from ``other`` to this epoch (positive if this one is later)."""
        return ((self.jd1 - other.jd1) + (self.jd2 - other.jd2)) * S_PER_DAY

    @property
    def jd(self) -> float:
        """Single-float Julian date [day] (resolution about 40 microseconds)."""
        return self.jd1 + self.jd2

    def gmst_rad(self) -> float:
        """Greenwich mean sidereal time at this epoch [rad] in [0, 2pi) (IAU-82)."""
        return float(gmst_rad(self.jd1, self.jd2))


def earth_rotation_angle(epoch: Epoch, t_s: ArrayLike, *, omega: float) -> np.ndarray:
    """Linearised Earth rotation angle theta(t) = GMST(epoch) + omega t.

    This is the angle the propagator rotates ECI into Earth-fixed axes with:
    IAU-82 GMST at the scenario epoch (Vallado eq. 3-47) advanced at the
    constant rate ``omega``.

    Parameters
    ----------
    epoch:
        Scenario epoch (t = 0).
    t_s:
        Seconds since ``epoch`` [s], any shape.
    omega:
        Earth rotation rate [rad/s].

    Returns
    -------
    theta [rad], same shape as ``t_s``. Not wrapped to [0, 2pi): the angle
    stays continuous and monotone in t, so it can be differenced or
    interpolated along a trajectory.
    """
    return epoch.gmst_rad() + omega * np.asarray(t_s, dtype=float)
