"""Pictures of a plan's dispersed Monte Carlo, drawn from its stored runs.

* the landing footprint: where each run reached the terminal interface, east and north
  of the landing site in km. The projection is azimuthal equidistant about the site on
  the sphere the landing miss is measured on, so a point's distance from the site is its
  miss and the stated miss is a circle. The closed and the open loop have their own
  colours, and the site's runway is drawn (``configs/montecarlo_plots.yaml``). Two
  panels: every landing, and the site itself
  (``footprint.zoom_half_width_stated_miss`` stated misses either way);
* the dV per manoeuvre: a histogram of the dV each manoeuvre spent over the runs that
  flew it, a panel per manoeuvre and one for the total, both loops on the same bins,
  the plan's value as a dashed line.

Data in, figures out: the caller reads the points and values from the stored run
(:mod:`ovtraj.runs.plan_monte_carlo`), so a picture depends on its inputs alone and its
PNG is the same wherever it is drawn (:mod:`ovtraj.plots.render`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ovtraj.config.montecarlo_plots import Runway
from ovtraj.plots.render import figure
from ovtraj.reentry.dynamics import range_and_bearing
from ovtraj.units import M_PER_KM

__all__ = ["LOOPS", "LandingPoints", "Site", "dv_figure", "footprint_figure", "site_offsets_km"]

# loop -> (colour, legend text)
LOOPS = {"closed": ("tab:blue", "closed loop"), "open": ("tab:orange", "open loop")}
_SITE_COLOUR = "tab:purple"
_MISS_COLOUR = "tab:green"
_RUNWAY_COLOUR = "0.15"


@dataclass(frozen=True)
class Site:
    """The landing site and the sphere its miss is measured on."""

    name: str
    latitude_deg: float
    longitude_deg: float
    radius_m: float


@dataclass(frozen=True)
class LandingPoints:
    """One loop: how many runs flew it, and where those that landed reached the terminal
    interface (geocentric [deg], one entry per landed run)."""

    runs: int
    latitude_deg: NDArray[np.float64]
    longitude_deg: NDArray[np.float64]


def site_offsets_km(
    site: Site, latitude_deg: NDArray[np.float64], longitude_deg: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points east and north of ``site`` [km]: the great-circle distance from the site
    along the initial bearing (azimuthal equidistant projection)."""
    east, north = [], []
    lat0, lon0 = math.radians(site.latitude_deg), math.radians(site.longitude_deg)
    for lat, lon in zip(latitude_deg, longitude_deg, strict=True):
        angle, bearing = range_and_bearing(lat0, lon0, math.radians(lat), math.radians(lon))
        distance = angle * site.radius_m / M_PER_KM
        east.append(distance * math.sin(bearing))
        north.append(distance * math.cos(bearing))
    return np.array(east, dtype=float), np.array(north, dtype=float)


def footprint_figure(
    loops: dict[str, LandingPoints],
    site: Site,
    stated_miss_m: float,
    runway: Runway | None,
    zoom_stated_misses: float,
    title: str,
) -> Any:
    """The landing footprint (module notes): ``loops`` by ``closed``/``open``, each loop's
    landed runs as one scatter labelled ``<loop>: <landed> of <runs> landed``."""
    fig = figure((12.0, 6.2))
    every, near = fig.subplots(1, 2)
    offsets = {
        loop: site_offsets_km(site, p.latitude_deg, p.longitude_deg) for loop, p in loops.items()
    }
    stated_km = stated_miss_m / M_PER_KM
    half = zoom_stated_misses * stated_km
    for ax in (every, near):
        _site_features(ax, site, stated_km, runway)
        for loop, (east, north) in offsets.items():
            colour, text = LOOPS[loop]
            ax.scatter(
                east,
                north,
                s=14,
                color=colour,
                alpha=0.8,
                zorder=3,
                label=f"{text}: {len(east)} of {loops[loop].runs} landed",
            )
        ax.set_xlabel("east of the site [km]")
        ax.set_ylabel("north of the site [km]")
        ax.grid(True, alpha=0.3)
    every.set_aspect("equal", adjustable="datalim")
    every.set_title("every landing", fontsize=10)
    near.set_xlim(-half, half)
    near.set_ylim(-half, half)
    near.set_aspect("equal", adjustable="box")
    inside = sum(
        int(np.sum((np.abs(east) <= half) & (np.abs(north) <= half)))
        for east, north in offsets.values()
    )
    landed = sum(len(east) for east, _ in offsets.values())
    near.set_title(f"at the site (+-{half:g} km): {inside} of {landed} landings", fontsize=10)
    every.legend(loc="best", fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def _site_features(ax: Any, site: Site, stated_km: float, runway: Runway | None) -> None:
    """The stated-miss circle, the runway and the site's point."""
    from matplotlib.patches import Circle, Polygon

    ax.add_patch(
        Circle(
            (0.0, 0.0),
            stated_km,
            fill=False,
            linestyle="--",
            color=_MISS_COLOUR,
            label=f"stated miss {stated_km:g} km",
        )
    )
    if runway is not None:
        heading = math.radians(runway.heading_deg)
        along = np.array([math.sin(heading), math.cos(heading)]) * runway.length_m / 2 / M_PER_KM
        across = np.array([math.cos(heading), -math.sin(heading)]) * runway.width_m / 2 / M_PER_KM
        corners = [along + across, along - across, -along - across, -along + across]
        ax.add_patch(
            Polygon(
                corners,
                closed=True,
                color=_RUNWAY_COLOUR,
                linewidth=1.5,
                zorder=2,
                label=f"runway {runway.designation} ({runway.length_m / M_PER_KM:g} km)",
            )
        )
    ax.plot(
        [0.0],
        [0.0],
        marker="+",
        markersize=10,
        color=_SITE_COLOUR,
        linestyle="none",
        label=site.name,
    )


def dv_figure(
    spent: dict[str, dict[str, NDArray[np.float64]]],
    planned: dict[str, float | None],
    title: str,
) -> Any:
    """The dV histograms (module notes): ``spent[manoeuvre][loop]`` the dV [m/s] of the
    runs of that loop that flew it, ``planned[manoeuvre]`` the plan's. Each loop's
    histogram is one bar container labelled ``<loop> (<n> runs)``."""
    names = list(spent)
    columns = 2
    rows = math.ceil(len(names) / columns)
    fig = figure((10.0, 2.6 * rows + 0.6))
    axes = np.atleast_1d(fig.subplots(rows, columns)).ravel()
    for ax, name in zip(axes, names, strict=False):
        loops = {loop: np.asarray(v, dtype=float) for loop, v in spent[name].items()}
        values = np.concatenate([*loops.values(), np.empty(0)])
        plan = planned.get(name)
        if len(values):
            edges = np.histogram_bin_edges(values, bins="auto")
            for loop, flown in loops.items():
                colour, text = LOOPS[loop]
                ax.hist(
                    flown,
                    bins=edges,
                    color=colour,
                    alpha=0.55,
                    label=f"{text} ({len(flown)} runs)",
                )
        else:
            ax.text(0.5, 0.5, "no run flew it", transform=ax.transAxes, ha="center")
        if plan is not None:
            ax.axvline(plan, color="k", linestyle="--", label=f"planned {plan:.2f} m/s")
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("dV [m/s]")
        ax.set_ylabel("runs")
        ax.legend(loc="best", fontsize=7)
        ax.grid(True, alpha=0.3)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    return fig
