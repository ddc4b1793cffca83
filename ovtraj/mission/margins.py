"""A plan's path peaks against the limits its scenario sets, and the margin each keeps.

Every limit is the scenario's own (the plan carries it, resolved): the reentry's heat rate,
load factor, dynamic pressure and bank angle (``reentry.limits``), the ascent's dynamic
pressure and axial load (the launcher's ``limits``; the launch counts a peak up to
``launch.insertion_tolerances.path_limit_fraction`` over its limit as within) and the
largest single impulse (``vehicle.max_impulse_mps``). The peaks are the plan's own, as the
stages solved them. Each row is in its limit's configuration unit; the margin is the limit
minus the peak (negative: over the limit).
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from ovtraj.config import Scenario
from ovtraj.mission.plan import MissionPlan

__all__ = ["LimitMargin", "limit_margins", "margins_frame"]


@dataclass(frozen=True)
class LimitMargin:
    """One peak against its limit, both in ``unit``; ``source``: the limit's config key."""

    quantity: str
    peak: float
    limit: float
    unit: str
    source: str
    # A peak up to this fraction over the limit still counts as within (the launch's).
    allowance_fraction: float = 0.0

    @property
    def margin(self) -> float:
        """Limit minus peak, in ``unit`` (negative: over the limit)."""
        return self.limit - self.peak

    @property
    def margin_percent(self) -> float:
        """The margin as a percentage of the limit."""
        return 100.0 * self.margin / self.limit

    @property
    def within(self) -> bool:
        return self.peak <= self.limit * (1.0 + self.allowance_fraction)


def limit_margins(plan: MissionPlan, scenario: Scenario) -> list[LimitMargin]:
    """Every path peak of ``plan`` against its limit in ``scenario`` (the plan's own,
    :func:`ovtraj.config.scenario_from_dict` of ``plan.scenario``), entry first."""
    entry = scenario.reentry.limits
    reentry = plan.reentry
    margins = [
        LimitMargin(
            "entry peak heat rate",
            reentry.max_heat_rate_w_m2 / 1e3,
            entry.max_heat_rate_kw_m2,
            "kW/m²",
            "reentry.limits.max_heat_rate_kw_m2",
        ),
        LimitMargin(
            "entry peak load factor",
            reentry.max_load_g,
            entry.max_load_g,
            "g",
            "reentry.limits.max_load_g",
        ),
        LimitMargin(
            "entry peak dynamic pressure",
            reentry.max_dynamic_pressure_pa / 1e3,
            entry.max_dynamic_pressure_kpa,
            "kPa",
            "reentry.limits.max_dynamic_pressure_kpa",
        ),
        LimitMargin(
            "entry peak bank angle",
            reentry.max_bank_deg,
            entry.max_bank_deg,
            "deg",
            "reentry.limits.max_bank_deg",
        ),
    ]
    if scenario.launch is not None:
        launcher = scenario.launch.launcher.limits
        allowance = scenario.launch.insertion_tolerances.path_limit_fraction
        margins += [
            LimitMargin(
                "ascent peak dynamic pressure",
                plan.launch.max_dynamic_pressure_pa / 1e3,
                launcher.max_dynamic_pressure_kpa,
                "kPa",
                "launch.launcher.limits.max_dynamic_pressure_kpa",
                allowance,
            ),
            LimitMargin(
                "ascent peak axial load",
                plan.launch.max_axial_load_g,
                launcher.max_axial_load_g,
                "g",
                "launch.launcher.limits.max_axial_load_g",
                allowance,
            ),
        ]
    largest = max(plan.impulses(), key=lambda burn: burn.dv_mps)
    margins.append(
        LimitMargin(
            f"largest single impulse ({largest.name})",
            largest.dv_mps,
            scenario.vehicle.max_impulse_mps,
            "m/s",
            "vehicle.max_impulse_mps",
        )
    )
    return margins


def margins_frame(margins: list[LimitMargin]) -> pd.DataFrame:
    """The margins as a table: quantity, peak, limit, margin, margin_percent, unit,
    within, source."""
    return pd.DataFrame(
        [
            {
                "quantity": m.quantity,
                "peak": m.peak,
                "limit": m.limit,
                "margin": m.margin,
                "margin_percent": m.margin_percent,
                "unit": m.unit,
                "within": m.within,
                "source": m.source,
            }
            for m in margins
        ]
    )
