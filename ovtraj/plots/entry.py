"""The entry's time histories against their limits, from the entry interface on.

Four panels share the time axis (seconds from the entry interface): heat rate [kW/m²],
load factor [g], dynamic pressure [kPa] and bank angle [deg], each drawn from the reentry
stage's trajectory table (``MissionRecord.trajectories["reentry"]``, sampled every
``reentry.integration.trajectory_step_s``) with its limit from ``reentry.limits`` as a
dashed line (the bank angle's at plus and minus its limit). Every value drawn comes from
the table or the scenario; the title names the scenario and its day, never the wall clock.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from ovtraj.config import Scenario
from ovtraj.plots.mission import limit_labels, scenario_when
from ovtraj.plots.render import figure, write_png

__all__ = ["ENTRY_PANELS", "entry_histories_figure", "entry_histories_plot"]

# (table column, axis label, limit key of limit_labels or "bank")
ENTRY_PANELS = (
    ("heat_rate_kw_m2", "heat rate [kW/m²]", "heat"),
    ("load_g", "load factor [g]", "load"),
    ("dynamic_pressure_kpa", "dynamic pressure [kPa]", "q"),
    ("bank_deg", "bank angle [deg]", "bank"),
)
_LIMIT = {"color": "C3", "ls": "--", "lw": 1.2}


def _limits(scenario: Scenario) -> dict[str, float]:
    """Each panel's limit in its axis unit (``reentry.limits``)."""
    limits = scenario.reentry.limits
    return {
        "heat": limits.max_heat_rate_kw_m2,
        "load": limits.max_load_g,
        "q": limits.max_dynamic_pressure_kpa,
        "bank": limits.max_bank_deg,
    }


def entry_histories_figure(table: pd.DataFrame, scenario: Scenario) -> Any:
    """The four panels of ``table`` (the reentry's trajectory table: ``time_s`` from the
    entry interface and the columns of :data:`ENTRY_PANELS`) with their limits."""
    fig = figure((11.0, 7.5))
    axes = fig.subplots(2, 2, sharex=True).ravel()
    limits = _limits(scenario)
    labels = {**limit_labels(scenario), "bank": f"bank angle limit ±{limits['bank']:g} deg"}
    time = table["time_s"].to_numpy(dtype=float)
    for ax, (column, label, key) in zip(axes, ENTRY_PANELS, strict=True):
        ax.plot(time, table[column].to_numpy(dtype=float), color="k", lw=1.2, label="planned")
        ax.axhline(limits[key], label=labels[key], **_LIMIT)
        if key == "bank":
            ax.axhline(-limits[key], **_LIMIT)
            ax.axhline(0.0, color="0.6", lw=0.6)
        else:
            ax.set_ylim(bottom=0.0)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    for ax in axes[2:]:
        ax.set_xlabel("time from the entry interface [s]")
    fig.suptitle(f"Entry time histories: {scenario_when(scenario)}")
    return fig


def entry_histories_plot(table: pd.DataFrame, scenario: Scenario, path: Path | str) -> Path:
    """Draw :func:`entry_histories_figure` to ``path`` (PNG); returns the path."""
    return write_png(entry_histories_figure(table, scenario), path)
