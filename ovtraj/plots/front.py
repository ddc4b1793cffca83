"""Pareto front plots: the three pairwise projections of (T_total, dV_total, M_load).

Each axis is an objective in its report unit (``Objective.report_unit``: T_total in
hours) and says which way is better (``Objective.sense``: T_total and dV_total lower,
M_load higher). The title names the product, the scenario and a date taken from the
data (the callers pass the scenario's epoch), never the wall clock: the PNG is listed
with its SHA-256 in stored products and must be byte-identical for one config and seed.
"""

from __future__ import annotations

from itertools import combinations
from pathlib import Path
from typing import Any

import pandas as pd

from ovtraj.optimize.objectives import Normalisation, Objective
from ovtraj.plots.render import figure, write_png

__all__ = ["axis_label", "front_figure", "front_plot", "subtitle"]

_ARROWS = {("x", +1): "\u2190", ("x", -1): "\u2192", ("y", +1): "\u2193", ("y", -1): "\u2191"}


def axis_label(objective: Objective, axis: str) -> str:
    """``"T_total [h] (lower is better ←)"``: name, report unit, better direction."""
    better = "lower" if objective.sense > 0 else "higher"
    arrow = _ARROWS[(axis, 1 if objective.sense > 0 else -1)]
    return f"{objective.label} [{objective.report_unit}] ({better} is better {arrow})"


def subtitle(scenario: str = "", date: str = "") -> str:
    """``"scenario NAME, DATE"``, or the part given ("" if neither)."""
    parts = [f"scenario {scenario}" if scenario else "", date]
    return ", ".join(part for part in parts if part)


def front_figure(
    normalisation: Normalisation,
    *,
    surrogate: pd.DataFrame | None = None,
    samples: pd.DataFrame | None = None,
    verified: pd.DataFrame | None = None,
    chosen: pd.DataFrame | None = None,
    title: str = "",
    scenario: str = "",
    date: str = "",
) -> Any:
    """The front's Figure, three panels; each table holds the objective columns (SI).

    ``samples``: every feasible real evaluation (grey); ``surrogate``: the predicted
    front; ``verified``: the verified front (real values); ``chosen``: the planned point.
    ``scenario`` and ``date`` (from the data, e.g. ``"epoch 2026-12-01T00:00:00Z"``) go
    under the title.
    """
    objectives = normalisation.objectives
    layers = (
        (samples, {"s": 10, "c": "0.65", "label": "real evaluations (feasible)"}),
        (surrogate, {"s": 12, "c": "C0", "marker": "x", "label": "surrogate front (predicted)"}),
        (verified, {"s": 28, "c": "C3", "marker": "o", "label": "verified front (real)"}),
        (chosen, {"s": 120, "c": "none", "edgecolors": "k", "marker": "s", "label": "planned"}),
    )
    fig = figure((15.0, 4.9))
    axes = fig.subplots(1, 3)
    for ax, (i, j) in zip(axes, combinations(range(len(objectives)), 2), strict=True):
        for table, style in layers:
            if table is None or len(table) == 0:
                continue
            x = table[objectives[i].name].to_numpy(dtype=float) * objectives[i].report_scale
            y = table[objectives[j].name].to_numpy(dtype=float) * objectives[j].report_scale
            ax.scatter(x, y, **style)
        ax.set_xlabel(axis_label(objectives[i], "x"))
        ax.set_ylabel(axis_label(objectives[j], "y"))
        ax.grid(True, alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=len(handles), fontsize=9)
    heading = "\n".join(part for part in (title, subtitle(scenario, date)) if part)
    if heading:
        fig.suptitle(heading)
    return fig


def front_plot(path: Path, normalisation: Normalisation, **layers: Any) -> Path:
    """Write :func:`front_figure` (its keyword arguments: the tables, title, scenario,
    date) as one PNG at ``path`` (atomically); returns the path."""
    return write_png(front_figure(normalisation, **layers), path)
