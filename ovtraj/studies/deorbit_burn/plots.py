"""Plots of the Monte Carlo entry errors (seed figs. 14-17): one PNG per strategy.

Each figure has three panels: the scatter of the along-track error [km] (entry u error times
r_E; the top axis gives the u error [deg]) against the flight-path-angle error [deg], and
the two histograms. matplotlib's Agg backend: no display is needed.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import pandas as pd

from ovtraj.store.files import write_bytes

__all__ = ["plot_dispersions"]


def plot_dispersions(
    frame: pd.DataFrame,
    directory: str | Path,
    entry_radius_m: float,
    *,
    bins: int = 30,
) -> list[Path]:
    """Write ``strategy-<k>.png`` for each strategy of ``frame`` (``RUN_SCHEMA`` rows).

    ``entry_radius_m`` [m] converts km of along-track error to deg of u for the top axis.
    Returns the written paths.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    km_per_deg = math.radians(1.0) * entry_radius_m / 1e3
    paths = []
    for strategy, group in frame.groupby("strategy", sort=True):
        good = group[group["ok"]]
        along = good["along_track_error_km"].to_numpy(dtype=float)
        fpa = good["entry_fpa_error_deg"].to_numpy(dtype=float)
        fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), constrained_layout=True)
        scatter, hist_u, hist_fpa = axes
        scatter.scatter(along, fpa, s=10, alpha=0.7)
        scatter.set_xlabel("along-track error at entry [km]")
        scatter.set_ylabel("entry flight-path angle error [deg]")
        scatter.grid(True, alpha=0.3)
        top = scatter.secondary_xaxis(
            "top", functions=(lambda x: x / km_per_deg, lambda x: x * km_per_deg)
        )
        top.set_xlabel("entry argument-of-latitude error [deg]")
        top.xaxis.set_major_locator(MaxNLocator(4))
        hist_u.hist(along, bins=bins)
        hist_u.set_xlabel("along-track error at entry [km]")
        hist_u.set_ylabel("runs")
        hist_fpa.hist(fpa, bins=bins)
        hist_fpa.set_xlabel("entry flight-path angle error [deg]")
        hist_fpa.set_ylabel("runs")
        for axis in (scatter.yaxis, hist_fpa.xaxis):
            # fpa errors of ~1e-4 deg: an offset and few ticks keep the labels apart.
            axis.set_major_locator(MaxNLocator(5))
            axis.get_major_formatter().set_powerlimits((-2, 3))
        cut = "predicted entry u" if int(strategy) == 1 else "predicted entry fpa"
        fig.suptitle(
            f"Strategy {int(strategy)} (cut-off on the {cut}): {len(good)} runs, "
            f"{len(group) - len(good)} failed"
        )
        path = directory / f"strategy-{int(strategy)}.png"
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=100)
        plt.close(fig)
        write_bytes(path, buffer.getvalue(), replace=True)
        paths.append(path)
    return paths
