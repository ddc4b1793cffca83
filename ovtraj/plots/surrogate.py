"""Parity plots of the selected surrogates: predicted against true value, one PNG per output.

Cross-validation points (each predicted by the model fitted without its fold) are hollow
circles, held-out points (predicted by the final model, never used in fitting or
selection) filled triangles; the diagonal is the 1:1 line. The title names the selected
candidate, its Q² (k-fold) and its held-out R² ("n/a" when undefined: fewer than 2
held-out feasible samples or no spread in them).
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ovtraj.files import write_bytes
from ovtraj.storage import location
from ovtraj.surrogate import SurrogateSet

__all__ = ["parity_plots"]


def _file_name(output: str, taken: set[str]) -> str:
    stem = "parity-" + (re.sub(r"[^A-Za-z0-9_.-]+", "_", output).strip("._") or "output")
    name, k = f"{stem}.png", 2
    while name in taken:
        name, k = f"{stem}-{k}.png", k + 1
    taken.add(name)
    return name


def _metric(value: object) -> str:
    return "n/a" if value is None or pd.isna(value) else f"{float(value):.4f}"


def parity_plots(surrogates: SurrogateSet, directory: Path) -> list[Path]:
    """Write ``parity-<output>.png`` for every output of ``surrogates``; return the paths.

    Each file is rendered in memory and written atomically (temporary name, then rename).
    """
    from matplotlib.figure import Figure  # no pyplot: no global state, nothing to close

    directory = location(directory)
    directory.mkdir(parents=True, exist_ok=True)
    table = surrogates.predictions
    validation = surrogates.validation
    taken: set[str] = set()
    paths = []
    for output in surrogates.output_names:
        rows = table[table["model"] == output]
        candidate = surrogates.selected[output]
        chosen = validation[(validation["model"] == output) & validation["selected"]].iloc[0]
        fig = Figure(figsize=(5.6, 5.4), constrained_layout=True)
        ax = fig.subplots()
        for split, style in (
            ("cv", {"marker": "o", "facecolors": "none", "edgecolors": "C0", "s": 28}),
            ("heldout", {"marker": "^", "color": "C3", "s": 36}),
        ):
            part = rows[rows["split"] == split]
            label = "k-fold CV" if split == "cv" else "held out"
            ax.scatter(part["y_true"], part["y_pred"], label=f"{label} ({len(part)})", **style)
        values = np.concatenate([rows["y_true"].to_numpy(float), rows["y_pred"].to_numpy(float)])
        low, high = float(values.min()), float(values.max())
        pad = (high - low) * 0.05 or abs(high) * 0.05 or 1.0
        line = [low - pad, high + pad]
        ax.plot(line, line, "k-", lw=0.8, label="1:1")
        ax.set_xlim(line)
        ax.set_ylim(line)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{output} (true)")
        ax.set_ylabel(f"{output} (predicted)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=9)
        ax.set_title(
            f"{output}: {candidate}, Q² = {_metric(chosen['cv_q2'])}, "
            f"held-out R² = {_metric(chosen['heldout_r2'])}",
            fontsize=10,
        )
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=100)
        path = directory / _file_name(output, taken)
        write_bytes(path, buffer.getvalue(), replace=True)
        paths.append(path)
    return paths
