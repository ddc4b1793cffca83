"""Two-line element sets (TLE): checked line by line, then initialised by ``sgp4``.

The format (Hoots & Roehrich 1980, Spacetrack Report No. 3; CelesTrak's "NORAD
Two-Line Element Set Format") has two 69-column lines, each ending in a modulo-10
checksum of its digits (a minus sign counts 1), optionally after a name line (with
or without the ``0 `` prefix of the three-line form). Each line is checked for its
length, its column layout (the ``sgp4`` package's own reader, ``sgp4.io``, which
checks the fixed separators of Vallado's ``twoline2rv``) and its checksum
(``sgp4.io.compute_checksum``), and a bad one is named by its line number in the
file or text.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from sgp4 import io as sgp4_io
from sgp4.api import WGS72, Satrec
from sgp4.earth_gravity import wgs72

from ovtraj.astro.epoch import Epoch
from ovtraj.element_sets.elements import SourceElements, check_physical, checked_satrec
from ovtraj.errors import ConfigError

__all__ = ["tle_element_sets", "tle_elements"]

# Format definitions (Spacetrack Report No. 3): a TLE line has 69 columns, the last
# one the checksum.
TLE_LINE_COLUMNS = 69
_NAME_PREFIX = "0 "
_FORMAT_LINE = re.compile(r"format for line (\d)")


def _where_in(line_no: int, number: int) -> str:
    """``line 3 (TLE line 2)``: the line in the file or list, and which TLE line it is."""
    return f"line {line_no} (TLE line {number})"


def _layout(number: int, line_no: int) -> str:
    template = sgp4_io.LINE1 if number == 1 else sgp4_io.LINE2
    return f"{_where_in(line_no, number)}: not in the TLE column layout {template!r}"


def _check_line(line: str, number: int, line_no: int, where: str) -> None:
    """Length, leading line number and checksum of one TLE line (1-based ``line_no``)."""
    at = _where_in(line_no, number)
    if not line.startswith(f"{number} "):
        raise ConfigError([f"{at}: does not start with '{number} '"], where)
    if not line.isascii():
        raise ConfigError([f"{at}: holds non-ASCII characters"], where)
    if len(line) != TLE_LINE_COLUMNS:
        raise ConfigError(
            [f"{at}: {len(line)} columns, a TLE line has {TLE_LINE_COLUMNS}"],
            where,
        )
    stated = line[TLE_LINE_COLUMNS - 1]
    computed = sgp4_io.compute_checksum(line)
    if not stated.isdigit() or int(stated) != computed:
        raise ConfigError(
            [
                f"{at}: checksum {stated!r} in column {TLE_LINE_COLUMNS}, but the line's "
                f"digits give {computed}"
            ],
            where,
        )


# Line 2's real fields (Spacetrack Report No. 3), columns 1-based inclusive: the mean
# motion and the eccentricity first (check_physical's order); the eccentricity has an
# assumed leading decimal point.
_LINE2_REALS = {
    "mean motion": (53, 63),
    "eccentricity": (27, 33),
    "inclination": (9, 16),
    "right ascension of the ascending node": (18, 25),
    "argument of perigee": (35, 42),
    "mean anomaly": (44, 51),
}


def _check_line2_values(line2: str, line_no: int, where: str) -> None:
    """ConfigError naming the field of line 2 that no orbit has (a mean motion of 0 would
    divide by zero in SGP4's initialisation, a NaN or ``inf`` propagate silently); a field
    that does not parse is left to the reference reader's layout checks."""
    values = {}
    for name, (first, last) in _LINE2_REALS.items():
        text = line2[first - 1 : last].strip()
        try:
            value = float(f"0.{text}" if name == "eccentricity" else text)
        except ValueError:
            return
        values[f"{name} (line {line_no}, columns {first}-{last})"] = value
    check_physical(values, where, "TLE")


def tle_elements(lines: Sequence[str], where: str, first_line_no: int = 1) -> SourceElements:
    """One element set from its two lines, or a name line and two lines.

    ``first_line_no`` is the number of ``lines[0]`` in the file, for the messages.
    Raises :class:`ConfigError` naming the line for a bad length, column layout,
    checksum, mismatched catalog numbers, or elements SGP4 refuses.
    """
    lines = [str(line).rstrip() for line in lines]
    if len(lines) not in (2, 3):
        raise ConfigError([f"a TLE has 2 lines (or a name and 2), got {len(lines)}"], where)
    name = ""
    if len(lines) == 3:
        name = lines[0].removeprefix(_NAME_PREFIX).strip()
    line1, line2 = lines[-2], lines[-1]
    no1, no2 = first_line_no + len(lines) - 2, first_line_no + len(lines) - 1
    _check_line(line1, 1, no1, where)
    _check_line(line2, 2, no2, where)
    _check_line2_values(line2, no2, where)
    try:  # the reference reader's column checks (it raises on the first bad line)
        sgp4_io.twoline2rv(line1, line2, wgs72)
    except ValueError as err:
        text = str(err)
        found = _FORMAT_LINE.search(text)
        if found:
            raise ConfigError(
                [_layout(int(found.group(1)), no1 if found.group(1) == "1" else no2)], where
            ) from None
        if "do not match" in text:
            raise ConfigError(
                [
                    f"TLE lines {no1}-{no2}: catalog numbers {line1[2:7]!r} and "
                    f"{line2[2:7]!r} differ"
                ],
                where,
            ) from None
        raise ConfigError(
            [f"TLE lines {no1}-{no2}: a field does not parse ({text})"], where
        ) from None
    sat = checked_satrec(Satrec.twoline2rv(line1, line2, WGS72), where, f"TLE lines {no1}-{no2}")
    return SourceElements(
        kind="tle",
        record=tuple(lines),
        name=name,
        catalog_number=int(sat.satnum),
        epoch=Epoch(sat.jdsatepoch, sat.jdsatepochF),
        satrec=sat,
        where=where,
    )


def tle_element_sets(text: str, where: str) -> list[SourceElements]:
    """Every element set of a TLE text (2LE or 3LE, blank lines ignored), in order.

    A line 1 must be followed by its line 2; any other line directly before a line 1
    is that set's name. A line that belongs to no set is an error naming it.
    """
    numbered = [(n, line.rstrip()) for n, line in enumerate(text.splitlines(), 1) if line.strip()]
    sets: list[SourceElements] = []
    k = 0
    while k < len(numbered):
        n, line = numbered[k]
        if line.startswith("1 "):
            if k + 1 >= len(numbered) or not numbered[k + 1][1].startswith("2 "):
                raise ConfigError([f"{_where_in(n, 1)}: not followed by TLE line 2"], where)
            sets.append(tle_elements([line, numbered[k + 1][1]], where, n))
            k += 2
        elif k + 1 < len(numbered) and numbered[k + 1][1].startswith("1 "):
            if k + 2 >= len(numbered) or not numbered[k + 2][1].startswith("2 "):
                raise ConfigError(
                    [f"{_where_in(numbered[k + 1][0], 1)}: not followed by TLE line 2"], where
                )
            sets.append(tle_elements([line, numbered[k + 1][1], numbered[k + 2][1]], where, n))
            k += 3
        else:
            raise ConfigError([f"line {n}: not part of a two-line element set"], where)
    return sets
