"""Targets from real element sets: TLE and CCSDS OMM files, inline records and URLs.

An element set is read (:mod:`.fetch` for URLs, through a content-addressed cache),
parsed and checked (:mod:`ovtraj.element_sets`), flown by SGP4 and rotated from TEME
into the project's inertial frame (:mod:`ovtraj.element_sets.ephemeris`), and the
project's first-order J2 mean elements are fitted to it by least squares
(:mod:`.fit`). :mod:`.resolve` ties this to scenario files (:func:`load_scenario`,
the one reader of a scenario file) and the command line.
``docs/targets.md`` describes the whole and its measured errors.
"""

from ovtraj.target_sources.resolve import (
    element_sets_from_text,
    fit_source,
    fitted_target,
    inline_target,
    load_scenario,
    load_scenario_with_target,
    read_source,
    resolved_target,
    scenario_with_target_source,
)

__all__ = [
    "PoorTargetFitWarning",
    "StaleElementSetWarning",
    "TargetFit",
    "element_sets_from_text",
    "fit_source",
    "fit_target",
    "fitted_target",
    "inline_target",
    "load_scenario",
    "load_scenario_with_target",
    "read_source",
    "resolved_target",
    "scenario_with_target_source",
]

# The fit's names load scipy and heyoka (~2 s): imported on first use (PEP 562), so that
# reading a scenario file stays light.
_FIT_NAMES = ("PoorTargetFitWarning", "StaleElementSetWarning", "TargetFit", "fit_target")


def __getattr__(name: str) -> object:
    if name in _FIT_NAMES:
        from ovtraj.target_sources import mean_elements_fit

        return getattr(mean_elements_fit, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
