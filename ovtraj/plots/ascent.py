"""The ascent from the carrier's drop to insertion, against time from the drop.

Six panels share the time axis (seconds from the drop): altitude [km], speed [m/s]
(Earth-relative and inertial), flight-path angle [deg] (Earth-relative), dynamic pressure
[kPa] and axial load [g], each with the launcher's limit (``limits`` of the launcher file)
as a dashed line, and the vehicle's mass [t]. Each phase of the flight programme (free
fall, each stage's burn, the coast) has its own colour. The table is the launch stage's
trajectory table (:func:`ovtraj.launch.result.trajectory_table`); the limits come from the
scenario; the title names the scenario and its day, never the wall clock.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config import Scenario
from ovtraj.plots.mission import scenario_when
from ovtraj.plots.render import figure, write_png

__all__ = ["ASCENT_PANELS", "ascent_figure", "ascent_plot"]

# (table column, axis label, scale to the axis unit, limit key or None)
ASCENT_PANELS = (
    ("altitude_m", "altitude [km]", 1e-3, None),
    ("speed_mps", "Earth-relative speed [m/s]", 1.0, None),
    ("flight_path_angle_deg", "Earth-relative flight-path angle [deg]", 1.0, None),
    ("dynamic_pressure_pa", "dynamic pressure [kPa]", 1e-3, "q"),
    ("axial_load_g", "axial load [g]", 1.0, "load"),
    ("mass_kg", "mass [t]", 1e-3, None),
)
_LIMIT = {"color": "C3", "ls": "--", "lw": 1.2}


def _runs(phase: np.ndarray) -> list[tuple[str, int, int]]:
    """(phase, first row, end row) of each run of consecutive rows of one phase; each run
    keeps the next one's first row, so the line has no gap at a phase change."""
    starts = np.r_[0, np.flatnonzero(phase[1:] != phase[:-1]) + 1]
    ends = np.r_[starts[1:], len(phase)]
    return [
        (str(phase[a]), int(a), int(min(b + 1, len(phase))))
        for a, b in zip(starts, ends, strict=True)
    ]


def ascent_figure(table: pd.DataFrame, scenario: Scenario) -> Any:
    """The six panels of ``table`` (the launch stage's trajectory table: ``time_s`` from
    the drop, ``phase`` and the columns of :data:`ASCENT_PANELS`, ``inertial_speed_mps``)."""
    launcher = scenario.launch.launcher
    limits = {
        "q": (
            launcher.limits.max_dynamic_pressure_kpa,
            f"launcher limit {launcher.limits.max_dynamic_pressure_kpa:g} kPa",
        ),
        "load": (
            launcher.limits.max_axial_load_g,
            f"launcher limit {launcher.limits.max_axial_load_g:g} g",
        ),
    }
    fig = figure((13.0, 7.5))
    axes = fig.subplots(2, 3, sharex=True).ravel()
    time = table["time_s"].to_numpy(dtype=float)
    phase = table["phase"].astype(str).to_numpy()
    colours: dict[str, str] = {}
    for name, _, _ in _runs(phase):
        colours.setdefault(name, f"C{len(colours) % 10}")
    for ax, (column, label, scale, key) in zip(axes, ASCENT_PANELS, strict=True):
        values = table[column].to_numpy(dtype=float) * scale
        for name, first, end in _runs(phase):
            ax.plot(time[first:end], values[first:end], color=colours[name], lw=1.3, label=name)
        shown = []  # this panel's own legend; the phases' is the figure's
        if column == "speed_mps":
            inertial = table["inertial_speed_mps"].to_numpy(dtype=float)
            shown += ax.plot(time, inertial, color="0.4", ls=":", lw=1.2, label="inertial speed")
        if key is not None:
            level, text = limits[key]
            shown.append(ax.axhline(level, label=text, **_LIMIT))
        if shown:
            ax.legend(handles=shown, fontsize=8, loc="upper left")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    for ax in axes[3:]:
        ax.set_xlabel("time from the drop [s]")
    handles = {}
    for line in axes[0].get_lines():
        handles.setdefault(line.get_label(), line)
    fig.legend(
        list(handles.values()),
        [f"phase: {name}" for name in handles],
        loc="outside lower center",
        ncols=min(len(handles), 6),
        fontsize=8,
    )
    fig.suptitle(f"Ascent from the drop: {launcher.name}\n{scenario_when(scenario)}")
    return fig


def ascent_plot(table: pd.DataFrame, scenario: Scenario, path: Path | str) -> Path:
    """Draw :func:`ascent_figure` to ``path`` (PNG); returns the path."""
    return write_png(ascent_figure(table, scenario), path)
