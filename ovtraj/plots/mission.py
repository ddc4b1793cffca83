"""Mission plots from the chain's trajectory tables (``MissionRecord.trajectories``).

Three PNGs (matplotlib's Agg canvas, no pyplot state; each written to a temporary
name and renamed):

* ``<prefix>_profile.png``: altitude against time from the launch day's 0 h, and
  altitude against speed, the stages coloured;
* ``<prefix>_ground_track.png``: the ground track (geocentric longitude and
  latitude, spherical Earth) with the entry region, the entry point, the terminal
  point and the landing site;
* ``<prefix>_reentry_corridor.png``: the reentry in the altitude-speed plane with
  the dynamic-pressure, load-factor and heat-rate limits drawn as boundary curves
  (the reentry's own vehicle, angle-of-attack schedule and atmosphere model), the
  entry interface and the terminal interface.

The tables are the stages' own (the run store keeps the same ones): the rendezvous
and transfer tables count seconds from the launch day's 0 h, the deorbit's from its
start (the transfer's arrival) and the reentry's from the entry (the deorbit's last
row); the plots chain these offsets. A missing stage is left out.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ovtraj.astro.epoch import Epoch
from ovtraj.config import Scenario
from ovtraj.files import write_bytes
from ovtraj.storage import location

__all__ = ["mission_plots"]

_COLOURS = {
    "rendezvous": "C0",
    "transfer": "C2",
    "deorbit": "C1",
    "reentry": "C3",
}
_HOUR = 3600.0


def mission_plots(
    trajectories: dict[str, pd.DataFrame],
    scenario: Scenario,
    directory: Path,
    prefix: str = "mission",
) -> list[Path]:
    """Write the three mission plots into ``directory``; returns their paths."""
    directory = location(directory)
    tracks = _tracks(trajectories, scenario)
    return [
        _save(_profile(tracks), directory / f"{prefix}_profile.png"),
        _save(_ground_track(tracks, scenario), directory / f"{prefix}_ground_track.png"),
        _save(
            _corridor(trajectories.get("reentry"), scenario),
            directory / f"{prefix}_reentry_corridor.png",
        ),
    ]


def _save(fig: object, path: Path) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    fig.clear()
    write_bytes(path, buffer.getvalue(), replace=True)
    return path


def _figure(size: tuple[float, float]) -> object:
    from matplotlib.figure import Figure  # no pyplot: no global state, safe in workers

    return Figure(figsize=size, constrained_layout=True)


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
        lon = np.degrees(_wrap(np.arctan2(r[:, 1], r[:, 0]) - theta0 - earth.omega * t))
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
                "longitude_deg": table["longitude_deg"].to_numpy(dtype=float),
                "phase": table["phase"].to_numpy() if "phase" in table else stage,
            }
        )
        offset = float(t[-1])  # the reentry starts at the deorbit's entry
    return tracks


def _launch_day(scenario: Scenario) -> Epoch:
    if scenario.launch is not None:
        return Epoch.from_iso(scenario.launch.launch_date_utc)
    return scenario.epoch


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _profile(tracks: dict[str, pd.DataFrame]) -> object:
    fig = _figure((13.0, 4.8))
    left, right = fig.subplots(1, 2)
    for stage, track in tracks.items():
        label = stage + (" (Earth-relative speed)" if stage == "reentry" else "")
        colour = _COLOURS[stage]
        left.plot(
            track["t_s"] / _HOUR, track["altitude_m"] / 1e3, color=colour, lw=1.0, label=label
        )
        right.plot(track["speed_mps"], track["altitude_m"] / 1e3, color=colour, lw=1.0, label=label)
    if "rendezvous" in tracks and "transfer" in tracks:
        docked = (tracks["rendezvous"]["t_s"].iloc[-1], tracks["transfer"]["t_s"].iloc[0])
        left.axvspan(docked[0] / _HOUR, docked[1] / _HOUR, color="0.85", label="docked (stay)")
    left.set_xlabel("time from the launch day's 0 h UTC [h]")
    left.set_ylabel("altitude [km]")
    left.set_title("altitude against time")
    right.set_xlabel("speed [m/s] (inertial in orbit)")
    right.set_ylabel("altitude [km]")
    right.set_title("altitude against speed")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    if tracks:
        left.legend(fontsize=8, loc="lower left")
    fig.suptitle("Mission profile")
    return fig


def _broken(lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Longitude and latitude with NaN where the track wraps across +-180 deg."""
    jumps = np.flatnonzero(np.abs(np.diff(lon)) > 180.0) + 1
    return np.insert(lon, jumps, np.nan), np.insert(lat, jumps, np.nan)


def _ground_track(tracks: dict[str, pd.DataFrame], scenario: Scenario) -> object:
    fig = _figure((12.0, 6.2))
    ax = fig.subplots()
    for stage, track in tracks.items():
        lon, lat = _broken(
            track["longitude_deg"].to_numpy(dtype=float),
            track["latitude_deg"].to_numpy(dtype=float),
        )
        orbital = stage in ("rendezvous", "transfer")
        ax.plot(
            lon,
            lat,
            color=_COLOURS[stage],
            lw=0.4 if orbital else 1.6,
            alpha=0.5 if orbital else 1.0,
            label=stage,
        )
    if scenario.deorbit is not None:
        entry = scenario.deorbit.entry
        lon0 = entry.longitude_deg - entry.longitude_tolerance_deg
        lat0 = entry.latitude_deg - entry.latitude_tolerance_deg
        box_lon = [lon0, lon0 + 2 * entry.longitude_tolerance_deg]
        box_lat = [lat0, lat0 + 2 * entry.latitude_tolerance_deg]
        ax.fill(
            [box_lon[0], box_lon[1], box_lon[1], box_lon[0]],
            [box_lat[0], box_lat[0], box_lat[1], box_lat[1]],
            color="C1",
            alpha=0.2,
            label="entry region",
        )
    reentry = tracks.get("reentry")
    if reentry is not None:
        first, last = reentry.iloc[0], reentry.iloc[-1]
        ax.plot(first["longitude_deg"], first["latitude_deg"], "o", color="k", label="entry point")
        ax.plot(last["longitude_deg"], last["latitude_deg"], "x", color="k", ms=9, label="terminal")
    if scenario.reentry is not None:
        site = scenario.reentry.landing_site
        ax.plot(site.longitude_deg, site.latitude_deg, "*", color="C4", ms=14, label=site.name)
    ax.set_xlim(-180.0, 180.0)
    ax.set_ylim(-90.0, 90.0)
    ax.set_aspect("equal")
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("geocentric latitude [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower left", ncols=2)
    ax.set_title("Ground track (spherical Earth)")
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


def _corridor(table: pd.DataFrame | None, scenario: Scenario) -> object:
    fig = _figure((9.0, 6.2))
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
    for key, level, colour, text in (
        ("q", limits.max_dynamic_pressure_kpa * 1e3, "C0", "dynamic pressure limit"),
        ("load", limits.max_load_g, "C2", "load factor limit"),
        ("heat", limits.max_heat_rate_kw_m2 * 1e3, "C3", "heat-rate limit"),
    ):
        ax.contour(speeds, altitudes / 1e3, fields[key], levels=[level], colors=colour)
        ax.plot([], [], color=colour, label=f"{text} (below: exceeded)")
    if track is not None:
        ax.plot(track["speed_mps"], track["altitude_m"] / 1e3, color="k", lw=1.4, label="reentry")
        ax.plot(track["speed_mps"].iloc[0], track["altitude_m"].iloc[0] / 1e3, "o", color="k")
    terminal = settings.terminal
    ax.axvline(terminal.speed_mps, color="C4", ls="--", lw=1.0, label="terminal speed")
    ax.plot(
        [terminal.speed_mps, terminal.speed_mps],
        [
            terminal.altitude_km - terminal.altitude_tolerance_km,
            terminal.altitude_km + terminal.altitude_tolerance_km,
        ],
        color="C4",
        lw=6.0,
        alpha=0.35,
        solid_capstyle="butt",
        label="terminal interface (altitude band)",
    )
    ax.axhline(entry_m / 1e3, color="C1", ls=":", lw=1.0, label="entry interface")
    ax.set_xlabel("Earth-relative speed [m/s]")
    ax.set_ylabel("altitude [km]")
    ax.set_xlim(speeds[0], speeds[-1])
    ax.set_ylim(altitudes[0] / 1e3, altitudes[-1] / 1e3)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("Reentry corridor (limits from the reentry's vehicle and atmosphere)")
    return fig
