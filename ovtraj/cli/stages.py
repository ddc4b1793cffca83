"""The stage commands: one stage of the mission solved alone on a scenario (rendezvous,
launch, launch-fit, deorbit, reentry)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from ovtraj.cli.common import (
    ConfigArg,
    JsonOpt,
    RowSpec,
    TargetOpt,
    app,
    exits_on,
    joined_fields,
    loaded_scenario,
    print_json,
    print_rows,
    renamed_options,
    report_stage,
    spec_rows,
)
from ovtraj.cli.progress import progress_bar
from ovtraj.config import ConfigError, Scenario
from ovtraj.formatting import duration, number
from ovtraj.store.records import plain

_RSW = ("radial", "along_track", "cross_track")
_MARGINS = ("heat_rate", "load", "dynamic_pressure", "bank")

_RENDEZVOUS_ROWS: RowSpec = [
    ("wait time", "wait_time_s", "s"),
    ("burn 1 epoch", "burn1_epoch_utc", "utc"),
    ("burn 2 epoch", "burn2_epoch_utc", "utc"),
    ("dv1", "dv1_mps", "m/s"),
    ("dv1 radial/along/cross", lambda row: joined_fields(row, "dv1_{}_mps", _RSW, "m/s"), ""),
    ("dv2", "dv2_mps", "m/s"),
    ("dv2 radial/along/cross", lambda row: joined_fields(row, "dv2_{}_mps", _RSW, "m/s"), ""),
    ("dv total", "dv_total_mps", "m/s"),
    (
        "two-body dv1 + dv2",
        lambda row: joined_fields(row, "dv{}_two_body_mps", ("1", "2"), "m/s", sep=" + "),
        "",
    ),
    ("transfer time", "transfer_time_s", "s"),
    ("two-body transfer time", "transfer_time_two_body_s", "s"),
    ("lead angle J2", "lead_angle_deg", "deg", 5),
    ("lead angle two-body", "lead_angle_two_body_deg", "deg", 5),
    ("plane difference", "plane_difference_deg", "deg"),
    ("miss distance", "miss_distance_m", "m"),
    ("two-body guess miss", "initial_miss_distance_m", "m"),
    ("iterations (interior point)", "iterations", ""),
]


@app.command()
def rendezvous(config: ConfigArg = None, as_json: JsonOpt = False) -> None:
    """Rendezvous of the OV with the space target: modified Hohmann transfer under J2.

    Example: `ovtraj rendezvous configs/scenario.yaml --json`"""
    from ovtraj.rendezvous import rendezvous_input, solve_rendezvous

    scenario = loaded_scenario(config)
    result = solve_rendezvous(rendezvous_input(scenario))
    title = f"rendezvous: {scenario.name} ({scenario.target.name})"
    report_stage(title, result, _RENDEZVOUS_ROWS, as_json)


_LOSSES = ("gravity", "aero", "steering", "back_pressure")


def _scaled(row: dict[str, Any], key: str, factor: float) -> float | None:
    value = row.get(key)
    return None if value is None else value * factor


_LAUNCH_ROWS: RowSpec = [
    ("target altitude", "target_altitude_km", "km"),
    ("opportunity", "opportunity", ""),
    ("payload", "payload_kg", "kg", 5),
    ("drop epoch", "drop_epoch_utc", "utc"),
    ("insertion epoch", "insertion_epoch_utc", "utc"),
    ("insertion time from 0 h UTC", "insertion_time_s", "s"),
    ("flight time", "flight_time_s", "s"),
    ("launch azimuth", "azimuth_deg", "deg", 5),
    ("insertion argument of latitude", "insertion_u_deg", "deg", 5),
    ("altitude error", "insertion_altitude_error_m", "m"),
    ("speed error", "insertion_speed_error_mps", "m/s"),
    ("flight-path angle error", "insertion_fpa_error_deg", "deg"),
    ("inclination error (mean)", "inclination_error_deg", "deg"),
    ("RAAN error (mean)", "raan_error_deg", "deg"),
    ("max dynamic pressure", lambda row: _scaled(row, "max_dynamic_pressure_pa", 1e-3), "kPa"),
    ("max axial load", "max_axial_load_g", "g"),
    ("ideal dv, rocket equation", "ideal_dv_rocket_equation_mps", "m/s"),
    (
        "losses: gravity/aero/steering/back-pressure",
        lambda row: joined_fields(row, "{}_loss_mps", _LOSSES, "m/s", 1),
        "",
    ),
    ("trajectories integrated", "trajectories", ""),
    ("wall time", "wall_time_s", "s"),
]


@app.command()
def launch(
    config: ConfigArg = None,
    altitude_km: Annotated[
        float | None,
        typer.Option(
            "--altitude-km",
            help="target altitude [km], 150-2000 (default: the config's launch.target_altitude_km)",
            show_default=False,
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Air launch: maximum payload to the target orbit (GA, SLSQP, then trust-constr; a
    progress bar on stderr).

    Example: `ovtraj launch --altitude-km 300`"""
    from ovtraj.launch import launch_input, solve_launch

    scenario = loaded_scenario(config)
    try:
        inp = launch_input(scenario, altitude_km=altitude_km)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    with progress_bar("launch", enabled=not as_json) as update:
        result = solve_launch(inp, on_progress=update)
    row = plain(result.to_row())
    if as_json:
        print_json(row)
        raise typer.Exit(code=0 if result.feasible else 1)
    shown: list[tuple[str, Any]] = [("feasible", row["feasible"])]
    if row.get("reason"):
        shown.append(("reason", row["reason"]))
    shown += spec_rows(row, _LAUNCH_ROWS)
    for phase in result.phases:
        shown.append(
            (
                f"phase {phase.name}",
                f"payload {number(phase.payload_kg, 'kg', 5)}, residual "
                f"{number(phase.max_residual, '', 3)}, {phase.iterations} iterations, "
                f"{phase.trajectories} trajectories, {duration(phase.wall_time_s)}"
                f"{'' if phase.accepted else ' (not kept)'}",
            )
        )
    print_rows(f"launch: {scenario.name} ({inp.launcher.name})", shown)
    if not result.feasible:
        raise typer.Exit(code=1)


# `--out` was `--output`: still taken for one release.
@app.command("launch-fit", cls=renamed_options({"--output": "--out"}))
def launch_fit_command(
    config: ConfigArg = None,
    output: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="directory for coefficients.json and grid.parquet (default: "
            "launch_fit/KEY in the workspace, `ovtraj paths`)",
            show_default=False,
        ),
    ] = None,
    target: TargetOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Launch fit (patent 5.1): solve the altitude grid, fit the Fourier series (a
    progress bar and a line per altitude on stderr).

    Example: `ovtraj launch-fit --target configs/targets/iss-like-2026-12-01.tle`"""
    from ovtraj.launch import launch_input
    from ovtraj.runs.preparation import solve_launch_fit

    scenario = loaded_scenario(config, target)
    with exits_on(ValueError):
        launcher = launch_input(scenario).launcher.name
    try:
        with progress_bar("launch fit", enabled=not as_json) as update:
            fit, directory = solve_launch_fit(scenario, output, on_progress=update)
    except ValueError as err:
        typer.echo(f"launch fit failed: {err}", err=True)
        raise typer.Exit(code=1) from None
    series = {
        name: {
            "unit": s.unit,
            "rms_residual": s.rms_residual,
            "loo_max_error": s.loo_max_error,
            "loo_relative_error": fit.loo_relative_error(name),
        }
        for name, s in fit.series.items()
    }
    if as_json:
        print_json(
            {
                "key": fit.key,
                "launcher": launcher,
                "grid_points": len(fit.grid),
                "altitude_range_km": list(fit.altitude_range_km),
                "saved_to": str(directory),
                "series": series,
            }
        )
        return
    print_rows(f"launch fit: {scenario.name} ({launcher})", _fit_rows(fit, directory, series))


def _fit_rows(
    fit: Any, directory: Path, series: dict[str, dict[str, Any]]
) -> list[tuple[str, str]]:
    """The launch fit's grid, folder and each series' residuals as labelled rows."""
    lo, hi = fit.altitude_range_km
    rows = [
        ("grid", f"{len(fit.grid)} altitudes, {number(lo)}-{number(hi, 'km')}"),
        ("saved to", str(directory)),
    ]
    for name, s in series.items():
        rows.append(
            (
                f"{name} fit",
                f"rms {number(s['rms_residual'], s['unit'], 3)}, leave-one-out max "
                f"{number(s['loo_max_error'], s['unit'], 3)} "
                f"({number(100 * s['loo_relative_error'], '%', 3)} of range)",
            )
        )
    return rows


def _stage_input(build: Any, scenario: Scenario) -> Any:
    try:
        return build(scenario)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None


_DEORBIT_ROWS: RowSpec = [
    ("burn epoch", "burn_epoch_utc", "utc"),
    ("wait on the preparation orbit", "wait_time_s", "s"),
    ("impulse", "dv_mps", "m/s"),
    ("impulse radial/along/cross", lambda row: joined_fields(row, "dv_{}_mps", _RSW, "m/s"), ""),
    ("two-body estimate", "estimate_dv_mps", "m/s"),
    ("burn to entry", "descent_time_s", "s"),
    ("entry epoch", "entry_epoch_utc", "utc"),
    ("entry latitude", "entry_lat_deg", "deg", 6),
    ("entry longitude", "entry_lon_deg", "deg", 6),
    ("entry error", "entry_error_km", "km"),
    ("entry speed, inertial", "entry_speed_mps", "m/s", 5),
    ("entry flight-path angle, inertial", "entry_fpa_deg", "deg"),
    ("entry speed, Earth-relative", "entry_relative_speed_mps", "m/s", 5),
    ("entry flight-path angle, Earth-relative", "entry_relative_fpa_deg", "deg"),
    ("entry heading", "entry_heading_deg", "deg", 5),
    ("SLSQP iterations", "iterations", ""),
    ("propagations", "propagations", ""),
    ("wall time", "wall_time_s", "s"),
]


@app.command()
def deorbit(config: ConfigArg = None, as_json: JsonOpt = False) -> None:
    """Deorbit: ground-track forecast, two-body estimate, SQP correction under J2.

    Example: `ovtraj deorbit configs/scenario.yaml`"""
    from ovtraj.deorbit import deorbit_input, solve_deorbit

    scenario = loaded_scenario(config)
    inp = _stage_input(deorbit_input, scenario)
    report_stage(f"deorbit: {scenario.name}", solve_deorbit(inp), _DEORBIT_ROWS, as_json)


_REENTRY_ROWS: RowSpec = [
    ("flags", "flags", ""),
    ("miss distance", "miss_distance_km", "km"),
    ("flight time", "flight_time_s", "s"),
    ("terminal epoch", "terminal_epoch_utc", "utc"),
    ("terminal altitude", "terminal_altitude_km", "km"),
    ("terminal speed", "terminal_speed_mps", "m/s"),
    ("terminal latitude", "terminal_lat_deg", "deg", 6),
    ("terminal longitude", "terminal_lon_deg", "deg", 6),
    ("terminal flight-path angle", "terminal_fpa_deg", "deg"),
    ("max heat rate", "max_heat_rate_kw_m2", "kW/m^2"),
    ("max load", "max_load_g", "g"),
    ("max dynamic pressure", "max_dynamic_pressure_kpa", "kPa"),
    ("max |bank|", "max_bank_deg", "deg"),
    ("margins heat/load/q/bank", lambda row: joined_fields(row, "{}_margin", _MARGINS, ""), ""),
    (
        "bank sigma_0 / sigma_1",
        lambda row: joined_fields(row, "sigma{}_deg", ("0", "1"), "deg", 2),
        "",
    ),
    ("bank reversals", "reversals", ""),
    ("golden-section evaluations", "golden_evaluations", ""),
    ("trajectories integrated", "trajectories", ""),
    ("wall time", "wall_time_s", "s"),
]


@app.command()
def reentry(config: ConfigArg = None, as_json: JsonOpt = False) -> None:
    """Reentry: guided lifting entry to the terminal interface near the landing site.

    Example: `ovtraj reentry --json`"""
    from ovtraj.reentry import reentry_input, solve_reentry

    scenario = loaded_scenario(config)
    inp = _stage_input(reentry_input, scenario)
    title = f"reentry: {scenario.name} (to {inp.settings.landing_site.name})"
    report_stage(title, solve_reentry(inp), _REENTRY_ROWS, as_json)
