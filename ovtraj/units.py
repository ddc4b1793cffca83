"""Units and time constants: the one definition of each conversion factor.

Every factor here is exact by definition (an SI prefix, the civil clock, the Julian
calendar, the IEC binary prefixes), so none is a setting: settings live in ``configs/``.
Each is written the way it was where it was first defined, so that using it gives the
same floats. This module imports nothing from the library and sits below every layer
(``[tool.importlinter]`` in pyproject.toml), so that the formatting and the store use
the same factors as the astrodynamics. tests/test_one_definition.py fails on a copy of
one of them elsewhere in ``ovtraj/``.

References
----------
BIPM, *The International System of Units (SI)*, 9th ed., 2019: tables 5 (prefixes) and
8 (minute, hour, day; degree = pi/180 rad).
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., 2013: eq. 3-42
(J2000.0 and the Julian century).
IAU 1994 resolution C7 (J2000.0 = JD 2451545.0); IAU 1973 (MJD = JD - 2400000.5).
IEC 80000-13:2008 (KiB, MiB, GiB).
"""

from __future__ import annotations

import math

__all__ = [
    "BYTES_PER_GIB",
    "BYTES_PER_KIB",
    "BYTES_PER_MIB",
    "DAYS_PER_JULIAN_CENTURY",
    "DEG_PER_RAD",
    "J2000_JD",
    "JD_MINUS_MJD",
    "JULIAN_CENTURIES_PER_MILLENNIUM",
    "M_PER_KM",
    "RAD_PER_DEG",
    "S_PER_DAY",
    "S_PER_HOUR",
    "S_PER_JULIAN_CENTURY",
]

# Length and angle
M_PER_KM = 1000.0
"""Metres per kilometre [m/km] (SI prefix kilo)."""

RAD_PER_DEG = math.pi / 180.0
"""Radians per degree [rad/deg] (SI brochure, table 8); ``math.radians`` multiplies by the same."""

DEG_PER_RAD = 180.0 / math.pi
"""Degrees per radian [deg/rad]."""

# Time
S_PER_HOUR = 3600.0
"""Seconds per hour [s/h] (SI brochure, table 8)."""

S_PER_DAY = 86400.0
"""Seconds per day [s/day]: the civil (UTC) day without leap seconds (SI brochure, table 8)."""

J2000_JD = 2451545.0
"""Julian date of the J2000.0 epoch, 2000-01-01 12:00 [day] (IAU 1994; Vallado eq. 3-42)."""

DAYS_PER_JULIAN_CENTURY = 36525.0
"""Days per Julian century [day], the unit of T_UT1 and T_TT (Vallado eq. 3-42)."""

S_PER_JULIAN_CENTURY = DAYS_PER_JULIAN_CENTURY * S_PER_DAY
"""Seconds per Julian century [s]."""

JULIAN_CENTURIES_PER_MILLENNIUM = 10.0
"""Julian centuries per Julian millennium [-], the time unit of VSOP and ELP series."""

JD_MINUS_MJD = 2400000.5
"""Julian date minus modified Julian date [day] (IAU 1973: MJD 0 = 1858-11-17 0 h)."""

# Data sizes
BYTES_PER_KIB = 1024
"""Bytes per kibibyte [B/KiB] (IEC 80000-13)."""

BYTES_PER_MIB = 1 << 20
"""Bytes per mebibyte [B/MiB] (IEC 80000-13)."""

BYTES_PER_GIB = 1 << 30
"""Bytes per gibibyte [B/GiB] (IEC 80000-13)."""
