"""Mission plots from the chain's trajectory tables (``MissionRecord.trajectories``).

Three PNGs (matplotlib's Agg canvas, no pyplot state; each written to a temporary
name and renamed; :func:`mission_figures` gives the Figures themselves):

* ``<prefix>_profile.png``: altitude against time from the launch day's 0 h [h], and
  altitude against speed, every stage and phase in its own colour;
* ``<prefix>_ground_track.png``: the ground track (geocentric longitude and latitude,
  spherical Earth) over the coastlines (Natural Earth 1:110m, :mod:`ovtraj.plots.coastlines`),
  the phases coloured, with the entry region (the deorbit's box), the entry point, the
  terminal point and the landing site; a second panel zooms on the entry region, the
  reentry and the landing site;
* ``<prefix>_reentry_corridor.png``: the reentry in the altitude-speed plane with the
  dynamic-pressure, load-factor and heat-rate limits drawn as boundary curves (the
  reentry's own vehicle, angle-of-attack schedule and atmosphere model), each labelled
  with its value from ``reentry.limits``, the entry interface and the terminal interface.

The tables are the stages' own (the run store keeps the same ones): the rendezvous
and transfer tables count seconds from the launch day's 0 h, the deorbit's from its
start (the transfer's arrival) and the reentry's from the entry (the deorbit's last
row); the plots chain these offsets. A missing stage is left out. Every physical value
drawn (limits, entry region, landing site, interfaces) comes from the scenario; titles
name the scenario and its launch day (or epoch), never the wall clock.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.angles import wrap_to_pi
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.frames import great_circle_distance
from ovtraj.config import Scenario
from ovtraj.config.deorbit import EntryRegionConfig
from ovtraj.plots.coastlines import draw_coastlines, split_at_wrap, with_breaks
from ovtraj.plots.render import figure, write_png
from ovtraj.store.backends import location
from ovtraj.units import S_PER_HOUR

__all__ = ["PHASES", "limit_labels", "mission_figures", "mission_plots", "scenario_when"]

# (stage, phase) -> colour and legend text; the phases are the tables' ``phase`` column.
PHASES: dict[tuple[str, str], tuple[str, str]] = {
    ("rendezvous", "wait"): ("tab:blue", "rendezvous: phasing in the parking orbit"),
    ("rendezvous", "transfer"): ("tab:cyan", "rendezvous: transfer to the target"),
    ("transfer", "wait"): ("tab:green", "after separation: in the target's orbit"),
    ("transfer", "transfer"): ("tab:olive", "transfer to the preparation orbit"),
    ("deorbit", "preparation"): ("tab:orange", "deorbit: preparation orbit"),
    ("deorbit", "descent"): ("tab:brown", "deorbit: descent to the entry interface"),
    ("reentry", "reentry"): ("tab:red", "reentry"),
}
_STAGE_COLOURS = {"rendezvous": "tab:blue", "transfer": "tab:green", "deorbit": "tab:orange"}
_ORBITAL = ("rendezvous", "transfer", "deorbit")
_COASTS = ("wait", "preparation")  # phases that last many revolutions
_ZOOM_MARGIN_DEG = 6.0  # around the entry region, the reentry and the landing site
_SITE = "tab:purple"


def mission_figures(trajectories: dict[str, pd.DataFrame], scenario: Scenario) -> dict[str, Any]:
    """The three mission Figures: ``profile``, ``ground_track``, ``reentry_corridor``."""
    tracks = _tracks(trajectories, scenario)
    return {
        "profile": _profile(tracks, scenario),
        "ground_track": _ground_track(tracks, scenario),
        "reentry_corridor": _corridor(trajectories.get("reentry"), scenario),
    }


def mission_plots(
    trajectories: dict[str, pd.DataFrame],
    scenario: Scenario,
    directory: Path,
    prefix: str = "mission",
) -> list[Path]:
    """Write the three mission plots into ``directory``; returns their paths."""
    directory = location(directory)
    figures = mission_figures(trajectories, scenario)
    return [write_png(fig, directory / f"{prefix}_{name}.png") for name, fig in figures.items()]


def _nonempty(table: pd.DataFrame | None) -> bool:
    return table is not None and len(table) > 0


def _tracks(trajectories: dict[str, pd.DataFrame], scenario: Scenario) -> dict[str, pd.DataFrame]:
    """Per stage: time from the launch day's 0 h [s], altitude [m], speed, lat/lon [deg]."""
    earth = scenario.earth
    day = _launch_day(scenario)
    theta0 = day.gmst_rad()
    tracks: dict[str, pd.DataFrame] = {}
    offset: float | None = None
    for stage in ("rendezvous", "transfer"):
        table = trajectories.get(stage)
        if not _nonempty(table):
            continue
        t = table["t_s"].to_numpy(dtype=float)
        r = table[["chaser_x_m", "chaser_y_m", "chaser_z_m"]].to_numpy(dtype=float)
        v = table[["chaser_vx_mps", "chaser_vy_mps", "chaser_vz_mps"]].to_numpy(dtype=float)
        lat = np.degrees(np.arctan2(r[:, 2], np.hypot(r[:, 0], r[:, 1])))
        lon = np.degrees(wrap_to_pi(np.arctan2(r[:, 1], r[:, 0]) - theta0 - earth.omega * t))
        tracks[stage] = pd.DataFrame(
            {
                "t_s": t,
                "altitude_m": np.linalg.norm(r, axis=1) - earth.radius,
                "speed_mps": np.linalg.norm(v, axis=1),
                "latitude_deg": lat,
                "longitude_deg": lon,
                "phase": table["phase"].to_numpy() if "phase" in table else stage,
            }
        )
        if stage == "transfer":
            offset = float(t[-1])  # the deorbit starts at the transfer's arrival
    for stage in ("deorbit", "reentry"):
        table = trajectories.get(stage)
        if not _nonempty(table) or offset is None:
            offset = None
            continue
        t = table["time_s"].to_numpy(dtype=float) + offset
        tracks[stage] = pd.DataFrame(
            {
                "t_s": t,
                "altitude_m": table["altitude_km"].to_numpy(dtype=float) * 1e3,
                "speed_mps": table["speed_mps"].to_numpy(dtype=float),
                "latitude_deg": table["latitude_deg"].to_numpy(dtype=float),
                "longitude_deg": _wrap_deg(table["longitude_deg"].to_numpy(dtype=float)),
                "phase": table["phase"].to_numpy() if "phase" in table else stage,
            }
        )
        offset = float(t[-1])  # the reentry starts at the deorbit's entry
    return tracks


def _launch_day(scenario: Scenario) -> Epoch:
    if scenario.launch is not None:
        return Epoch.from_iso(scenario.launch.launch_date_utc)
    return scenario.epoch


def scenario_when(scenario: Scenario) -> str:
    """The scenario's name and day, from the config (never the wall clock)."""
    if scenario.launch is not None:
        return f"scenario {scenario.name}, launch day {scenario.launch.launch_date_utc}"
    return f"scenario {scenario.name}, epoch {scenario.epoch_utc}"


def _wrap_deg(angle: np.ndarray | float) -> np.ndarray:
    """Degrees into [-180, 180)."""
    return (np.asarray(angle, dtype=float) + 180.0) % 360.0 - 180.0


def _segments(tracks: dict[str, pd.DataFrame]) -> list[tuple[str, str, pd.DataFrame]]:
    """(stage, phase, rows) for every run of consecutive rows of one phase, in time order."""
    out = []
    for stage, track in tracks.items():
        phase = track["phase"].astype(str).to_numpy()
        starts = np.r_[0, np.flatnonzero(phase[1:] != phase[:-1]) + 1]
        ends = np.r_[starts[1:], len(track)]
        for a, b in zip(starts, ends, strict=True):
            # keep the next run's first row: the line has no gap at the phase change
            out.append((stage, str(phase[a]), track.iloc[a : min(b + 1, len(track))]))
    return out


def _style(stage: str, phase: str) -> tuple[str, str]:
    if (stage, phase) in PHASES:
        return PHASES[(stage, phase)]
    if stage == "reentry":
        return PHASES[("reentry", "reentry")]
    return _STAGE_COLOURS.get(stage, "0.3"), f"{stage}: {phase}"


def _profile(tracks: dict[str, pd.DataFrame], scenario: Scenario) -> Any:
    fig = figure((13.0, 5.6))
    left, right = fig.subplots(1, 2)
    for stage, phase, rows in _segments(tracks):
        colour, label = _style(stage, phase)
        if stage == "reentry":
            label += " (Earth-relative speed)"
        altitude = rows["altitude_m"] / 1e3
        left.plot(rows["t_s"] / S_PER_HOUR, altitude, color=colour, lw=1.0, label=label)
        right.plot(rows["speed_mps"], altitude, color=colour, lw=1.0)
    if "rendezvous" in tracks and "transfer" in tracks:
        docked = (tracks["rendezvous"]["t_s"].iloc[-1], tracks["transfer"]["t_s"].iloc[0])
        left.axvspan(
            docked[0] / S_PER_HOUR, docked[1] / S_PER_HOUR, color="0.85", label="docked (stay)"
        )
    left.set_xlabel("time from the launch day's 0 h UTC [h]")
    left.set_ylabel("altitude [km]")
    left.set_title("altitude against time")
    right.set_xlabel("speed [m/s] (inertial in orbit)")
    right.set_ylabel("altitude [km]")
    right.set_title("altitude against speed")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    entries = _legend_entries(left)
    if entries:
        fig.legend(
            list(entries.values()), list(entries), loc="outside lower center", ncols=4, fontsize=8
        )
    fig.suptitle(f"Mission profile: {scenario_when(scenario)}")
    return fig


def _legend_entries(ax: Any) -> dict[str, Any]:
    """Label -> handle of an axes' artists, each label once (first-drawn order)."""
    handles, labels = ax.get_legend_handles_labels()
    entries: dict[str, Any] = {}
    for handle, label in zip(handles, labels, strict=True):
        entries.setdefault(label, handle)
    return entries


def _line(ax: Any, lon: np.ndarray, lat: np.ndarray, centre: float, **style: Any) -> None:
    """A lon/lat line drawn in the frame centred on ``centre`` [deg], cut at its edges."""
    pieces = split_at_wrap(_wrap_deg(lon - centre), lat)
    x, y = with_breaks([(x + centre, y) for x, y in pieces])
    ax.plot(x, y, **style)


def _boxes(lon: float, lat: float, dlon: float, dlat: float, centre: float) -> list[list[float]]:
    """[lon0, lon1, lat0, lat1] of a box in the frame centred on ``centre``, cut at its edges."""
    mid = float(_wrap_deg(lon - centre))
    lon0, lon1 = mid - dlon, mid + dlon
    spans = [(lon0, lon1)]
    if lon0 < -180.0:
        spans = [(lon0 + 360.0, 180.0), (-180.0, lon1)]
    elif lon1 > 180.0:
        spans = [(lon0, 180.0), (-180.0, lon1 - 360.0)]
    return [[a + centre, b + centre, lat - dlat, lat + dlat] for a, b in spans]


def _point(lon: float, centre: float) -> float:
    return float(_wrap_deg(lon - centre)) + centre


def _draw_map(ax: Any, tracks: dict[str, pd.DataFrame], scenario: Scenario, centre: float) -> None:
    """Coastlines, the phases, the entry region and the points on a lon/lat axes."""
    draw_coastlines(ax, centre=centre)
    _draw_phases(ax, tracks, centre)
    if scenario.deorbit is not None:
        _draw_entry_region(ax, scenario.deorbit.entry, centre)
    _draw_landing(ax, tracks.get("reentry"), scenario, centre)
    ax.set_xlabel("longitude [deg east]")
    ax.set_ylabel("geocentric latitude [deg]")
    ax.grid(True, alpha=0.3, zorder=0.0)


def _draw_phases(ax: Any, tracks: dict[str, pd.DataFrame], centre: float) -> None:
    """Each stage's phases as lines in their colours: long coasts thin (tens of
    revolutions), transfers medium, the way down bold."""
    for stage, phase, rows in _segments(tracks):
        colour, label = _style(stage, phase)
        weight = 0 if phase in _COASTS else 1 if stage in _ORBITAL and phase != "descent" else 2
        _line(
            ax,
            rows["longitude_deg"].to_numpy(dtype=float),
            rows["latitude_deg"].to_numpy(dtype=float),
            centre,
            color=colour,
            lw=(0.5, 1.2, 1.8)[weight],
            alpha=(0.55, 0.9, 1.0)[weight],
            zorder=2.0 + weight,
            label=label,
        )


def _draw_entry_region(ax: Any, entry: EntryRegionConfig, centre: float) -> None:
    """The deorbit's entry region (its box of latitude and longitude tolerances), one
    legend entry however the frame's edge cuts it."""
    label = (
        f"entry region ({entry.latitude_deg:g} ± {entry.latitude_tolerance_deg:g}° lat, "
        f"{entry.longitude_deg:g} ± {entry.longitude_tolerance_deg:g}° lon, "
        f"{entry.altitude_km:g} km)"
    )
    for lon0, lon1, lat0, lat1 in _boxes(
        entry.longitude_deg,
        entry.latitude_deg,
        entry.longitude_tolerance_deg,
        entry.latitude_tolerance_deg,
        centre,
    ):
        ax.fill(
            [lon0, lon1, lon1, lon0],
            [lat0, lat0, lat1, lat1],
            facecolor="gold",
            edgecolor="darkgoldenrod",
            lw=1.5,
            alpha=0.75,
            zorder=3.5,
            label=label,
        )
        label = "_"  # one legend entry


def _draw_landing(ax: Any, reentry: pd.DataFrame | None, scenario: Scenario, centre: float) -> None:
    """The landing site, and the reentry's entry and terminal points (the terminal one
    with its distance from the site)."""
    site = scenario.reentry.landing_site if scenario.reentry is not None else None
    if site is not None:
        ax.plot(
            _point(site.longitude_deg, centre),
            site.latitude_deg,
            "o",
            ms=15,
            mfc="none",
            mec=_SITE,
            mew=2.0,
            zorder=5.0,
            label=f"landing site: {site.name}",
        )
    if reentry is None:
        return
    first, last = reentry.iloc[0], reentry.iloc[-1]
    ax.plot(
        _point(first["longitude_deg"], centre),
        first["latitude_deg"],
        "^",
        color="k",
        ms=8,
        zorder=6.0,
        label="entry point",
    )
    label = "terminal point"
    if site is not None:
        miss_m = great_circle_distance(
            math.radians(last["latitude_deg"]),
            math.radians(last["longitude_deg"]),
            math.radians(site.latitude_deg),
            math.radians(site.longitude_deg),
            radius=scenario.earth.radius,
        )
        label += f" ({miss_m / 1e3:.1f} km from the site)"
    ax.plot(
        _point(last["longitude_deg"], centre),
        last["latitude_deg"],
        "D",
        color="k",
        mfc="yellow",
        ms=5,
        zorder=7.0,
        label=label,
    )


def _zoom_extent(
    tracks: dict[str, pd.DataFrame], scenario: Scenario
) -> tuple[float, list[float]] | None:
    """(centre longitude, [lon0, lon1, lat0, lat1]) around the reentry and its targets."""
    lon, lat = [], []
    if "reentry" in tracks:
        lon.extend(tracks["reentry"]["longitude_deg"])
        lat.extend(tracks["reentry"]["latitude_deg"])
    if scenario.reentry is not None:
        lon.append(scenario.reentry.landing_site.longitude_deg)
        lat.append(scenario.reentry.landing_site.latitude_deg)
    if scenario.deorbit is not None:
        entry = scenario.deorbit.entry
        for s in (-1.0, 1.0):
            lon.append(entry.longitude_deg + s * entry.longitude_tolerance_deg)
            lat.append(entry.latitude_deg + s * entry.latitude_tolerance_deg)
    if not lon:
        return None
    lon_arr = _wrap_deg(np.asarray(lon, dtype=float))
    # centre: the circular mean, so that a region across +-180 deg stays in one piece
    centre = math.degrees(
        math.atan2(np.mean(np.sin(np.radians(lon_arr))), np.mean(np.cos(np.radians(lon_arr))))
    )
    x = _wrap_deg(lon_arr - centre) + centre
    m = _ZOOM_MARGIN_DEG
    return centre, [
        float(x.min()) - m,
        float(x.max()) + m,
        max(float(min(lat)) - m, -90.0),
        min(float(max(lat)) + m, 90.0),
    ]


def _wrapped_ticks(ax: Any) -> None:
    from matplotlib.ticker import FuncFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{float(_wrap_deg(v)):g}"))


def _ground_track(tracks: dict[str, pd.DataFrame], scenario: Scenario) -> Any:
    zoom = _zoom_extent(tracks, scenario)
    fig = figure((12.0, 12.5 if zoom else 7.5))
    if zoom:
        world, near = fig.subplots(2, 1, height_ratios=[1.0, 1.15])
    else:
        world, near = fig.subplots(), None
    _draw_map(world, tracks, scenario, centre=0.0)
    world.set_xlim(-180.0, 180.0)
    world.set_ylim(-90.0, 90.0)
    world.set_xticks(np.arange(-180.0, 181.0, 30.0))
    world.set_yticks(np.arange(-90.0, 91.0, 30.0))
    world.set_aspect("equal")
    world.set_title("Ground track (spherical Earth; coastlines: Natural Earth 1:110m)")
    if near is not None and zoom is not None:
        centre, (lon0, lon1, lat0, lat1) = zoom
        for a, b, c, d in _boxes(
            0.5 * (lon0 + lon1), 0.5 * (lat0 + lat1), 0.5 * (lon1 - lon0), 0.5 * (lat1 - lat0), 0.0
        ):
            world.plot([a, b, b, a, a], [c, c, d, d, c], "k--", lw=0.9, zorder=4.5)
        _draw_map(near, tracks, scenario, centre=centre)
        near.set_xlim(lon0, lon1)
        near.set_ylim(lat0, lat1)
        near.set_aspect("equal")
        _wrapped_ticks(near)
        near.set_title("Entry region, reentry and landing site (dashed box above)")
    entries = _legend_entries(world)
    entries["coastlines (Natural Earth 1:110m)"] = world.plot([], [], color="0.55", lw=0.6)[0]
    fig.legend(
        list(entries.values()),
        list(entries),
        loc="outside lower center",
        ncols=3,
        fontsize=8,
    )
    fig.suptitle(f"Ground track: {scenario_when(scenario)}")
    return fig


def _limit_fields(
    scenario: Scenario, speeds: np.ndarray, altitudes: np.ndarray
) -> dict[str, np.ndarray]:
    """Heat rate [W/m^2], load [g] and dynamic pressure [Pa] over a speed-altitude grid."""
    from ovtraj.reentry import dynamics as dyn
    from ovtraj.reentry import reentry_input
    from ovtraj.reentry.model import EntryModel

    model = EntryModel(reentry_input(scenario))
    p, tables = model.params, model.tables
    fields = {name: np.empty((len(altitudes), len(speeds))) for name in ("heat", "load", "q")}
    x = np.zeros(6)
    for i, h in enumerate(altitudes):
        x[0] = p[dyn.P_RADIUS] + h
        for j, v in enumerate(speeds):
            x[3] = v
            _, _, _, heat, load, qdyn = dyn._path(x, p, tables)
            fields["heat"][i, j], fields["load"][i, j], fields["q"][i, j] = heat, load, qdyn
    return fields


def limit_labels(scenario: Scenario) -> dict[str, str]:
    """Legend text of each reentry limit with its value and unit (``reentry.limits``)."""
    limits = scenario.reentry.limits
    return {
        "q": f"dynamic pressure limit q_max = {limits.max_dynamic_pressure_kpa:g} kPa",
        "load": f"load factor limit n_max = {limits.max_load_g:g} g",
        "heat": f"heat-rate limit {limits.max_heat_rate_kw_m2:g} kW/m²",
    }


def _corridor(table: pd.DataFrame | None, scenario: Scenario) -> Any:
    fig = figure((9.0, 6.6))
    track = None
    if _nonempty(table):
        track = pd.DataFrame(
            {
                "speed_mps": table["speed_mps"].to_numpy(dtype=float),
                "altitude_m": table["altitude_km"].to_numpy(dtype=float) * 1e3,
            }
        )
    ax = fig.subplots()
    settings = scenario.reentry
    if settings is None:
        ax.set_title("Reentry corridor (no reentry section in the scenario)")
        return fig
    entry_m = (
        scenario.deorbit.entry.altitude_km * 1e3
        if scenario.deorbit is not None
        else settings.entry.altitude_km * 1e3
    )
    v_top = float(track["speed_mps"].max()) if track is not None else settings.entry.speed_mps
    speeds = np.linspace(0.5 * settings.terminal.speed_mps, 1.05 * v_top, 160)
    altitudes = np.linspace(0.0, 1.05 * entry_m, 160)
    fields = _limit_fields(scenario, speeds, altitudes)
    limits = settings.limits
    labels = limit_labels(scenario)
    for key, level, colour in (
        ("q", limits.max_dynamic_pressure_kpa * 1e3, "C0"),
        ("load", limits.max_load_g, "C2"),
        ("heat", limits.max_heat_rate_kw_m2 * 1e3, "C3"),
    ):
        ax.contour(speeds, altitudes / 1e3, fields[key], levels=[level], colors=colour)
        ax.plot([], [], color=colour, label=labels[key])
    if track is not None:
        ax.plot(track["speed_mps"], track["altitude_m"] / 1e3, color="k", lw=1.4, label="reentry")
        ax.plot(track["speed_mps"].iloc[0], track["altitude_m"].iloc[0] / 1e3, "o", color="k")
    terminal = settings.terminal
    ax.axvline(
        terminal.speed_mps,
        color="C4",
        ls="--",
        lw=1.0,
        label=f"terminal speed {terminal.speed_mps:g} m/s",
    )
    low = terminal.altitude_km - terminal.altitude_tolerance_km
    high = terminal.altitude_km + terminal.altitude_tolerance_km
    ax.plot(
        [terminal.speed_mps, terminal.speed_mps],
        [low, high],
        color="C4",
        lw=6.0,
        alpha=0.35,
        solid_capstyle="butt",
        label=f"terminal interface {low:g}-{high:g} km",
    )
    ax.axhline(
        entry_m / 1e3, color="C1", ls=":", lw=1.0, label=f"entry interface {entry_m / 1e3:g} km"
    )
    ax.set_xlabel("Earth-relative speed [m/s]")
    ax.set_ylabel("altitude [km]")
    ax.set_xlim(speeds[0], speeds[-1])
    ax.set_ylim(altitudes[0] / 1e3, altitudes[-1] / 1e3)
    ax.grid(True, alpha=0.3)
    ax.legend(
        fontsize=8, loc="upper left", title="limits: exceeded below each line", title_fontsize=8
    )
    ax.set_title(f"Reentry corridor: {scenario_when(scenario)}", fontsize=11)
    return fig
