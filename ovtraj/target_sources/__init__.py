"""Targets from real element sets: TLE and CCSDS OMM files, inline records and URLs.

An element set is read and checked (:mod:`.tle`, :mod:`.omm`; :mod:`.fetch` for
URLs, through a content-addressed cache), flown by SGP4 and rotated from TEME into
the project's inertial frame (:mod:`.ephemeris`, :mod:`ovtraj.astro.teme`), and the
project's first-order J2 mean elements are fitted to it by least squares
(:mod:`.fit`). :mod:`.resolve` ties this to scenarios and the command line.
``docs/targets.md`` describes the whole and its measured errors.
"""

from ovtraj.target_sources.elements import SourceElements, select_element_set
from ovtraj.target_sources.fit import (
    PoorTargetFitWarning,
    StaleElementSetWarning,
    TargetFit,
    fit_target,
)
from ovtraj.target_sources.resolve import (
    element_sets_from_text,
    fit_source,
    fitted_target,
    inline_target,
    load_scenario_with_target,
    read_source,
    scenario_with_target_source,
    target_elements,
)

__all__ = [
    "PoorTargetFitWarning",
    "SourceElements",
    "StaleElementSetWarning",
    "TargetFit",
    "element_sets_from_text",
    "fit_source",
    "fit_target",
    "fitted_target",
    "inline_target",
    "load_scenario_with_target",
    "read_source",
    "scenario_with_target_source",
    "select_element_set",
    "target_elements",
]
