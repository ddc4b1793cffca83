"""Numbers, epochs and durations as text for people: the human-readable output of the
``ovtraj`` commands (``--json`` keeps every digit; this is for reading).

- :func:`number`: significant digits, never fewer than the integer part, no exponent
  except for tiny values, the unit after it (``35.58 m/s``);
- :func:`duration`: seconds below an hour (``263.8 s``), hours above (``3.022 h``);
- :func:`utc`: an epoch as ISO 8601 UTC with a ``Z`` and milliseconds;
- :func:`quantity`: any value of a result row, by its unit (``"s"`` a duration,
  ``"utc"`` an epoch), lists joined, ``None`` and NaN shown as ``-``;
- :func:`split_unit`: a row key's name and the unit of its suffix
  (``min_t_total_s`` -> ``min_t_total``, ``"s"``), for rows printed by key;
- :func:`printable` and :func:`clipped`: a text from the user or a file made one
  printable line, and cut to a length, for error lines
  (:func:`ovtraj.config.io_limits.echoed` does both with the configured length).
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Iterable
from typing import Any

from ovtraj.units import S_PER_HOUR

__all__ = [
    "MISSING",
    "byte_size",
    "clipped",
    "duration",
    "joined",
    "number",
    "printable",
    "quantity",
    "split_unit",
    "utc",
]

MISSING = "-"
"""What a missing value (``None``, NaN) is shown as."""


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and not math.isfinite(value))


def _with_unit(text: str, unit: str) -> str:
    return f"{text} {unit}" if unit else text


def number(
    value: float | int | None, unit: str = "", digits: int = 4, *, decimals: int | None = None
) -> str:
    """``value`` to ``digits`` significant digits (all of its integer part, trailing zeros
    dropped), then ``unit``; below 1e-3 in magnitude with an exponent (``1.023e-07 m``).
    ``decimals``: that many decimals instead (components of a vector, ``-0.020``)."""
    if _missing(value):
        return MISSING
    if isinstance(value, bool) or isinstance(value, int):
        return _with_unit(str(value), unit)
    x = float(value)
    if decimals is not None:
        text = f"{x:.{decimals}f}"
        return _with_unit("0" if float(text) == 0.0 else text, unit)
    if x == 0.0:
        return _with_unit("0", unit)
    if abs(x) < 1e-3:
        return _with_unit(f"{x:.{max(digits - 1, 0)}e}", unit)
    decimals = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
    text = f"{x:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    if text in ("-0", ""):
        text = "0"
    return _with_unit(text, unit)


def byte_size(size: int | None) -> str:
    """A size in bytes with binary multiples (``812 B``, ``4.2 MiB``, ``1.07 GiB``)."""
    if _missing(size):
        return MISSING
    value = float(size)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(value) < 1024.0 or unit == "GiB":
            return f"{int(value)} B" if unit == "B" else f"{number(value, digits=3)} {unit}"
        value /= 1024.0
    return MISSING  # unreachable: the loop returns at GiB


def duration(seconds: float | None) -> str:
    """A duration: seconds below an hour (``0 s``, ``4.27 s``, ``263.8 s``, ``2430 s``),
    hours with three decimals from an hour on (``3.022 h``, ``142.003 h``)."""
    if _missing(seconds):
        return MISSING
    s = float(seconds)
    if abs(s) >= S_PER_HOUR:
        return f"{s / S_PER_HOUR:.3f} h"
    if abs(s) < 5e-3:
        return "0 s"
    return number(s, "s", digits=4)


def utc(value: Any) -> str:
    """An epoch (ISO 8601 text, :class:`datetime.datetime` or
    :class:`~ovtraj.astro.epoch.Epoch`) as ISO 8601 UTC, ``2026-12-01T03:01:20.291Z``
    (whole seconds when it has no fraction); text that is not an epoch as it is."""
    if _missing(value) or value == "":
        return MISSING
    if hasattr(value, "to_datetime"):
        value = value.to_datetime()
    if isinstance(value, str):
        try:
            value = datetime.datetime.fromisoformat(value.strip())
        except ValueError:
            return value
    if not isinstance(value, datetime.datetime):
        return str(value)
    if value.tzinfo is not None:
        value = value.astimezone(datetime.UTC)
    milliseconds = round(value.microsecond / 1e3)
    value = value.replace(microsecond=0, tzinfo=None) + datetime.timedelta(
        milliseconds=milliseconds
    )
    text = value.strftime("%Y-%m-%dT%H:%M:%S")
    if value.microsecond:
        text += f".{value.microsecond // 1000:03d}"
    return text + "Z"


def quantity(value: Any, unit: str = "", digits: int = 4) -> str:
    """Any value of a result: by ``unit`` (``"s"`` :func:`duration`, ``"utc"``
    :func:`utc`, else :func:`number` with the unit), a list or tuple joined by commas
    (the unit once, at the end), text as it is, ``None`` and NaN as ``-``."""
    if _missing(value):
        return MISSING
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, str):
        return utc(value) if unit == "utc" else (value or MISSING)
    if isinstance(value, (list, tuple)):
        return _joined(value, unit, digits, ", ")
    if unit == "s":
        return duration(value)
    if unit == "utc":
        return utc(value)
    if isinstance(value, (int, float)):
        return number(value, unit, digits)
    if hasattr(value, "item"):  # a numpy scalar
        return quantity(value.item(), unit, digits)
    return str(value)


def joined(
    values: Iterable[Any],
    unit: str = "",
    digits: int = 4,
    sep: str = " / ",
    *,
    decimals: int | None = None,
) -> str:
    """Several values of one unit, ``11.575 / 31.477 / 11.874 m/s`` (``decimals`` or
    ``digits`` each; durations and epochs each with its own unit; a missing value ``-``)."""
    values = list(values)
    if decimals is None or unit in ("s", "utc"):
        return _joined(values, unit, digits, sep)
    return _with_unit(sep.join(number(v, "", decimals=decimals) for v in values), unit)


def _joined(values: list[Any], unit: str, digits: int, sep: str) -> str:
    if not values:
        return MISSING
    if unit in ("s", "utc"):
        return sep.join(quantity(v, unit, digits) for v in values)
    return _with_unit(sep.join(quantity(v, "", digits) for v in values), unit)


# Key suffixes of the project's result rows (units in the key names, docs/conventions.md)
# and the unit each is shown in.
_SUFFIXES = {
    "_utc": "utc",
    "_s": "s",
    "_h": "h",
    "_days": "d",
    "_m": "m",
    "_km": "km",
    "_mps": "m/s",
    "_mps2": "m/s^2",
    "_deg": "deg",
    "_deg_s": "deg/s",
    "_rad_s": "rad/s",
    "_m_s2": "m/s^2",
    "_m3_s2": "m^3/s^2",
    "_kg_m3": "kg/m^3",
    "_rad": "rad",
    "_kg": "kg",
    "_pa": "Pa",
    "_kpa": "kPa",
    "_g": "g",
    "_kw_m2": "kW/m^2",
    "_w_m2": "W/m^2",
    "_n": "N",
    "_kn": "kN",
}


def split_unit(key: str) -> tuple[str, str]:
    """A row key's name without its unit suffix, and the unit (``""`` when it has none):
    ``wait_time_s`` -> ``("wait_time", "s")``, ``insertion_epoch_utc`` -> ``(...,
    "utc")``."""
    for suffix in sorted(_SUFFIXES, key=len, reverse=True):
        if key.endswith(suffix) and len(key) > len(suffix):
            return key[: -len(suffix)], _SUFFIXES[suffix]
    return key, ""


_ELLIPSIS = "..."


def printable(text: str) -> str:
    """``text`` with every non-printable character escaped as Python writes it (``\\n``,
    ``\\x1b``, ``\\u2028``): echoed in an error line, a name from the user or a file
    stays one line and sends no terminal control sequence."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def clipped(text: str, max_chars: int) -> str:
    """``text`` if at most ``max_chars`` characters, else its start and its end around
    ``...`` (``max_chars`` in all): a file name or a closing quote stays visible."""
    if len(text) <= max_chars:
        return text
    keep = max(max_chars - len(_ELLIPSIS), 0)
    head = (keep + 1) // 2
    return text[:head] + _ELLIPSIS + text[len(text) - (keep - head) :]


def one_line(text: str, max_chars: int) -> str:
    """``text`` as one printable line of at most ``max_chars`` characters: every
    non-printable character escaped (:func:`printable`), a longer text cut in the middle
    (:func:`clipped`). A value or a name echoed in an error line is shown so."""
    # cut before escaping too: escaping a long text costs its length in time
    return clipped(printable(clipped(text, max_chars)), max_chars)
