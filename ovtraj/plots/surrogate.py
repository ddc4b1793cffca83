"""Parity plots of the selected surrogates: predicted against true value, one PNG per output.

Cross-validation points (each predicted by the model fitted without its fold) are hollow
circles, held-out points (predicted by the final model, never used in fitting or
selection) filled triangles; the diagonal is the 1:1 line. The title names the selected
candidate, its Q² (k-fold) and its held-out R² ("n/a" when undefined: fewer than 2
held-out feasible samples or no spread in them). Values are shown in the unit their name
ends with, times in hours (``rendezvous_wait_s``, ``t_total_s``: up to 72 h and more,
hard to read in seconds); Q² and R² do not depend on the unit.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.plots.render import figure, write_png
from ovtraj.store.backends import location
from ovtraj.surrogate import SurrogateSet
from ovtraj.units import S_PER_HOUR

__all__ = ["display_unit", "parity_figure", "parity_plots"]

# Name suffix (the stored value's unit) -> (shown unit, shown value per stored value).
_UNITS = {
    "_s": ("h", 1.0 / S_PER_HOUR),
    "_h": ("h", 1.0),
    "_mps": ("m/s", 1.0),
    "_kg": ("kg", 1.0),
    "_km": ("km", 1.0),
    "_m": ("km", 1e-3),
    "_deg": ("deg", 1.0),
}


def display_unit(output: str) -> tuple[str, str, float]:
    """``(name, unit, scale)`` of an output: ``"rendezvous_wait_s"`` -> wait in hours.

    The shown value is the stored one times ``scale``; an unknown suffix is shown as is
    with no unit.
    """
    for suffix, (unit, scale) in _UNITS.items():
        if output.endswith(suffix) and len(output) > len(suffix):
            return output[: -len(suffix)], unit, scale
    return output, "", 1.0


def _file_name(output: str, taken: set[str]) -> str:
    stem = "parity-" + (re.sub(r"[^A-Za-z0-9_.-]+", "_", output).strip("._") or "output")
    name, k = f"{stem}.png", 2
    while name in taken:
        name, k = f"{stem}-{k}.png", k + 1
    taken.add(name)
    return name


def _metric(value: object) -> str:
    return "n/a" if value is None or pd.isna(value) else f"{float(value):.4f}"


def parity_figure(surrogates: SurrogateSet, output: str) -> Any:
    """The parity Figure of one output of ``surrogates`` (values in the output's unit)."""
    table = surrogates.predictions
    validation = surrogates.validation
    rows = table[table["model"] == output]
    candidate = surrogates.selected[output]
    chosen = validation[(validation["model"] == output) & validation["selected"]].iloc[0]
    name, unit, scale = display_unit(output)
    shown = f"{name} [{unit}]" if unit else name
    fig = figure((5.6, 5.4))
    ax = fig.subplots()
    for split, style in (
        ("cv", {"marker": "o", "facecolors": "none", "edgecolors": "C0", "s": 28}),
        ("heldout", {"marker": "^", "color": "C3", "s": 36}),
    ):
        part = rows[rows["split"] == split]
        label = "k-fold CV" if split == "cv" else "held out"
        ax.scatter(
            part["y_true"].to_numpy(float) * scale,
            part["y_pred"].to_numpy(float) * scale,
            label=f"{label} ({len(part)})",
            **style,
        )
    values = scale * np.concatenate(
        [rows["y_true"].to_numpy(float), rows["y_pred"].to_numpy(float)]
    )
    low, high = float(values.min()), float(values.max())
    pad = (high - low) * 0.05 or abs(high) * 0.05 or 1.0
    line = [low - pad, high + pad]
    ax.plot(line, line, "k-", lw=0.8, label="1:1")
    ax.set_xlim(line)
    ax.set_ylim(line)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{shown} (true)")
    ax.set_ylabel(f"{shown} (predicted)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=9)
    ax.set_title(
        f"{output}: {candidate}, Q² = {_metric(chosen['cv_q2'])}, "
        f"held-out R² = {_metric(chosen['heldout_r2'])}",
        fontsize=10,
    )
    return fig


def parity_file_names(surrogates: SurrogateSet) -> dict[str, str]:
    """``parity-<output>.png`` of every output of ``surrogates`` (distinct names)."""
    taken: set[str] = set()
    return {output: _file_name(output, taken) for output in surrogates.output_names}


def parity_plots(surrogates: SurrogateSet, directory: Path) -> list[Path]:
    """Write ``parity-<output>.png`` for every output of ``surrogates``; return the paths.

    Each file is rendered in memory and written atomically (temporary name, then rename).
    """
    directory = location(directory)
    directory.mkdir(parents=True, exist_ok=True)
    return [
        write_png(parity_figure(surrogates, output), directory / name)
        for output, name in parity_file_names(surrogates).items()
    ]
