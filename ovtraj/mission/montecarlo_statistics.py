"""The statistics of a plan's Monte Carlo runs, per loop (:mod:`ovtraj.mission.montecarlo`).

The landing-miss percentiles (a run that did not land counting as a miss beyond any
distance), the landed fraction and the fraction within the plan's stated miss, the
failures by stage, the smallest margin of each path limit (limit minus maximum), and the
dV spent against the plan's (:func:`summarise`); the closed loop's figures reported with
the open loop's beside them (:func:`monte_carlo_report`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ovtraj.mission.montecarlo_outcome import (
    IMPULSES,
    MANOEUVRES,
    PATH_LIMITS,
    RunOutcome,
    outcomes_of,
)
from ovtraj.mission.plan import MissionPlan

__all__ = [
    "dv_statistics",
    "loop_summaries",
    "monte_carlo_report",
    "outcome_summaries",
    "path_limits",
    "planned_dv",
    "summarise",
]


def path_limits(plan: MissionPlan) -> dict[str, float]:
    """The entry's path limits of the plan's scenario, in the units of ``PATH_LIMITS``."""
    limits = plan.scenario["reentry"]["limits"]
    return {
        "max_heat_rate_w_m2": limits["max_heat_rate_kw_m2"] * 1e3,
        "max_load_g": limits["max_load_g"],
        "max_dynamic_pressure_pa": limits["max_dynamic_pressure_kpa"] * 1e3,
    }


def planned_dv(plan: MissionPlan) -> dict[str, float]:
    """The dV [m/s] the plan spends on each manoeuvre of :data:`MANOEUVRES` (its impulses'
    magnitudes; no mid-course correction: 0) and ``total``, their sum."""
    planned = dict.fromkeys(MANOEUVRES, 0.0)
    planned.update(
        {name: impulse.dv_mps for name, impulse in zip(IMPULSES, plan.impulses(), strict=True)}
    )
    return {"total": sum(planned.values()), **planned}


def outcome_summaries(
    plan: MissionPlan, closed: list[RunOutcome], opened: list[RunOutcome]
) -> dict[str, dict[str, Any]]:
    """:func:`summarise` of each loop's runs (``closed``, ``open``) against the plan's
    limits, stated miss and dV."""
    limits, stated, planned = path_limits(plan), plan.terminal.stated_miss_m, planned_dv(plan)
    return {
        loop: summarise(outcomes, limits, stated, planned)
        for loop, outcomes in (("closed", closed), ("open", opened))
    }


def loop_summaries(plan: MissionPlan, frame: pd.DataFrame) -> dict[str, dict[str, Any]]:
    """:func:`outcome_summaries` of the stored rows of each loop (``closed``, ``open``)."""
    return outcome_summaries(plan, outcomes_of(frame, "closed"), outcomes_of(frame, "open"))


def monte_carlo_report(
    closed: dict[str, Any], opened: dict[str, Any], seed: int, stated_miss_m: float
) -> dict[str, Any]:
    """The Monte Carlo as reported: the closed loop's figures (``runs``, ``landing_miss_m``,
    ``feasible_fraction``, ``dv_mps``, ...) with ``open_loop``'s beside them."""
    return {
        "loop": "closed",
        "seed": int(seed),
        "stated_miss_m": stated_miss_m,
        **closed,
        "open_loop": opened,
    }


def summarise(
    outcomes: list[RunOutcome],
    limits: dict[str, float],
    stated_miss_m: float,
    planned: dict[str, float] | None = None,
) -> dict[str, Any]:
    """The landing-miss percentiles over every run, a run that did not land counting as a
    miss beyond any distance (a percentile that falls on one is ``None``); the landed
    fraction, the fraction within the stated miss, the failures by stage, the smallest
    margin of each path limit over the runs that flew the entry, and the dV spent
    (:func:`dv_statistics` against ``planned``, the plan's: :func:`planned_dv`)."""
    landed = [o for o in outcomes if o.landed and o.landing_miss_m is not None]
    misses = np.array([o.landing_miss_m if o in landed else np.inf for o in outcomes], dtype=float)
    summary: dict[str, Any] = {
        "runs": len(outcomes),
        "landed": len(landed),
        "feasible_fraction": len(landed) / len(outcomes) if outcomes else 0.0,
        "within_stated_miss_fraction": (
            float(np.sum(misses <= stated_miss_m)) / len(outcomes) if outcomes else 0.0
        ),
        "landing_miss_m": _percentiles(misses) if landed else None,
        "failures": _failures(outcomes),
    }
    margins = {}
    for name in PATH_LIMITS:
        values = [o.maxima[name] for o in outcomes if name in o.maxima]
        margins[name] = (
            {"limit": limits[name], "smallest_margin": limits[name] - max(values)}
            if values
            else None
        )
    summary["path_limit_margins"] = margins
    summary["dv_mps"] = dv_statistics(outcomes, planned or {})
    return summary


def _percentiles(values: NDArray[np.float64]) -> dict[str, float | None]:
    """``p50``, ``p95`` and ``max`` of ``values`` (non-empty), each one of the values
    (numpy's ``higher`` method); a non-finite one (a run counted beyond any value) is
    ``None``."""

    def percentile(q: float) -> float | None:
        value = float(np.percentile(values, q, method="higher"))
        return value if math.isfinite(value) else None

    return {"p50": percentile(50), "p95": percentile(95), "max": percentile(100)}


def dv_statistics(
    outcomes: list[RunOutcome], planned: dict[str, float]
) -> dict[str, dict[str, Any]]:
    """The dV spent [m/s], ``total`` and each manoeuvre of :data:`MANOEUVRES`: ``runs``
    (how many executed it; for the total, all of them), ``p50``, ``p95`` and ``max`` over
    those runs (``None`` when none did), ``planned`` (``planned``'s value, ``None`` if it
    has none) and ``p95_minus_planned``, the margin beyond the plan a tank sized at p95
    carries."""
    section = {}
    for name in ("total", *MANOEUVRES):
        flown = [o.dv_total_mps if name == "total" else o.dv_mps.get(name) for o in outcomes]
        values = np.array([v for v in flown if v is not None and math.isfinite(v)], dtype=float)
        stats = _percentiles(values) if len(values) else dict.fromkeys(("p50", "p95", "max"))
        plan = planned.get(name)
        section[name] = {
            "runs": len(values),
            **stats,
            "planned": plan,
            "p95_minus_planned": (
                None if stats["p95"] is None or plan is None else stats["p95"] - plan
            ),
        }
    return section


def _failures(outcomes: list[RunOutcome]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for o in outcomes:
        if not o.landed:
            key = o.failed_stage or "unknown"
            counts[key] = counts.get(key, 0) + 1
    return counts
