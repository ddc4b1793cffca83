"""Pareto front plots: the three pairwise projections of (T_total, dV_total, M_load)."""

from __future__ import annotations

import io
from itertools import combinations
from pathlib import Path

import pandas as pd

from ovtraj.files import write_bytes
from ovtraj.optimize.objectives import Normalisation
from ovtraj.storage import location

__all__ = ["front_plot"]


def front_plot(
    path: Path,
    normalisation: Normalisation,
    *,
    surrogate: pd.DataFrame | None = None,
    samples: pd.DataFrame | None = None,
    verified: pd.DataFrame | None = None,
    chosen: pd.DataFrame | None = None,
    title: str = "",
) -> Path:
    """One PNG, three panels; each table holds the objective columns (SI, totals names).

    ``samples``: every feasible real evaluation (grey); ``surrogate``: the predicted
    front; ``verified``: the verified front (real values); ``chosen``: the planned point.
    """
    from matplotlib.figure import Figure  # no pyplot: no global state, safe in workers

    objectives = normalisation.objectives
    layers = (
        (samples, {"s": 10, "c": "0.65", "label": "real evaluations (feasible)"}),
        (surrogate, {"s": 12, "c": "C0", "marker": "x", "label": "surrogate front (predicted)"}),
        (verified, {"s": 28, "c": "C3", "marker": "o", "label": "verified front (real)"}),
        (chosen, {"s": 120, "c": "none", "edgecolors": "k", "marker": "s", "label": "planned"}),
    )
    fig = Figure(figsize=(15, 4.6), constrained_layout=True)
    axes = fig.subplots(1, 3)
    for ax, (i, j) in zip(axes, combinations(range(len(objectives)), 2), strict=True):
        for table, style in layers:
            if table is None or len(table) == 0:
                continue
            x = table[objectives[i].name].to_numpy(dtype=float) * objectives[i].report_scale
            y = table[objectives[j].name].to_numpy(dtype=float) * objectives[j].report_scale
            ax.scatter(x, y, **style)
        ax.set_xlabel(f"{objectives[i].label} [{objectives[i].report_unit}]")
        ax.set_ylabel(f"{objectives[j].label} [{objectives[j].report_unit}]")
        ax.grid(True, alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=len(handles), fontsize=9)
    if title:
        fig.suptitle(title)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    path = location(path)
    write_bytes(path, buffer.getvalue(), replace=True)
    return path
