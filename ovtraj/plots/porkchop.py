"""Porkchop plots: costs as filled contours over the launch day and a design variable.

One panel per cost (the caller's labelled grids), the launch day along x, the swept
variable along y. The contours fill between neighbouring days; every evaluated grid
point is also a small dot in its value's colour, so a day whose neighbours have no data
still shows. Each day's chosen design is a white circle, the best day's a red star, a
day without one a grey cross on the x axis, an infeasible grid point a small black dot.
Drawn from the given data alone (no wall clock), so the same data give the same bytes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime, timedelta
from typing import Any

import numpy as np

from ovtraj.plots.launch_days import mark_days_without_plan
from ovtraj.plots.render import figure

__all__ = ["porkchop_figure"]

LEVELS = 12  # filled contour levels a panel (matplotlib's MaxNLocator picks round values)


def porkchop_figure(
    dates: Sequence[str],
    values: np.ndarray,
    y_label: str,
    panels: Mapping[str, np.ndarray],
    *,
    chosen: Mapping[int, float],
    best: int | None,
    infeasible: np.ndarray,
    title: str,
) -> Any:
    """The Figure: a panel per ``panels`` item (colour-bar label -> array of
    ``(len(values), len(dates))``, NaN where nothing was evaluated or the design is
    infeasible) over ``dates`` (``YYYY-MM-DD``) and ``values``; ``chosen``: column ->
    the chosen design's value of the variable; ``best``: the best column (None: none);
    ``infeasible``: the grid points to dot."""
    from matplotlib.dates import date2num

    days = [datetime.fromisoformat(d) for d in dates]  # 0 h UTC of each day
    # One day is a band a day wide, its one column repeated: a contour needs two columns.
    half = timedelta(hours=12)
    x = date2num(days if len(days) > 1 else [days[0] - half, days[0] + half])
    fig = figure((7.0 * len(panels), 5.2))
    axes = np.atleast_1d(fig.subplots(1, len(panels), sharey=True))
    for ax, (label, grid) in zip(axes, panels.items(), strict=True):
        _contours(fig, ax, x, days, values, label, grid, bool(chosen))
        _marks(ax, dates, days, values, chosen=chosen, best=best, infeasible=infeasible)
        _day_axes(ax, x, days, values, label)
    axes[0].set_ylabel(y_label)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=len(handles), fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def _contours(
    fig: Any,
    ax: Any,
    x: np.ndarray,
    days: list[datetime],
    values: np.ndarray,
    label: str,
    grid: np.ndarray,
    planned: bool,
) -> None:
    """One cost's filled contours with its colour bar and every evaluated point a dot in
    its colour; or why there is nothing to draw."""
    from matplotlib.dates import date2num

    z = np.asarray(grid, dtype=float)
    z = z if len(days) > 1 else np.repeat(z, 2, axis=1)
    if np.isfinite(z).any():
        filled = ax.contourf(x, values, np.ma.masked_invalid(z), levels=LEVELS, cmap="viridis")
        fig.colorbar(filled, ax=ax, label=label)
        k, j = np.nonzero(np.isfinite(grid))
        ax.scatter(
            date2num([days[i] for i in j]),
            values[k],
            c=np.asarray(grid)[k, j],
            cmap=filled.cmap,
            norm=filled.norm,
            s=6,
            linewidths=0,
            label="evaluated design (its colour)",
        )
    else:
        empty = "nothing feasible" if planned else "no day has a plan: nothing swept"
        ax.text(0.5, 0.5, empty, transform=ax.transAxes, ha="center")


def _marks(
    ax: Any,
    dates: Sequence[str],
    days: list[datetime],
    values: np.ndarray,
    *,
    chosen: Mapping[int, float],
    best: int | None,
    infeasible: np.ndarray,
) -> None:
    """The infeasible grid points, each day's plan, the best day's and the days without
    one."""
    from matplotlib.dates import date2num

    k, j = np.nonzero(infeasible)
    if len(j):
        ax.plot(
            date2num([days[i] for i in j]),
            values[k],
            linestyle="none",
            marker=".",
            markersize=3,
            color="k",
            label="infeasible design",
        )
    planned = sorted(chosen)
    if planned:
        ax.plot(
            date2num([days[i] for i in planned]),
            [chosen[i] for i in planned],
            linestyle="none",
            marker="o",
            markerfacecolor="white",
            markeredgecolor="k",
            label="the day's plan",
            gid="chosen",
        )
    if best is not None:
        ax.plot(
            date2num([days[best]]),
            [chosen[best]],
            linestyle="none",
            marker="*",
            markersize=16,
            color="tab:red",
            markeredgecolor="k",
            label=f"best day {dates[best]}",
            gid="best",
        )
    missing = [i for i in range(len(days)) if i not in chosen]
    if missing:
        mark_days_without_plan(ax, date2num([days[i] for i in missing]))


def _day_axes(ax: Any, x: np.ndarray, days: list[datetime], values: np.ndarray, label: str) -> None:
    """Limits (the days, the swept values with a margin), day ticks and the labels."""
    from matplotlib.dates import DateFormatter, DayLocator

    margin = 0.5 if len(days) > 1 else 0.0  # half a day each side; one day's band fills
    ax.set_xlim(x[0] - margin, x[-1] + margin)
    pad = 0.03 * (values[-1] - values[0])  # a plan at a bound shows whole
    ax.set_ylim(values[0] - pad, values[-1] + pad)
    ax.xaxis.set_major_locator(DayLocator(interval=max(1, -(-len(days) // 8))))
    ax.xaxis.set_major_formatter(DateFormatter("%Y-%m-%d"))
    ax.tick_params(axis="x", labelrotation=30)
    ax.set_xlabel("launch day (UTC)")
    ax.set_title(label.split(" [")[0])
