"""The optimiser's result: summary figures, histories, Parquet files and a plot.

Units are in the field names where they are not SI; ``max_heat_rate`` is in kW/m^2,
``objective_value`` in ``objective_unit`` (km for maximum downrange, deg of final latitude
for maximum cross-range, MJ/m^2 for the heat load, s for the time).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.store.files import parquet_bytes, write_parquet
from ovtraj.store.records import FLOAT, plain, record_schema, table_from_rows
from ovtraj.studies.optimal_entry.feasibility import FeasibilityReport

__all__ = ["CONTROLS_SCHEMA", "STATES_SCHEMA", "OptimalEntryResult", "write_histories"]

# The independent variable's column when it is the normalised energy (with time as the
# independent variable, ``time_s`` is both); the rate-limited controls' columns.
_INDEPENDENT = ("energy_normalised", FLOAT)

STATES_SCHEMA = record_schema(
    [
        _INDEPENDENT,
        ("time_s", FLOAT),
        ("altitude_km", FLOAT),
        ("longitude_deg", FLOAT),
        ("latitude_deg", FLOAT),
        ("speed_mps", FLOAT),
        ("fpa_deg", FLOAT),
        ("heading_deg", FLOAT),
        ("downrange_km", FLOAT),
        ("crossrange_km", FLOAT),
        ("energy_mj_kg", FLOAT),
        ("alpha_deg", FLOAT),  # a state when its rate is limited, else null
        ("bank_deg", FLOAT),
    ]
)
"""``<stem>_states.parquet``: the states at every state point of the transcription."""

CONTROLS_SCHEMA = record_schema(
    [
        _INDEPENDENT,
        ("time_s", FLOAT),
        ("alpha_deg", FLOAT),
        ("bank_deg", FLOAT),
        ("mach", FLOAT),
        ("density_kg_m3", FLOAT),
        ("cl", FLOAT),
        ("cd", FLOAT),
        ("lift_to_drag", FLOAT),
        ("dynamic_pressure_kpa", FLOAT),
        ("load_g", FLOAT),
        ("heat_rate_kw_m2", FLOAT),
        ("alpha_rate_deg_s", FLOAT),  # the control when the rate is limited, else null
        ("bank_rate_deg_s", FLOAT),
    ]
)
"""``<stem>_controls.parquet``: controls and path quantities at the collocation points."""


@dataclass(frozen=True)
class OptimalEntryResult:
    """One solve of an optimal-entry problem (see the module notes for units)."""

    name: str
    objective: str
    independent: str
    method: str
    segments: int
    nodes_per_segment: int
    converged: bool
    status: str  # the NLP solver's own status (IPOPT's return status)
    reason: str | None  # why the result is not usable, None when converged
    backend: str
    objective_value: float
    objective_unit: str
    final_time_s: float
    range_km: float
    crossrange_km: float
    final_latitude_deg: float
    final_longitude_deg: float
    final_altitude_km: float
    final_speed_mps: float
    final_fpa_deg: float
    final_heading_deg: float
    max_load_g: float
    max_dynamic_pressure_kpa: float
    max_heat_rate: float  # kW/m^2
    heat_load_mj_m2: float
    nlp_iterations: int
    solve_time_s: float  # guess + transcription + NLP build + NLP solve
    nlp_build_time_s: float
    nlp_solve_time_s: float
    max_constraint_violation: float
    feasibility_error_km: float  # largest over the interpolations
    feasibility_error_deg: float
    refinements: int  # mesh refinements after the configured mesh (``segments`` is the last)
    feasibility: tuple[FeasibilityReport, ...] = ()
    states: pd.DataFrame = field(default_factory=pd.DataFrame)
    controls: pd.DataFrame = field(default_factory=pd.DataFrame)

    def to_row(self) -> dict[str, Any]:
        """Flat scalars for a table, the run store or ``--json``."""
        row: dict[str, Any] = {
            "name": self.name,
            "objective": self.objective,
            "independent": self.independent,
            "method": self.method,
            "segments": self.segments,
            "nodes_per_segment": self.nodes_per_segment,
            "refinements": self.refinements,
            "converged": self.converged,
            "status": self.status,
            "reason": self.reason,
            "backend": self.backend,
            "objective_value": self.objective_value,
            "objective_unit": self.objective_unit,
            "final_time_s": self.final_time_s,
            "range_km": self.range_km,
            "crossrange_km": self.crossrange_km,
            "final_latitude_deg": self.final_latitude_deg,
            "final_longitude_deg": self.final_longitude_deg,
            "final_altitude_km": self.final_altitude_km,
            "final_speed_mps": self.final_speed_mps,
            "final_fpa_deg": self.final_fpa_deg,
            "final_heading_deg": self.final_heading_deg,
            "max_load_g": self.max_load_g,
            "max_dynamic_pressure_kpa": self.max_dynamic_pressure_kpa,
            "max_heat_rate": self.max_heat_rate,
            "max_heat_rate_kw_m2": self.max_heat_rate,
            "heat_load_mj_m2": self.heat_load_mj_m2,
            "nlp_iterations": self.nlp_iterations,
            "solve_time_s": self.solve_time_s,
            "nlp_build_time_s": self.nlp_build_time_s,
            "nlp_solve_time_s": self.nlp_solve_time_s,
            "max_constraint_violation": self.max_constraint_violation,
            "feasibility_error_km": self.feasibility_error_km,
            "feasibility_error_deg": self.feasibility_error_deg,
        }
        for report in self.feasibility:
            key = f"feasibility_{report.interpolation}"
            row[f"{key}_position_km"] = report.position_error_km
            row[f"{key}_altitude_km"] = report.altitude_error_km
            row[f"{key}_speed_mps"] = report.speed_error_mps
            row[f"{key}_fpa_deg"] = report.fpa_error_deg
            row[f"{key}_angle_deg"] = report.angle_error_deg
            row[f"{key}_max_load_g"] = report.max_load_g
            row[f"{key}_max_dynamic_pressure_kpa"] = report.max_dynamic_pressure_kpa
            row[f"{key}_max_heat_rate_kw_m2"] = report.max_heat_rate_kw_m2
        return plain(row)


def write_histories(
    result: OptimalEntryResult,
    directory: str | Path,
    stem: str | None = None,
    *,
    content_named: bool = False,
) -> dict[str, Path]:
    """Write ``<stem>_states.parquet``, ``<stem>_controls.parquet`` and ``<stem>.png``.

    The tables have the declared schemas :data:`STATES_SCHEMA` and :data:`CONTROLS_SCHEMA`
    (a column the problem does not have is null). A stored table is never overwritten:
    writing the same histories again is a no-op, other histories under the same names are
    refused (:class:`~ovtraj.store.files.StoreError`). With ``content_named`` the files go to a
    subfolder ``<stem>-<content hash>`` of ``directory`` instead, one per distinct result.
    The plot is a view of the tables and is replaced.
    """
    stem = stem or f"{result.name}_{result.independent}_{result.method}"
    states = table_from_rows(
        result.states.to_dict(orient="records"),
        STATES_SCHEMA,
        "optimal-entry states",
        optional=("energy_normalised", "alpha_deg", "bank_deg"),
    )
    controls = table_from_rows(
        result.controls.to_dict(orient="records"),
        CONTROLS_SCHEMA,
        "optimal-entry controls",
        optional=("energy_normalised", "alpha_rate_deg_s", "bank_rate_deg_s"),
    )
    directory = Path(directory)
    if content_named:
        content = hashlib.sha256()
        for table in (states, controls):
            content.update(parquet_bytes(table))
        directory = directory / f"{stem}-{content.hexdigest()[:12]}"
    paths = {
        "states": directory / f"{stem}_states.parquet",
        "controls": directory / f"{stem}_controls.parquet",
        "plot": directory / f"{stem}.png",
    }
    write_parquet(paths["states"], states, STATES_SCHEMA)
    write_parquet(paths["controls"], controls, CONTROLS_SCHEMA)
    plot_result(result, paths["plot"])
    return paths


def plot_result(result: OptimalEntryResult, path: str | Path) -> None:
    """Six panels: altitude, speed, flight-path angle, controls, path quantities, range."""
    # A bare Figure (no pyplot): no global backend state, safe in workers and the CLI.
    from matplotlib.figure import Figure

    s, c = result.states, result.controls
    fig = Figure(figsize=(15, 8.5))
    axes = fig.subplots(2, 3)
    panels = (
        (axes[0, 0], "altitude_km", "altitude [km]", lambda y: y[:, 0] / 1e3),
        (axes[0, 1], "speed_mps", "speed [m/s]", lambda y: y[:, 3]),
        (axes[0, 2], "fpa_deg", "flight-path angle [deg]", lambda y: np.degrees(y[:, 4])),
    )
    for ax, column, label, integrated in panels:
        ax.plot(s["time_s"], s[column], "o", ms=3, label="optimised (nodes)")
        for report in result.feasibility:
            if len(report.t):
                ax.plot(
                    report.t,
                    integrated(report.y),
                    "-",
                    lw=1,
                    label=f"integrated, {report.interpolation} controls",
                )
        ax.set(xlabel="time [s]", ylabel=label)
    ax = axes[1, 0]
    ax.plot(c["time_s"], c["alpha_deg"], "o-", ms=3, label="angle of attack")
    ax.plot(c["time_s"], c["bank_deg"], "s-", ms=3, label="bank")
    ax.set(xlabel="time [s]", ylabel="control [deg]")
    ax = axes[1, 1]
    ax.plot(c["time_s"], c["load_g"], "o-", ms=3, label="load [g]")
    ax.plot(c["time_s"], c["dynamic_pressure_kpa"], "s-", ms=3, label="dynamic pressure [kPa]")
    ax.set(xlabel="time [s]", ylabel="load [g], dynamic pressure [kPa]")
    twin = ax.twinx()
    twin.plot(c["time_s"], c["heat_rate_kw_m2"], "^-", ms=3, color="C3", label="heat rate")
    twin.set(ylabel="heat rate [kW/m^2]")
    twin.legend(fontsize=8, loc="upper right")
    ax = axes[1, 2]
    ax.plot(s["downrange_km"], s["altitude_km"], "o-", ms=3)
    ax.set(xlabel="downrange [km]", ylabel="altitude [km]")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="upper left")
    fig.suptitle(
        f"{result.name}: {result.objective} = {result.objective_value:.6g} "
        f"{result.objective_unit} ({result.independent}, {result.method.upper()}, "
        f"{result.segments} x {result.nodes_per_segment} nodes, {result.status})"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
