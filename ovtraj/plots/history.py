"""The re-plan history's trend: the plan's key figures against the element-set epoch.

Four panels share the time axis (the epoch of the element set each plan was made from):
dV_total [m/s], T_total [h], M_load [kg] and the landing miss [m] (with the Monte Carlo's
p95 when a plan has one). A change of code version between two re-plans is a dashed
vertical line labelled with the new version: a jump there may be the code's, not the
target's.
"""

from __future__ import annotations

import datetime
from pathlib import Path

import pandas as pd

from ovtraj.plots.render import figure, write_png
from ovtraj.units import S_PER_HOUR

__all__ = ["history_plot"]

_PANELS = (
    ("dv_total_mps", "dV_total [m/s]", 1.0),
    ("t_total_s", "T_total [h]", 1.0 / S_PER_HOUR),
    ("m_load_kg", "M_load [kg]", 1.0),
    ("landing_miss_m", "landing miss [m]", 1.0),
)


def _epochs(values: pd.Series) -> list[datetime.datetime]:
    return [datetime.datetime.fromisoformat(str(v)) for v in values]


def history_plot(rows: pd.DataFrame, path: Path | str, title: str) -> Path:
    """Draw the history ``rows`` (:func:`ovtraj.tracking.history.history`) to ``path``."""
    rows = rows[rows["element_set_epoch_utc"].notna()]
    fig = figure((8.0, 9.0))
    axes = fig.subplots(len(_PANELS), 1, sharex=True)
    epochs = _epochs(rows["element_set_epoch_utc"])
    changes = [
        (epochs[k], rows["code_version"].iloc[k])
        for k in range(1, len(rows))
        if rows["code_version"].iloc[k] != rows["code_version"].iloc[k - 1]
    ]
    for ax, (column, label, scale) in zip(axes, _PANELS, strict=True):
        values = rows[column].astype(float) * scale
        ax.plot(epochs, values, marker="o", color="tab:blue", label="plan")
        if column == "landing_miss_m" and rows["mc_landing_miss_p95_m"].notna().any():
            ax.plot(
                epochs,
                rows["mc_landing_miss_p95_m"].astype(float),
                marker="s",
                linestyle="none",
                color="tab:red",
                label="Monte Carlo p95",
            )
            ax.legend(loc="best", fontsize=8)
        for when, version in changes:
            ax.axvline(when, color="0.4", linestyle="--", linewidth=1.0)
            if ax is axes[0]:
                ax.annotate(
                    f"code {version}",
                    (when, 1.0),
                    xycoords=("data", "axes fraction"),
                    rotation=90,
                    fontsize=7,
                    va="top",
                    ha="right",
                )
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("element-set epoch (UTC)")
    fig.autofmt_xdate()
    axes[0].set_title(title, fontsize=10)
    return write_png(fig, path)
