"""What a stored run, pipeline result or plan says, as named figures with units.

A figure is a leaf of the item's documents, named by its path (``totals.dv_total_mps``,
``scenario.target.tle``) and grouped as *inputs* (what it was computed from: the scenario's
fields, the element set and its epoch, the design, the code version) or *results* (what
came out: the plan's key figures, the front's size and hypervolume, the Monte Carlo's
percentiles). The unit is the name's suffix (``docs/conventions.md``,
:func:`ovtraj.formatting.split_unit`). :mod:`ovtraj.tracking.diff` compares two lists of
figures; :mod:`ovtraj.tracking.catalog` keeps the key ones in a table.

Identifiers (run, pipeline and plan ids) are not figures: two re-plans always differ
there, and the diff's header names them.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from ovtraj.astro.epoch import Epoch
from ovtraj.element_sets.inline import inline_elements
from ovtraj.errors import ConfigError
from ovtraj.formatting import split_unit

__all__ = [
    "INPUTS",
    "RESULTS",
    "Figure",
    "element_set_epoch",
    "monte_carlo_figures",
    "pipeline_figures",
    "plan_figures",
    "run_figures",
    "scenario_figures",
    "target_name",
]

INPUTS = "inputs"
RESULTS = "results"

# Plan sections that are results (the scenario is the plan's input, ``source`` its ids).
_PLAN_RESULTS = (
    "launch",
    "rendezvous",
    "stay",
    "transfer",
    "deorbit",
    "reentry",
    "terminal",
    "totals",
)
# Leaves of a plan that are not figures of the mission: provenance and free text.
_PLAN_SKIPPED = {"source", "schema_version", "scenario", "design", "code_version"}
# The largest nesting a document is walked to (the stored ones are 6-7 deep).
_MAX_DEPTH = 12


@dataclass(frozen=True)
class Figure:
    """One named value of a stored item; ``unit`` from the name's suffix ("" for none)."""

    group: str
    name: str
    value: Any

    @property
    def unit(self) -> str:
        return split_unit(self.name.rsplit(".", 1)[-1])[1]


def _leaves(value: Any, prefix: str, *, lists: bool, depth: int = 0) -> Iterator[tuple[str, Any]]:
    """``(dotted path, leaf)`` of a JSON document; lists are leaves when ``lists``, else
    skipped (vectors and time series are not compared figure by figure)."""
    if depth > _MAX_DEPTH:
        raise ValueError(f"{prefix}: nested deeper than {_MAX_DEPTH} levels")
    if isinstance(value, Mapping):
        for key in sorted(value):
            yield from _leaves(
                value[key], f"{prefix}.{key}" if prefix else str(key), lists=lists, depth=depth + 1
            )
    elif isinstance(value, list | tuple):
        if lists:
            yield prefix, list(value)
    else:
        yield prefix, value


def element_set_epoch(scenario: Mapping[str, Any]) -> str | None:
    """The epoch [UTC] of the scenario's target element set: the TLE's or OMM's epoch, or,
    for a hand-typed orbit, the scenario epoch (its elements are given at that epoch).
    None when the scenario names neither."""
    target = scenario.get("target")
    if isinstance(target, Mapping) and (target.get("tle") or target.get("omm")):
        try:
            elements = inline_elements(target.get("tle"), target.get("omm"))
        except (ConfigError, ValueError, TypeError):
            return None
        return elements.epoch.iso()
    epoch = scenario.get("epoch_utc")
    if epoch is None:
        return None
    try:  # one format for every kind of target, so that epochs sort as text
        return Epoch.from_iso(str(epoch)).iso()
    except ValueError:
        return str(epoch)


def target_name(scenario: Mapping[str, Any]) -> str | None:
    """The target's name as the scenario gives it (the key of its re-plan history)."""
    target = scenario.get("target")
    name = target.get("name") if isinstance(target, Mapping) else None
    return str(name) if name is not None else None


def scenario_figures(scenario: Mapping[str, Any]) -> list[Figure]:
    """The scenario's fields (lists as whole values) and the element set's epoch."""
    figures = [Figure(INPUTS, f"scenario.{k}", v) for k, v in _leaves(scenario, "", lists=True)]
    figures.append(Figure(INPUTS, "target.element_set_epoch_utc", element_set_epoch(scenario)))
    return figures


def plan_figures(plan: Mapping[str, Any]) -> list[Figure]:
    """A plan's inputs (scenario, element-set epoch, design, code version) and results
    (every scalar of its stages and totals)."""
    figures = scenario_figures(plan.get("scenario") or {})
    figures += [
        Figure(INPUTS, f"design.{k}", v)
        for k, v in _leaves(plan.get("design") or {}, "", lists=True)
    ]
    figures.append(Figure(INPUTS, "code_version", plan.get("code_version")))
    for section in _PLAN_RESULTS:
        if section in plan:
            figures += [
                Figure(RESULTS, name, value)
                for name, value in _leaves(plan[section], section, lists=False)
            ]
    return figures


def run_figures(
    manifest: Mapping[str, Any], config: Mapping[str, Any], summary: Mapping[str, Any]
) -> list[Figure]:
    """A DoE run's inputs (scenario, seed, samples, origin, code version) and results
    (status, evaluated, feasible, the objectives' ranges over the feasible samples)."""
    figures = scenario_figures(config)
    figures += [
        Figure(INPUTS, f"run.{key}", manifest.get(key))
        for key in ("seed", "samples", "origin", "code_version")
    ]
    figures += [
        Figure(RESULTS, f"run.{key}", summary.get(key))
        for key in sorted(summary)
        if key in ("status", "evaluated", "feasible") or key.startswith(("min_", "max_"))
    ]
    return figures


def pipeline_figures(summary: Mapping[str, Any], config: Mapping[str, Any]) -> list[Figure]:
    """A pipeline result's inputs (its DoE run's scenario, the code version) and results
    (front size and hypervolume, the stop, the real evaluations, the rounds)."""
    figures = scenario_figures(config)
    figures.append(Figure(INPUTS, "code_version", summary.get("code")))
    for key in ("front_points", "hypervolume", "stop_reason", "converged"):
        figures.append(Figure(RESULTS, f"pipeline.{key}", summary.get(key)))
    spent = summary.get("real_evaluations") or {}
    for key in sorted(spent) if isinstance(spent, Mapping) else ():
        figures.append(Figure(RESULTS, f"pipeline.real_evaluations.{key}", spent[key]))
    figures.append(Figure(RESULTS, "pipeline.rounds", len(summary.get("iterations") or [])))
    return figures


def monte_carlo_figures(summary: Mapping[str, Any]) -> list[Figure]:
    """A plan Monte Carlo's results (the closed loop's): runs, landed, the landing miss's
    and the dV's percentiles, the margin beyond the plan at p95."""
    figures = [
        Figure(RESULTS, f"monte_carlo.{k}", summary.get(k)) for k in ("runs", "landed", "seed")
    ]
    figures.append(
        Figure(
            RESULTS,
            "monte_carlo.within_stated_miss_fraction",
            summary.get("within_stated_miss_fraction"),
        )
    )
    miss = summary.get("landing_miss_m") or {}
    for key in ("p50", "p95", "max"):
        figures.append(Figure(RESULTS, f"monte_carlo.landing_miss_{key}_m", miss.get(key)))
    total = (summary.get("dv_mps") or {}).get("total") or {}
    for key in ("p50", "p95", "max"):
        figures.append(Figure(RESULTS, f"monte_carlo.dv_total_{key}_mps", total.get(key)))
    figures.append(Figure(RESULTS, "monte_carlo.dv_margin_p95_mps", total.get("p95_minus_planned")))
    return figures
