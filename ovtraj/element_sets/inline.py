"""The element set of a scenario target given inline: TLE lines or OMM fields, parsed and
checked once per process (a scenario is validated many times: each batch, each task)."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from functools import lru_cache

from ovtraj.element_sets.elements import SourceElements
from ovtraj.element_sets.omm import omm_elements
from ovtraj.element_sets.tle import tle_elements
from ovtraj.errors import ConfigError


def inline_elements(
    tle: Sequence[str] | None,
    omm: Mapping[str, str | int | float] | None,
    catalog_number: int | None = None,
) -> SourceElements:
    """The element set of ``tle`` (2 or 3 lines) or else ``omm`` (its fields), checked
    against ``catalog_number`` when given; :class:`ConfigError` naming the problem."""
    if tle is not None:
        elements = _tle_cached(tuple(tle))
    elif omm is not None:
        elements = _omm_cached(json.dumps(dict(omm), sort_keys=True))
    else:
        raise ConfigError(["target: hand-typed orbit, no TLE / OMM element set"])
    if catalog_number is not None and catalog_number != elements.catalog_number:
        found = elements.catalog_number
        raise ConfigError([f"catalog_number = {catalog_number} but the element set is of {found}"])
    return elements


@lru_cache(maxsize=64)
def _tle_cached(lines: tuple[str, ...]) -> SourceElements:
    return tle_elements(lines, "target.tle")


@lru_cache(maxsize=64)
def _omm_cached(fields_json: str) -> SourceElements:
    return omm_elements(json.loads(fields_json), "target.omm")
