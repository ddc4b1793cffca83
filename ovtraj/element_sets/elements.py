"""One SGP4 element set read from a TLE or an OMM, and picking one of several.

An element set keeps its record exactly as read (the TLE lines; the OMM's fields),
the ``sgp4`` package's initialised :class:`~sgp4.api.Satrec` (WGS-72 constants, the
ones the elements are defined with: Vallado et al. 2006, sec. "Gravitational
constants"), and what the reports show: name, catalog number and epoch (UTC).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from sgp4.api import SGP4_ERRORS, Satrec

from ovtraj.astro.elements import perigee_radius
from ovtraj.astro.epoch import Epoch
from ovtraj.errors import ConfigError

__all__ = ["SourceElements", "select_element_set"]

SourceKind = Literal["tle", "omm"]


@dataclass(frozen=True)
class SourceElements:
    """One element set: its record as read, SGP4 initialised from it, and its identity.

    ``record`` is the TLE's lines (a tuple, name line first when there is one) or the
    OMM's fields (a tuple of (field, value) pairs, in the order read); ``where`` names
    the file, URL or config key it was read from, for messages.
    """

    kind: SourceKind
    record: tuple[Any, ...]
    name: str
    catalog_number: int
    epoch: Epoch
    satrec: Satrec = field(compare=False, repr=False)
    where: str = field(default="", compare=False)  # the file, URL or key it was read from

    def config(self) -> dict[str, Any]:
        """The inline form of a scenario's target: ``{"tle": [...]}`` or ``{"omm": {...}}``."""
        if self.kind == "tle":
            return {"tle": list(self.record)}
        return {"omm": dict(self.record)}

    def perigee_radius_km(self) -> float:
        """Perigee radius [km] of SGP4's (Brouwer) mean elements, WGS-72 Earth radius."""
        sat = self.satrec
        return float(perigee_radius(sat.a, sat.ecco) * sat.radiusearthkm)

    def label(self) -> str:
        """``NAME (catalog number N)`` for messages."""
        return f"{self.name or 'unnamed'} (catalog number {self.catalog_number})"


def check_physical(values: dict[str, float], where: str, what: str) -> None:
    """ConfigError naming the first of ``values`` (an element set's real fields, by the
    name a reader knows them: ``MEAN_MOTION`` or ``mean motion (line 2, columns 53-63)``)
    that no orbit has: not finite (NaN, inf), a mean motion not above 0 (SGP4 divides by
    it), an eccentricity outside [0, 1) (not an ellipse). The first two keys are the mean
    motion [rev/day] and the eccentricity; checked before SGP4 sees them."""
    for name, value in values.items():
        if not math.isfinite(value):
            raise ConfigError([f"{what}: {name} = {value!r} is not a finite number"], where)
    (motion_name, motion), (eccentricity_name, eccentricity) = list(values.items())[:2]
    if motion <= 0:
        raise ConfigError(
            [f"{what}: {motion_name} = {motion!r} rev/day; an orbit's mean motion is above 0"],
            where,
        )
    if not 0 <= eccentricity < 1:
        raise ConfigError(
            [
                f"{what}: {eccentricity_name} = {eccentricity!r}; an elliptic orbit's "
                "eccentricity is from 0 to below 1"
            ],
            where,
        )


def checked_satrec(sat: Satrec, where: str, what: str) -> Satrec:
    """``sat`` if SGP4 initialised it without an error, else a ConfigError naming it."""
    code = int(getattr(sat, "error", 0) or 0)
    if code:
        reason = SGP4_ERRORS.get(code, "unknown error")
        raise ConfigError([f"{what}: SGP4 refuses the elements: {reason} (error {code})"], where)
    return sat


def select_element_set(
    sets: Sequence[SourceElements], catalog_number: int | None, where: str
) -> SourceElements:
    """The one element set of ``sets``, or the one of ``catalog_number``.

    A source holding several element sets (a CelesTrak group, a catalogue file)
    needs ``catalog_number``; one holding none, or none of that number, is an error.
    """
    if not sets:
        raise ConfigError(["holds no TLE or OMM element set"], where)
    if catalog_number is not None:
        chosen = [s for s in sets if s.catalog_number == catalog_number]
        if not chosen:
            raise ConfigError(
                [f"no element set of catalog number {catalog_number} among {len(sets)}"], where
            )
        if len(chosen) > 1:
            raise ConfigError(
                [f"{len(chosen)} element sets of catalog number {catalog_number}; keep one"],
                where,
            )
        return chosen[0]
    if len(sets) > 1:
        numbers = ", ".join(str(s.catalog_number) for s in sets[:5])
        more = ", ..." if len(sets) > 5 else ""
        raise ConfigError(
            [
                f"holds {len(sets)} element sets (catalog numbers {numbers}{more}); "
                "choose one with catalog_number"
            ],
            where,
        )
    return sets[0]
