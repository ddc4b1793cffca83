"""The ``ovtraj`` command line."""

from __future__ import annotations

import contextlib
import json
import logging
from pathlib import Path
from typing import Annotated, Any

import typer
import typer.core

from ovtraj import __version__
from ovtraj.cli_progress import configure_logging, echo, progress_bar
from ovtraj.config import ConfigError, Scenario, load_scenario
from ovtraj.config.deorbit_burn import MonteCarloConfig
from ovtraj.config.dispersions import MonteCarloExecution
from ovtraj.config.io_limits import echoed
from ovtraj.config.mission import DoeSettings
from ovtraj.formatting import byte_size, duration, joined, number, quantity, split_unit, utc
from ovtraj.records import json_text, plain

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Whole-mission trajectory planning of a small reusable orbital vehicle.",
    # Markdown, not rich markup: rich would take a unit such as `[m/s]` in a help text
    # for a style tag and drop it.
    rich_markup_mode="markdown",
)


def _flag_type(option: Any, ctx: Any) -> str | None:
    """The type column of an option's help: none for a flag (typer 0.29 shows `<bool>`)."""
    return None if getattr(option, "is_flag", False) else _OPTION_TYPE(option, ctx)


# typer's own hook for the column; left alone by a typer that no longer has it.
_OPTION_TYPE = getattr(typer.core.TyperOption, "display_type_rich", None)
if _OPTION_TYPE is not None:
    typer.core.TyperOption.display_type_rich = _flag_type

ConfigArg = Annotated[
    Path | None,
    typer.Argument(
        help="scenario YAML file (default: the shipped scenario, `ovtraj paths`)",
        show_default=False,
    ),
]
JsonOpt = Annotated[
    bool,
    typer.Option(
        "--json",
        help="print one JSON object on stdout, nothing else (progress and logs on stderr)",
    ),
]
TargetOpt = Annotated[
    str | None,
    typer.Option(
        "--target",
        help="TLE/OMM file or URL replacing the scenario's target (default: the scenario's)",
        show_default=False,
    ),
]


def _version(value: bool) -> None:
    if value:
        typer.echo(f"ovtraj {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="show the version")
    ] = False,
    quiet: Annotated[
        bool,
        typer.Option("--quiet", "-q", help="warnings and errors only on stderr, no progress bars"),
    ] = False,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="debug messages on stderr too")
    ] = False,
) -> None:
    """ovtraj command line. Results go to stdout; progress bars (while stderr is a
    terminal), progress messages and warnings to stderr, one line each."""
    if quiet and verbose:
        typer.echo("--quiet and --verbose: choose one", err=True)
        raise typer.Exit(code=2)
    configure_logging(quiet=quiet, verbose=verbose)


def _load(config: Path | None, target: str | None = None) -> Scenario:
    """The scenario (the shipped one when ``config`` is None), its target replaced by the
    TLE/OMM file or URL ``target`` when given."""
    from ovtraj.paths import config_path
    from ovtraj.target_sources import load_scenario_with_target

    try:
        path = config if config is not None else config_path("scenario.yaml")
        return load_scenario(path) if target is None else load_scenario_with_target(path, target)
    except ConfigError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None


def _print_rows(title: str, rows: list[tuple[str, Any]]) -> None:
    """A title and aligned ``label  value`` lines (a value not yet text through
    :func:`ovtraj.formatting.quantity`: ``-`` for None, 4 significant digits)."""
    typer.echo(title)
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        shown = value if isinstance(value, str) else quantity(value)
        typer.echo(f"  {key:<{width}}  {shown}")


# A table row of a result: (label, key of the row or function of the row, unit[, digits]);
# the unit "s" shows a duration, "utc" an epoch (ovtraj.formatting.quantity).
RowSpec = list[tuple[Any, ...]]


def _rows(row: dict[str, Any], spec: RowSpec) -> list[tuple[str, str]]:
    """``(label, text)`` of every row of ``spec`` the result has a value for."""
    shown = []
    for label, how, unit, *digits in spec:
        value = how(row) if callable(how) else row.get(how)
        if value is not None and value != "":
            shown.append((label, quantity(value, unit, *digits)))
    return shown


def _keyed_rows(row: dict[str, Any], digits: int = 4) -> list[tuple[str, str]]:
    """Every field of a flat row, labelled by its key without the unit suffix and shown
    in that unit with ``digits`` significant digits (``min_t_total_s`` -> ``min t total
    142.003 h``)."""
    shown = []
    for key, value in row.items():
        name, unit = split_unit(key)
        shown.append((name.replace("_", " "), quantity(value, unit, digits)))
    return shown


def _joined(
    row: dict[str, Any],
    pattern: str,
    names: tuple[str, ...],
    unit: str,
    decimals: int = 3,
    sep: str = " / ",
) -> str | None:
    """``a / b / c unit`` of ``row[pattern.format(name)]`` with ``decimals`` each; None
    when the stage did not get there."""
    values = [row.get(pattern.format(name)) for name in names]
    if any(v is None for v in values):
        return None
    return joined(values, unit, sep=sep, decimals=decimals)


def _print_json(value: Any) -> None:
    """One JSON object, on one line of stdout."""
    typer.echo(json_text(value, indent=None))


def _report(title: str, result: Any, rows: RowSpec, as_json: bool) -> None:
    """Print a stage result (JSON or a table: feasible, the reason if any, ``rows``);
    exit 1 when it is infeasible."""
    row = plain(result.to_row())
    if as_json:
        _print_json(row)
    else:
        shown: list[tuple[str, Any]] = [("feasible", row["feasible"])]
        if row.get("reason"):
            shown.append(("reason", row["reason"]))
        _print_rows(title, shown + _rows(row, rows))
    if not result.feasible:
        raise typer.Exit(code=1)


_RSW = ("radial", "along_track", "cross_track")
_MARGINS = ("heat_rate", "load", "dynamic_pressure", "bank")

_RENDEZVOUS_ROWS: RowSpec = [
    ("wait time", "wait_time_s", "s"),
    ("burn 1 epoch", "burn1_epoch_utc", "utc"),
    ("burn 2 epoch", "burn2_epoch_utc", "utc"),
    ("dv1", "dv1_mps", "m/s"),
    ("dv1 radial/along/cross", lambda row: _joined(row, "dv1_{}_mps", _RSW, "m/s"), ""),
    ("dv2", "dv2_mps", "m/s"),
    ("dv2 radial/along/cross", lambda row: _joined(row, "dv2_{}_mps", _RSW, "m/s"), ""),
    ("dv total", "dv_total_mps", "m/s"),
    (
        "two-body dv1 + dv2",
        lambda row: _joined(row, "dv{}_two_body_mps", ("1", "2"), "m/s", sep=" + "),
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
    """Rendezvous of the OV with the space target: modified Hohmann transfer under J2."""
    from ovtraj.rendezvous import rendezvous_input, solve_rendezvous

    scenario = _load(config)
    result = solve_rendezvous(rendezvous_input(scenario))
    title = f"rendezvous: {scenario.name} ({scenario.target.name})"
    _report(title, result, _RENDEZVOUS_ROWS, as_json)


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
        lambda row: _joined(row, "{}_loss_mps", _LOSSES, "m/s", 1),
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
    progress bar on stderr)."""
    from ovtraj.launch import launch_input, solve_launch

    scenario = _load(config)
    try:
        inp = launch_input(scenario, altitude_km=altitude_km)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    with progress_bar("launch", enabled=not as_json) as update:
        result = solve_launch(inp, on_progress=update)
    row = plain(result.to_row())
    if as_json:
        _print_json(row)
        raise typer.Exit(code=0 if result.feasible else 1)
    shown: list[tuple[str, Any]] = [("feasible", row["feasible"])]
    if row.get("reason"):
        shown.append(("reason", row["reason"]))
    shown += _rows(row, _LAUNCH_ROWS)
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
    _print_rows(f"launch: {scenario.name} ({inp.launcher.name})", shown)
    if not result.feasible:
        raise typer.Exit(code=1)


@app.command("launch-fit")
def launch_fit_command(
    config: ConfigArg = None,
    output: Annotated[
        Path | None,
        typer.Option(
            "--output",
            help="directory for coefficients.json and grid.parquet (default: "
            "launch_fit/KEY in the workspace, `ovtraj paths`)",
            show_default=False,
        ),
    ] = None,
    target: TargetOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Launch fit (patent 5.1): solve the altitude grid, fit the Fourier series (a
    progress bar and a line per altitude on stderr)."""
    from ovtraj.launch import launch_input
    from ovtraj.launch.fit import fit_roots, launch_fit, launch_fit_key

    scenario = _load(config, target)
    try:
        inp = launch_input(scenario)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    key = launch_fit_key(scenario)
    try:
        with progress_bar("launch fit", enabled=not as_json) as update:
            fit = launch_fit(inp, scenario.launch.fit, key=key, on_progress=update)
    except ValueError as err:
        typer.echo(f"launch fit failed: {err}", err=True)
        raise typer.Exit(code=1) from None
    directory = Path(output or fit_roots()[0] / key).resolve()
    fit.save(directory)
    lo, hi = fit.altitude_range_km
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
        _print_json(
            {
                "key": key,
                "launcher": inp.launcher.name,
                "grid_points": len(fit.grid),
                "altitude_range_km": [lo, hi],
                "saved_to": str(directory),
                "series": series,
            }
        )
        return
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
    _print_rows(f"launch fit: {scenario.name} ({inp.launcher.name})", rows)


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
    ("impulse radial/along/cross", lambda row: _joined(row, "dv_{}_mps", _RSW, "m/s"), ""),
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
    """Deorbit: ground-track forecast, two-body estimate, SQP correction under J2."""
    from ovtraj.deorbit import deorbit_input, solve_deorbit

    scenario = _load(config)
    inp = _stage_input(deorbit_input, scenario)
    _report(f"deorbit: {scenario.name}", solve_deorbit(inp), _DEORBIT_ROWS, as_json)


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
    ("margins heat/load/q/bank", lambda row: _joined(row, "{}_margin", _MARGINS, ""), ""),
    ("bank sigma_0 / sigma_1", lambda row: _joined(row, "sigma{}_deg", ("0", "1"), "deg", 2), ""),
    ("bank reversals", "reversals", ""),
    ("golden-section evaluations", "golden_evaluations", ""),
    ("trajectories integrated", "trajectories", ""),
    ("wall time", "wall_time_s", "s"),
]


@app.command()
def reentry(config: ConfigArg = None, as_json: JsonOpt = False) -> None:
    """Reentry: guided lifting entry to the terminal interface near the landing site."""
    from ovtraj.reentry import reentry_input, solve_reentry

    scenario = _load(config)
    inp = _stage_input(reentry_input, scenario)
    title = f"reentry: {scenario.name} (to {inp.settings.landing_site.name})"
    _report(title, solve_reentry(inp), _REENTRY_ROWS, as_json)


_OPTIMAL_ENTRY_ROWS: RowSpec = [
    ("reason", "reason", ""),
    ("status", "status", ""),
    ("objective", "objective", ""),
    (
        "formulation",
        lambda row: (
            f"{row['independent']}, {row['method']} {row['segments']}x{row['nodes_per_segment']}"
            f" ({row['refinements']} mesh refinements)"
        ),
        "",
    ),
    ("objective value", "objective_value", "", 6),
    ("final time", "final_time_s", "s"),
    ("range", "range_km", "km", 5),
    ("cross-range", "crossrange_km", "km"),
    ("final latitude", "final_latitude_deg", "deg", 6),
    ("final altitude", "final_altitude_km", "km"),
    ("final speed", "final_speed_mps", "m/s"),
    ("final flight-path angle", "final_fpa_deg", "deg"),
    ("max load", "max_load_g", "g"),
    ("max dynamic pressure", "max_dynamic_pressure_kpa", "kPa"),
    ("max heat rate", "max_heat_rate", "kW/m^2"),
    ("NLP iterations", "nlp_iterations", ""),
    ("solve time", "solve_time_s", "s"),
    ("feasibility error", "feasibility_error_km", "km", 3),
    ("feasibility error, angle", "feasibility_error_deg", "deg", 3),
    (
        "re-flight, each interpolation",
        lambda row: (
            ", ".join(
                f"{key[len('feasibility_') : -len('_position_km')]} {number(value, 'km', 3)}"
                for key, value in row.items()
                if key.startswith("feasibility_") and key.endswith("_position_km")
            )
            or None
        ),
        "",
    ),
]

IndependentOpt = Annotated[
    str | None,
    typer.Option(
        "--independent",
        help="independent variable: energy | time (default: the config's)",
        show_default=False,
    ),
]
TranscriptionOpt = Annotated[
    str | None,
    typer.Option(
        "--transcription",
        help="collocation: lg | lgr (default: the config's)",
        show_default=False,
    ),
]


@app.command("optimal-entry")
def optimal_entry(
    config: Annotated[Path, typer.Argument(help="optimal-entry YAML file", show_default=False)],
    as_json: JsonOpt = False,
    independent: IndependentOpt = None,
    transcription: TranscriptionOpt = None,
    out: Annotated[
        Path | None,
        typer.Option(
            help="where the histories go, in a subfolder named by their content "
            "(default: optimal_entry in the workspace, `ovtraj paths`)",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Optimal lifting entry by Gauss pseudospectral collocation (seed 001)."""
    from ovtraj.paths import workspace
    from ovtraj.reentry.pseudospectral import (
        load_optimal_entry,
        solve_optimal_entry,
        write_histories,
    )

    try:
        problem = load_optimal_entry(config)
        result = solve_optimal_entry(problem, independent=independent, transcription=transcription)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    # One subfolder per distinct result: stored histories are never overwritten.
    root = (out or workspace() / "optimal_entry").resolve()
    paths = write_histories(result, root, content_named=True)
    row = {k: v for k, v in plain(result.to_row()).items() if v is not None}
    if as_json:
        _print_json(row | {k: str(v) for k, v in paths.items()})
    else:
        shown: list[tuple[str, Any]] = [("converged", row["converged"])]
        shown += _rows(row, _OPTIMAL_ENTRY_ROWS)
        shown += [(f"{name} file", str(path)) for name, path in paths.items()]
        _print_rows(f"optimal entry: {result.name}", shown)
    if not result.converged:
        raise typer.Exit(code=1)


_MANEUVER_ROWS: RowSpec = [
    ("reason", "reason", ""),
    ("time of flight", "time_of_flight_s", "s"),
    ("time of flight, impulses", "impulsive_time_of_flight_s", "s"),
    ("impulse epochs", "impulse_epochs_s", "s"),
    ("impulses", "impulse_dv_mps", "m/s"),
    ("total dv, impulses", "total_dv_mps", "m/s", 5),
    ("dv budget (eq. 14)", "dv_budget_mps", "m/s", 5),
    ("dv capacity, burn-time limit", "dv_capacity_mps", "m/s", 5),
    ("finite burns, total dv", "finite_total_dv_mps", "m/s", 5),
    ("total burn time", "total_burn_time_s", "s"),
    ("final position error", "final_position_error_m", "m", 3),
    ("final velocity error", "final_velocity_error_mps", "m/s", 3),
    ("DE generations / evaluations", lambda d: f"{d['generations']} / {d['evaluations']}", ""),
    ("wall time", "wall_time_s", "s"),
]


@app.command()
def maneuver(
    config: Annotated[Path, typer.Argument(help="manoeuvre YAML file", show_default=False)],
    as_json: JsonOpt = False,
) -> None:
    """Quick multi-impulse manoeuvre of an upper stage, then finite burns (seed 003)."""
    from ovtraj.maneuver import comparison_rows, load_maneuver, solve_maneuver

    try:
        problem = load_maneuver(config)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    result = solve_maneuver(problem)
    if as_json:
        _print_json(result.to_json())
    else:
        doc = plain(result.to_json())
        shown: list[tuple[str, Any]] = [("converged", doc["converged"])]
        shown += _rows(doc, _MANEUVER_ROWS)
        for k, burn in enumerate(doc["burns"], start=1):
            shown.append(
                (
                    f"burn {k}",
                    f"from {duration(burn['start_s'])} for {duration(burn['duration_s'])}, "
                    f"{number(burn['dv_mps'], 'm/s', 5)}, mass "
                    f"{number(burn['mass_before_kg'], '', 6)} -> "
                    f"{number(burn['mass_after_kg'], 'kg', 6)}",
                )
            )
        _print_rows(f"manoeuvre: {config.stem}", shown)
        comparison = comparison_rows(problem, result)
        if comparison:
            typer.echo("published vs ours")
            width = max(len(q) for q, _, _ in comparison)
            for name, published, ours in comparison:
                typer.echo(f"  {name:<{width}}  {published:>24}  {ours}")
    if not result.converged:
        raise typer.Exit(code=1)


@app.command("deorbit-burn")
def deorbit_burn(
    config: Annotated[Path, typer.Argument(help="deorbit-burn YAML file", show_default=False)],
    as_json: JsonOpt = False,
    monte_carlo: Annotated[
        int | None,
        typer.Option(
            "--monte-carlo",
            **_limits(MonteCarloConfig, "runs"),
            help="also fly this many dispersed runs (default: none; a progress bar on stderr)",
            show_default=False,
        ),
    ] = None,
    strategy: Annotated[
        int | None,
        typer.Option(
            min=1,
            max=2,
            help="cut-off: 1 argument of latitude, 2 flight-path angle (default: the config's "
            "strategy; with --monte-carlo, the config's strategies)",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Finite-thrust deorbit burn by osculating-element prediction (seed 004)."""
    from ovtraj.deorbit.burn import deorbit_burn_report, format_report, load_deorbit_burn

    try:
        problem = load_deorbit_burn(config)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    with progress_bar("Monte Carlo", enabled=bool(monte_carlo) and not as_json) as update:
        report = deorbit_burn_report(
            problem, strategy=strategy, monte_carlo_runs=monte_carlo, on_progress=update
        )
    if as_json:
        # The solve's fields at the top level, the history and statistics alongside.
        flat = report["result"] | {k: v for k, v in report.items() if k != "result"}
        _print_json(flat)
    else:
        typer.echo(format_report(report))
    if not report["result"]["converged"]:
        raise typer.Exit(code=1)


def _store(root: str | None, scenario: Scenario | None = None, config: Path | None = None) -> Any:
    """``--store``, else the scenario's store (relative to its file ``config``), else the
    workspace's (ovtraj.paths)."""
    from ovtraj.runs import RunStore

    if scenario is not None:
        return RunStore.for_scenario(scenario, config, root)
    return RunStore(root)


StoreOpt = Annotated[
    str | None,
    typer.Option(
        "--store",
        help="run store root, a folder or s3://bucket/prefix (default: the scenario's "
        "mission.doe.store for a command given a scenario, else runs in the workspace, "
        "`ovtraj paths`)",
        show_default=False,
    ),
]


@app.command()
def paths(as_json: JsonOpt = False) -> None:
    """Where ovtraj reads its shipped files and writes its results (the workspace)."""
    from ovtraj import paths as where

    found = {
        "configs": str(where.config_dir()),
        "reference": str(where.reference_dir()),
        "default_scenario": str(where.config_dir() / "scenario.yaml"),
        "workspace": str(where.workspace()),
        "run_store": str(where.store_root(None, None, None)),
        "launch_fits": str(where.workspace() / "launch_fit"),
        "source_checkout": where.source_checkout(),
    }
    if as_json:
        _print_json(found)
    else:
        labels = {"workspace": "workspace (OVTRAJ_HOME)"}
        rows = [(labels.get(k, k.replace("_", " ")), v) for k, v in found.items()]
        _print_rows("ovtraj paths", rows)


RunnerOpt = Annotated[
    str | None,
    typer.Option(
        "--runner",
        help="serial | threads | processes | dask: where the batches run (default: the "
        "config's mission.doe.task_runner)",
        show_default=False,
    ),
]
DaskAddressOpt = Annotated[
    str | None,
    typer.Option(
        "--dask-address",
        help="scheduler of an existing Dask cluster, e.g. tls://host:8786 (--runner dask; "
        "default: $OVTRAJ_DASK_ADDRESS, else a local cluster; never from a scenario file)",
        show_default=False,
    ),
]


def _limits(model: Any, name: str) -> dict[str, Any]:
    """A config field's bounds as typer's ``min``/``max``: the command refuses what the
    config would (one definition of each range, in ``ovtraj.config``)."""
    limits: dict[str, Any] = {}
    for constraint in model.model_fields[name].metadata:
        if getattr(constraint, "ge", None) is not None:
            limits["min"] = constraint.ge
        if getattr(constraint, "le", None) is not None:
            limits["max"] = constraint.le
    return limits


SamplesOpt = Annotated[
    int | None,
    typer.Option(
        "--samples",
        **_limits(DoeSettings, "samples"),
        help="DoE samples (default: the config's mission.doe.samples)",
        show_default=False,
    ),
]
SeedOpt = Annotated[
    int | None,
    typer.Option(
        "--seed",
        **_limits(DoeSettings, "seed"),
        help="Latin hypercube seed (default: the config's mission.doe.seed)",
        show_default=False,
    ),
]


@app.command()
def run(
    config: ConfigArg = None,
    samples: SamplesOpt = None,
    seed: SeedOpt = None,
    append: Annotated[
        str | None,
        typer.Option(
            "--append",
            help="add the samples to this run, a child run (default: a run of its own)",
            show_default=False,
        ),
    ] = None,
    store_root: StoreOpt = None,
    target: TargetOpt = None,
    runner: RunnerOpt = None,
    dask_address: DaskAddressOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """DoE of the whole mission into the run store (a progress bar on stderr; a line per
    batch on stdout, on stderr with --json).

    ``--runner`` says where the batches run (``serial`` here; a pool of ``threads`` or
    ``processes``; ``dask``: the cluster at ``--dask-address`` or a local one); each
    batch is stored where the run is by the process that computed it. No Prefect: the
    flows (``flows/doe.py``) run the same batches as Prefect tasks.
    """
    scenario = _load(config, target)
    if scenario.mission is None:
        typer.echo(f"{config}: the scenario has no mission section", err=True)
        raise typer.Exit(code=2)
    settings = scenario.mission.doe
    execution = _doe_execution(settings, runner, dask_address)
    from ovtraj.runs import StoreError, prepare_run, run_doe
    from ovtraj.runs.execute import BatchesFailed
    from ovtraj.runs.runners import ClusterError
    from ovtraj.version import code_version

    fit = _launch_fit_or_exit(scenario, target)
    store = _store(store_root, scenario, config)
    try:
        parent = store.run(append) if append else None
        stored = prepare_run(
            scenario,
            samples=settings.samples if samples is None else samples,
            seed=settings.seed if seed is None else seed,
            code=code_version(),
            store=store,
            parent=parent,
        )
        # a line per batch: the command's output (stdout), with --json the log's (stderr)
        say = None if as_json else echo
        with progress_bar("DoE samples", enabled=not as_json) as update:
            run_doe(scenario, stored, fit, progress=say, on_progress=update, **execution)
    except (StoreError, ValueError, ClusterError, BatchesFailed) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    summary = stored.summary()
    if as_json:
        _print_json(summary | {"stored_in": str(stored.url)})
        return
    _print_rows(f"run {stored.id}", _keyed_rows(summary))
    typer.echo(f"stored in {stored.url}")


def _doe_execution(settings: Any, runner: str | None, dask_address: str | None) -> dict[str, Any]:
    """The keyword arguments of ``run_doe`` for the runner chosen: the option, else the
    config's ``mission.doe``; a bad choice is one line, exit 2."""
    from ovtraj.config.mission import RUNNERS
    from ovtraj.config.orchestration import load_orchestration
    from ovtraj.runs.runners import dask_address as chosen_address

    chosen = runner or settings.task_runner
    if chosen not in RUNNERS:
        shown = echoed(repr(chosen))
        typer.echo(f"--runner {shown}: must be one of {', '.join(RUNNERS)}", err=True)
        raise typer.Exit(code=2)
    if dask_address and chosen != "dask":
        typer.echo(f"--dask-address needs --runner dask (the runner is {chosen})", err=True)
        raise typer.Exit(code=2)
    orchestration = load_orchestration()
    return {
        "batch_size": settings.batch_size,
        "runner": chosen,
        "workers": settings.workers,
        "dask_address": chosen_address(dask_address) if chosen == "dask" else None,
        "dask": orchestration.dask,
        "time_limit_s": orchestration.flows.doe_s,
    }


@app.command()
def runs(store_root: StoreOpt = None, as_json: JsonOpt = False) -> None:
    """List the stored runs by family: each DoE run, then the runs that extend it (a
    pipeline's infill rounds, `run --append`), with their pipeline results and sizes."""
    from ovtraj.pipeline.catalog import store_catalog
    from ovtraj.runs import StoreError

    store = _store(store_root)
    try:
        entries = store_catalog(store)
    except (StoreError, OSError) as err:
        typer.echo(f"{store.root}: {err}", err=True)
        raise typer.Exit(code=2) from None
    if as_json:
        _print_json({"store": str(store.root.resolve()), "runs": [e.to_json() for e in entries]})
        return
    if not entries:
        typer.echo(f"no runs in {store.root.resolve()}")
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"runs in {store.root.resolve()}", title_justify="left", box=None, pad_edge=False
    )
    for column, justify in (
        ("run", "left"),
        ("created (UTC)", "left"),
        ("scenario", "left"),
        ("origin", "left"),
        ("samples", "right"),
        ("feasible", "right"),
        ("status", "left"),
        ("pipeline results", "left"),
        ("size", "right"),
    ):
        table.add_column(column, justify=justify, no_wrap=column == "run")
    for e in entries:
        indent = "  " * e.depth + ("└ " if e.depth else "")
        if e.error is not None:
            table.add_row(indent + e.run_id, "-", "-", "-", "-", "-", f"error: {e.error}")
            continue
        table.add_row(
            indent + e.run_id,
            utc(e.created_utc),
            e.scenario or "-",
            e.origin or "-",
            str(e.samples),
            f"{e.feasible}/{e.evaluated}",
            e.status or "-",
            ", ".join(e.pipelines) or "-",
            "-" if e.size_bytes is None else byte_size(e.size_bytes),
        )
    # On a terminal the table fits its width; elsewhere (a pipe, a file) every row is whole.
    console = Console(highlight=False)
    if not console.is_terminal:
        console = Console(highlight=False, width=10_000)
    console.print(table)
    families = sum(1 for e in entries if e.depth == 0)
    total = sum(e.size_bytes or 0 for e in entries)
    typer.echo(
        f"{len(entries)} runs in {families} families, {byte_size(total)} on disk "
        "(a file shared by hard link counted once); `ovtraj prune` lists what can go"
    )


@app.command()
def show(run_id: str, store_root: StoreOpt = None) -> None:
    """Print a run's manifest and summary as one JSON object."""
    from ovtraj.runs import StoreError

    try:
        stored = _store(store_root).run(run_id)
        manifest, summary = stored.manifest, stored.summary()
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    typer.echo(json.dumps({"manifest": manifest, "summary": summary}, indent=2, default=str))


PruneKinds = Annotated[
    list[str] | None,
    typer.Option(
        "--only",
        help="what to prune: children (superseded child runs), fits (surrogate fits and "
        "fronts of another code version), prefect-results (Prefect's local task results); "
        "repeat the option for several (default: all three)",
        show_default=False,
    ),
]


@app.command()
def prune(
    store_root: StoreOpt = None,
    only: PruneKinds = None,
    yes: Annotated[
        bool, typer.Option("--yes", help="delete (without it: only list what would go)")
    ] = False,
    as_json: JsonOpt = False,
) -> None:
    """List, and with --yes delete, what the store can lose without losing a result:
    child runs whose samples a later complete run holds (never a family's DoE run nor a
    pipeline's final run), surrogate fits and fronts no longer loaded by this code
    version, and Prefect's task results (a cache). See docs/mission.md."""
    from ovtraj.config.orchestration import load_orchestration
    from ovtraj.pipeline.prune import KINDS, prunable, remove
    from ovtraj.runs import StoreError
    from ovtraj.version import code_version

    kinds = tuple(only) if only else KINDS
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        shown = ", ".join(echoed(repr(kind)) for kind in unknown)
        typer.echo(f"--only: {shown} is not one of {', '.join(KINDS)}", err=True)
        raise typer.Exit(code=2)
    store = _store(store_root)
    results = load_orchestration().results.location()
    try:
        items = prunable(
            store,
            code_version(),
            kinds=kinds,
            prefect_results=None if "://" in results else Path(results),
        )
        removed = [item for item in items if yes and remove(item)]
    except (StoreError, OSError) as err:
        typer.echo(f"prune: {err}", err=True)
        raise typer.Exit(code=2) from None
    freed = sum(item.size_bytes for item in removed)
    if as_json:
        _print_json(
            {
                "store": str(store.root.resolve()),
                "deleted": yes,
                "items": [i.to_json() | {"removed": i in removed} for i in items],
                "freed_bytes": freed,
            }
        )
        return
    for item in items:
        done = "deleted" if item in removed else "would delete" if not yes else "kept (in use)"
        typer.echo(f"{done}: {item.path} ({byte_size(item.size_bytes)}): {item.reason}")
    total = sum(item.size_bytes for item in items)
    if yes:
        typer.echo(f"{len(removed)} of {len(items)} items deleted, {byte_size(freed)} freed")
    else:
        typer.echo(f"{len(items)} items, {byte_size(total)}: nothing deleted (add --yes to delete)")


@app.command()
def verify(run_id: str, store_root: StoreOpt = None, as_json: JsonOpt = False) -> None:
    """Check every file of a run against its recorded size, SHA-256 and schema.

    The checksums detect accidents; with OVTRAJ_STORE_KEY set, the manifest's and the
    markers' seals are checked too, and one missing or wrong is reported as tampered.
    Exit 0 when every covered file is intact, 1 with the list of bad or tampered files,
    2 when the run cannot be opened.
    """
    from ovtraj.runs import StoreError

    try:
        stored = _store(store_root).run(run_id)
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    report = stored.verify()
    if as_json:
        _print_json(
            {
                "run_id": stored.id,
                "clean": report.clean,
                "checked_files": report.checked_files,
                "checked_bytes": report.checked_bytes,
                "problems": [str(p) for p in report.problems],
                "tampered": [str(p) for p in report.tampered],
                "uncovered": [str(p) for p in report.uncovered],
            }
        )
        raise typer.Exit(code=0 if report.clean else 1)
    for problem in report.tampered:
        typer.echo(f"tampered: {problem}")
    for problem in report.problems:
        typer.echo(f"bad: {problem}")
    for path in report.uncovered:
        typer.echo(f"not covered by any marker (never read): {path}")
    found = [
        f"{len(found)} {what} file(s)"
        for found, what in ((report.tampered, "tampered"), (report.problems, "bad"))
        if found
    ]
    verdict = "clean" if report.clean else ", ".join(found)
    typer.echo(
        f"run {stored.id}: {report.checked_files} files, {number(report.checked_bytes / 1e6)} "
        f"MB checked: {verdict}"
    )
    if not report.clean:
        raise typer.Exit(code=1)


@app.command()
def replay(run_id: str, store_root: StoreOpt = None, as_json: JsonOpt = False) -> None:
    """Re-derive the mission totals from the stored stage rows (no simulation)."""
    import numpy as np

    from ovtraj.runs import StoreError
    from ovtraj.runs import replay as replay_run

    try:
        stored = _store(store_root).run(run_id)
        derived = replay_run(stored)
        totals = stored.totals()
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    merged = derived.merge(totals, on="sample_id", suffixes=("", "_stored"))
    differences = {}
    for column in ("t_total_s", "dv_total_mps", "m_load_kg"):
        a, b = merged[column].to_numpy(float), merged[f"{column}_stored"].to_numpy(float)
        both = np.isfinite(a) & np.isfinite(b)
        differences[column] = float(np.max(np.abs(a[both] - b[both]))) if both.any() else 0.0
    worst = max(differences.values())
    if as_json:
        _print_json(
            {
                "run_id": stored.id,
                "samples": len(derived),
                "feasible": int(derived["feasible"].sum()),
                "largest_difference": worst,
                "largest_differences": differences,
            }
        )
        return
    rows = [
        ("samples", len(derived)),
        ("feasible", int(derived["feasible"].sum())),
        ("largest difference from the stored totals", worst),
    ]
    _print_rows(f"replay of {stored.id} (no simulation)", rows)


def _launch_fit_or_exit(scenario: Scenario, target: str | None = None) -> Any:
    from ovtraj.launch.fit import find_launch_fit

    fit = find_launch_fit(scenario)
    if fit is None:
        also = f" --target {target}" if target else ""
        typer.echo(
            "no launch fit for this scenario (its target and launch settings): run "
            f"`ovtraj launch-fit CONFIG{also}` (~4 min) or the launch-fit flow first",
            err=True,
        )
        raise typer.Exit(code=2)
    return fit


def _run_scenario(stored: Any, config: Path | None) -> Scenario:
    from ovtraj.pipeline import run_scenario

    try:
        return run_scenario(stored, config)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None


PickIndexOpt = Annotated[
    int | None,
    typer.Option(
        "--pick",
        min=0,
        help="front index, see the front table (default: the best by --weights)",
        show_default=False,
    ),
]
WeightsOpt = Annotated[
    str | None,
    typer.Option(
        "--weights",
        help="T,dV,M weights on the normalised objectives, e.g. 1,1,2 (default: 1,1,1)",
        show_default=False,
    ),
]
MaxTimeOpt = Annotated[
    float | None,
    typer.Option(
        "--max-time-h",
        min=0.0,
        help="pick among points with T_total <= this [h] (default: no limit)",
        show_default=False,
    ),
]
MaxDvOpt = Annotated[
    float | None,
    typer.Option(
        "--max-dv",
        min=0.0,
        help="pick among points with dV_total <= this [m/s] (default: no limit)",
        show_default=False,
    ),
]
MinLoadOpt = Annotated[
    float | None,
    typer.Option(
        "--min-payload",
        min=0.0,
        help="pick among points with M_load >= this [kg] (default: no limit)",
        show_default=False,
    ),
]


def _pick(
    index: int | None,
    weights: str | None,
    max_time_h: float | None,
    max_dv: float | None,
    min_payload: float | None,
    default_weights: tuple[float, float, float] | None = None,
) -> Any:
    """The pick of the options, checked before any work: one line naming the option, exit 2."""
    import math

    from ovtraj.pipeline import Pick
    from ovtraj.pipeline.pick import weights_problem

    parsed = default_weights
    if weights is not None:
        try:
            parsed = tuple(float(w) for w in weights.split(","))
            problem = weights_problem(parsed)
        except ValueError:
            problem = "must be three numbers separated by commas"
        if problem is not None:
            typer.echo(f"--weights {echoed(repr(weights))}: {problem}", err=True)
            raise typer.Exit(code=2) from None
    limits = {"--max-time-h": max_time_h, "--max-dv": max_dv, "--min-payload": min_payload}
    for option, value in limits.items():
        if value is not None and not math.isfinite(value):  # their min= lets inf (1e400) by
            typer.echo(f"{option} {value}: must be a finite number", err=True)
            raise typer.Exit(code=2)
    return Pick(index, parsed, max_time_h, max_dv, min_payload)


def _print_front(front: Any) -> None:
    typer.echo(
        "  front  sample   H_P0 [km]  H_dp [km]  t_dsp [h]   T [h]  dV [m/s]  M [kg]  origin"
    )
    for row in front.itertuples(index=False):
        typer.echo(
            f"  {row.front_index:5d}  {row.sample_id:6d}  {row.parking_altitude_km:9.2f}  "
            f"{row.preparation_altitude_km:9.2f}  {row.separation_delay_h:9.2f}  "
            f"{row.t_total_s / 3600:6.1f}  {row.dv_total_mps:8.2f}  {row.m_load_kg:6.1f}  "
            f"{row.origin}"
        )
    typer.echo(
        "  H_P0: parking (launch insertion) altitude, H_dp: preparation orbit altitude, "
        "t_dsp: separation delay after docking; T, dV lower and M (payload) higher is better"
    )


@app.command()
def pipeline(
    config: ConfigArg = None,
    samples: SamplesOpt = None,
    seed: SeedOpt = None,
    from_run: Annotated[
        str | None, typer.Option("--run", help="start from this stored DoE run (no new DoE)")
    ] = None,
    refit: Annotated[
        bool, typer.Option("--refit", help="refit and re-optimise even when stored")
    ] = False,
    pick: PickIndexOpt = None,
    weights: WeightsOpt = None,
    max_time_h: MaxTimeOpt = None,
    max_dv: MaxDvOpt = None,
    min_payload: MinLoadOpt = None,
    store_root: StoreOpt = None,
    target: TargetOpt = None,
    runner: RunnerOpt = None,
    dask_address: DaskAddressOpt = None,
    require_converged: Annotated[
        bool,
        typer.Option(
            "--require-converged",
            help="exit 1 when the verification loop stops before its tolerance is met "
            "(the front, plan and report are stored all the same)",
        ),
    ] = False,
    as_json: JsonOpt = False,
) -> None:
    """The whole pipeline: DoE, surrogates, NSGA-II, verification and infill, the plan
    and its HTML report. Says whether the verification loop converged and why it stopped."""
    from functools import partial

    from ovtraj.mission.plan import PlanMismatch
    from ovtraj.parallel import Bounded
    from ovtraj.pipeline import (
        OptimiserStopped,
        PipelineError,
        PipelineSteps,
        draw_views,
        fit_step,
        front_step,
        pipeline_doe_run,
        run_pipeline,
        start_drawing,
    )
    from ovtraj.pipeline.planning import write_mission_plan
    from ovtraj.pipeline.report import stop_explanation
    from ovtraj.runs import StoreError, run_doe
    from ovtraj.runs.execute import BatchesFailed
    from ovtraj.runs.runners import ClusterError, batch_pool
    from ovtraj.surrogate import SurrogateError
    from ovtraj.version import code_version

    chosen = _pick(pick, weights, max_time_h, max_dv, min_payload)  # refused before any work
    scenario = _load(config, target)
    if scenario.mission is None:
        typer.echo(f"{config}: the scenario has no mission section", err=True)
        raise typer.Exit(code=2)
    fit = _launch_fit_or_exit(scenario, target)
    exits = contextlib.ExitStack()
    execution = _doe_execution(scenario.mission.doe, runner, dask_address)
    store = _store(store_root, scenario, config)
    code = code_version()

    say = logging.getLogger("ovtraj.pipeline").info if as_json else echo

    def evaluate(run: Any) -> Any:
        with progress_bar(f"run {run.id}", enabled=not as_json) as update:
            return run_doe(
                scenario, run, fit, progress=say, on_progress=update, pool=pool, **execution
            )

    try:
        # One pool for the DoE and every infill run: its processes keep their mission
        # context between runs instead of each run starting and warming up its own.
        pool = exits.enter_context(
            batch_pool(
                execution["runner"],
                execution["workers"],
                execution["dask_address"],
                execution["dask"],
            )
        )
        doe_run, scenario = pipeline_doe_run(
            scenario,
            store,
            code,
            samples=samples,
            seed=seed,
            from_run=from_run,
            config=config if from_run else None,
        )
        say(f"DoE run {doe_run.id}: {len(doe_run.samples())} samples")
        evaluate(doe_run)
        # the pool's processes score the surrogate candidates and draw the plots too (not
        # threads: those would only share this process's core)
        processes = pool.executor if execution["runner"] in ("processes", "dask") else None
        if execution["runner"] == "dask":
            # A cluster that lost every worker keeps tasks pending: bounded, then done here.
            processes = Bounded(processes, execution["dask"].side_work_timeout_s)
        steps = PipelineSteps(
            evaluate=evaluate,
            fit=partial(fit_step, refit=refit, executor=processes),
            front=partial(front_step, refit=refit),
            draw=partial(draw_views, executor=processes),
            predraw=None if processes is None else partial(start_drawing, executor=processes),
        )
        result = run_pipeline(scenario, doe_run, store=store, code=code, steps=steps, progress=say)
        exits.close()
        planned = write_mission_plan(scenario, fit, store, result, chosen)
    except (OptimiserStopped, PlanMismatch) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=1) from None
    except (
        StoreError,
        PipelineError,
        SurrogateError,
        ValueError,
        ClusterError,
        BatchesFailed,
    ) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    finally:
        exits.close()
    verdict = stop_explanation(result.summary, scenario.mission.verify)
    converged = bool(result.summary["converged"])
    front_plot = Path(result.directory / "front.png").resolve()
    # The last round's views, drawn with the result: parity plots and the surrogate front.
    views = sorted(
        path.resolve() for path in Path(result.directory).glob("*.png") if path.name != "front.png"
    )
    if as_json:
        _print_plan(
            planned,
            True,
            {
                "doe_run": doe_run.id,
                "final_run": result.final_run,
                "pipeline_id": result.pipeline_id,
                "converged": converged,
                "stop_reason": result.summary["stop_reason"],
                "verdict": verdict,
                "real_evaluations": result.summary["real_evaluations"],
                "hypervolume": result.summary["hypervolume"],
                "front_points": len(result.front),
                "front": str(Path(result.front_path).resolve()),
                "front_plot": str(front_plot),
                "views": [str(p) for p in views],
            },
        )
    else:
        typer.echo(
            f"verified front of DoE run {doe_run.id} (pipeline {result.pipeline_id}, final "
            f"run {result.final_run}):"
        )
        _print_front(result.front)
        typer.echo(verdict)
        typer.echo(f"front: {Path(result.front_path).resolve()}")
        typer.echo(f"plot: {front_plot}")
        for path in views:
            typer.echo(f"plot: {path}")
        _print_plan(planned, False, {})
    if require_converged and not converged:
        raise typer.Exit(code=1)


@app.command()
def optimize(
    run_id: str,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            help="surrogate/optimisation settings from this scenario YAML (default: the run's own)",
            show_default=False,
        ),
    ] = None,
    refit: Annotated[
        bool, typer.Option("--refit", help="refit and re-optimise even when stored")
    ] = False,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Fit the surrogates on a stored run's samples and run NSGA-II on them (no simulation)."""
    from ovtraj.pipeline import (
        OptimiserStopped,
        PipelineError,
        fit_step,
        front_step,
        training_data,
    )
    from ovtraj.pipeline.features import unregressed
    from ovtraj.runs import StoreError
    from ovtraj.surrogate import SurrogateError
    from ovtraj.version import code_version

    try:
        stored = _store(store_root).run(run_id)
        scenario = _run_scenario(stored, config)
        code = code_version()
        fitted = fit_step(stored, training_data(stored), scenario, code, refit=refit)
        front = front_step(stored, fitted, scenario, code, refit=refit)
    except OptimiserStopped as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=1) from None
    except (StoreError, PipelineError, SurrogateError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    validation = fitted.surrogates.validation
    chosen = validation[validation["selected"].astype(bool)]
    if as_json:
        _print_json(
            {
                "run_id": stored.id,
                "surrogates": str(fitted.directory.resolve()),
                "loaded_from_store": fitted.reused,
                "models": [
                    *(
                        {"model": row.model, "candidate": row.candidate}
                        for row in chosen.itertuples(index=False)
                    ),
                    *(
                        {"model": output, "candidate": model}
                        for output, model in unregressed(fitted.surrogates).items()
                    ),
                ],
                "front": str((front.directory / "front.parquet").resolve()),
                "front_points": len(front.front),
                "hypervolume": front.front.hypervolume,
                "identical_to_stored_front": front.matches_stored,
            }
        )
        raise typer.Exit(code=1 if front.matches_stored is False else 0)
    rows = [
        ("surrogates", str(fitted.directory.resolve())),
        ("loaded from the store", fitted.reused),
    ]
    for row in chosen.itertuples(index=False):
        rows.append((f"{row.model} model", row.candidate))
    for output, model in unregressed(fitted.surrogates).items():
        rows.append((f"{output} model", model))
    rows += [
        ("front", str((front.directory / "front.parquet").resolve())),
        ("front points", len(front.front)),
        ("hypervolume", number(front.front.hypervolume, "", 6)),
    ]
    if front.matches_stored is not None:
        rows.append(("identical to the stored front", front.matches_stored))
    _print_rows(f"surrogate front of run {stored.id}", rows)
    if front.matches_stored is False:
        raise typer.Exit(code=1)


@app.command()
def plan(
    run_id: Annotated[
        str,
        typer.Argument(
            help="any run of a pipeline family: its DoE run, an infill run (also a pruned "
            "one) or the final run"
        ),
    ],
    pick: PickIndexOpt = None,
    weights: WeightsOpt = None,
    max_time_h: MaxTimeOpt = None,
    max_dv: MaxDvOpt = None,
    min_payload: MinLoadOpt = None,
    pipeline_id: Annotated[
        str | None, typer.Option("--pipeline", help="pipeline id (default: the newest)")
    ] = None,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Write the mission plan (JSON and YAML), its plots and its HTML report, of a point
    of the verified front of a run's pipeline result."""
    from ovtraj.mission.plan import PlanError, PlanMismatch
    from ovtraj.pipeline import PipelineError
    from ovtraj.pipeline.catalog import family_root
    from ovtraj.pipeline.planning import find_pipeline, write_mission_plan
    from ovtraj.runs import StoreError

    chosen = _pick(pick, weights, max_time_h, max_dv, min_payload)  # refused before any work
    try:
        store = _store(store_root)
        stored = family_root(store, run_id)
        scenario = _run_scenario(stored, None)
        result = find_pipeline(stored, pipeline_id)
        planned = write_mission_plan(scenario, _launch_fit_or_exit(scenario), store, result, chosen)
    except PlanMismatch as err:  # the plan does not fly its front point: an unmet result
        typer.echo(str(err), err=True)
        raise typer.Exit(code=1) from None
    except (StoreError, PipelineError, PlanError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    _print_plan(planned, as_json, {"doe_run": stored.id, "pipeline_id": result.pipeline_id})


def _print_plan(planned: dict[str, Any], as_json: bool, extra: dict[str, Any]) -> None:
    """The written plan's paths (absolute) and why its point was picked."""
    paths = {
        "plan_json": str(planned["json"].resolve()),
        "plan_yaml": str(planned["yaml"].resolve()),
        "report": str(planned["report"].resolve()),
        "plots": [str(p.resolve()) for p in planned["plots"]],
    }
    if as_json:
        _print_json(extra | {"pick": planned["pick"]} | paths)
        return
    typer.echo(f"picked {planned['pick']}")
    typer.echo(f"plan: {paths['plan_json']}")
    typer.echo(f"plan: {paths['plan_yaml']}")
    for path in paths["plots"]:
        typer.echo(f"plot: {path}")
    typer.echo(f"report: {paths['report']}")


@app.command()
def fly(
    plan_file: Annotated[Path, typer.Argument(help="mission plan (JSON or YAML)")],
    monte_carlo: Annotated[
        int,
        typer.Option(
            "--monte-carlo",
            min=0,
            max=_limits(MonteCarloExecution, "runs")["max"],
            help="also fly this many dispersed runs, closed loop and open loop (0: none)",
        ),
    ] = 0,
    seed: Annotated[int, typer.Option("--seed", min=0, help="seed of the dispersed runs")] = 0,
    dispersions_file: Annotated[
        Path | None,
        typer.Option(
            "--dispersions",
            help="dispersions YAML (default: the shipped configs/dispersions.yaml)",
            show_default=False,
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Replay a mission plan through the real dynamics from the carrier's drop: landing miss
    and constraint maxima; with --monte-carlo, the dispersed closed- and open-loop flights
    (a progress bar on stderr)."""
    from ovtraj.mission.fly import fly_plan, format_flight_report
    from ovtraj.mission.plan import PlanError, read_plan

    try:
        plan = read_plan(plan_file)
        dispersions = _dispersions(dispersions_file) if monte_carlo else None
    except PlanError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    except ConfigError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    report = fly_plan(plan)
    row = report.to_dict()
    if monte_carlo:
        row["monte_carlo"] = _monte_carlo(plan, dispersions, monte_carlo, seed, as_json)
    if as_json:
        _print_json(row)
    else:
        typer.echo(format_flight_report(report))
        if monte_carlo:
            typer.echo(_format_monte_carlo(row["monte_carlo"]))
    if not report.landed_within_stated_miss:
        raise typer.Exit(code=1)


def _dispersions(path: Path | None) -> Any:
    from ovtraj.config.base import load_model
    from ovtraj.config.dispersions import DispersionsConfig, default_dispersions

    return default_dispersions() if path is None else load_model(DispersionsConfig, path)


def _monte_carlo(plan: Any, dispersions: Any, runs: int, seed: int, as_json: bool) -> dict:
    """The dispersed runs, closed and open loop, summarised (a progress bar on stderr
    unless ``as_json``)."""
    from ovtraj.mission.montecarlo import monte_carlo, monte_carlo_report, outcome_summaries

    with progress_bar("Monte Carlo runs", enabled=not as_json) as update:
        pairs = monte_carlo(plan, dispersions, runs, seed, progress=update)
    loops = outcome_summaries(plan, [c for c, _ in pairs], [o for _, o in pairs])
    return monte_carlo_report(loops["closed"], loops["open"], seed, plan.terminal.stated_miss_m)


def _format_monte_carlo(summary: dict) -> str:
    stated_km = number(summary["stated_miss_m"] / 1e3, "km")
    lines = [f"monte carlo (seed {summary['seed']}): stated miss {stated_km}"]
    for loop, s in (("closed loop", summary), ("open loop", summary["open_loop"])):
        miss = s["landing_miss_m"]

        def km(value: float | None) -> str:
            return "a failed run" if value is None else number(value / 1e3, "km")

        shown = (
            "no run landed"
            if miss is None
            else f"miss p50 {km(miss['p50'])}, p95 {km(miss['p95'])}, max {km(miss['max'])} "
            "(a failed run counts as beyond any miss)"
        )
        lines.append(
            f"  {loop}: {s['landed']}/{s['runs']} landed "
            f"({s['within_stated_miss_fraction']:.0%} within the stated miss); {shown}"
        )
        if s["failures"]:
            failed = ", ".join(f"{stage} {n}" for stage, n in s["failures"].items())
            lines.append(f"    failed: {failed}")
        for name, margin in s["path_limit_margins"].items():
            if margin is not None:
                stem, unit = split_unit(name)
                lines.append(
                    f"    {stem}: smallest margin {number(margin['smallest_margin'], unit)} "
                    f"(limit {number(margin['limit'], unit)})"
                )
        lines.extend(_format_dv_spent(s["dv_mps"]))
    return "\n".join(lines)


def _format_dv_spent(dv: dict) -> list[str]:
    """The dV lines of a loop's Monte Carlo summary (``dv_mps``)."""

    def mps(value: float | None, unit: str = "") -> str:
        return number(value, unit, decimals=2)

    lines = ["    dV spent, p50 / p95 / max over the runs that flew it (planned; p95 - planned):"]
    for name, s in dv.items():
        planned = f"planned {mps(s['planned'], 'm/s')}"
        if s["runs"] == 0:
            lines.append(f"      {name}: no run flew it ({planned})")
            continue
        margin = s["p95_minus_planned"]
        lines.append(
            f"      {name}: {mps(s['p50'])} / {mps(s['p95'])} / {mps(s['max'], 'm/s')} "
            f"({planned}; {'n/a' if margin is None else f'{margin:+.2f} m/s'}; "
            f"{s['runs']} runs)"
        )
    return lines


@app.command()
def export(
    plan_file: Annotated[Path, typer.Argument(help="mission plan (JSON or YAML)")],
    fmt: Annotated[
        str,
        typer.Option(
            "--format",
            help="oem: the whole trajectory (CCSDS 502.0 OEM 2.0); opm: the insertion state "
            "and the five impulses (OPM 2.0)",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="file to write (never overwritten)")],
    settings_file: Annotated[
        Path | None,
        typer.Option(
            "--settings",
            help="export settings YAML (default: the shipped configs/ccsds_export.yaml)",
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Export a mission plan as a CCSDS OEM or OPM (KVN, EME2000, UTC) for GMAT, Orekit, STK."""
    from ovtraj.config.base import load_model
    from ovtraj.config.export import CcsdsExportSettings, default_export_settings
    from ovtraj.mission.ccsds import FORMATS, UnflownPlan, export_plan
    from ovtraj.mission.plan import PlanError, read_plan

    fmt = fmt.lower()
    if fmt not in FORMATS:
        typer.echo(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}", err=True)
        raise typer.Exit(code=2)
    try:
        settings = (
            default_export_settings()
            if settings_file is None
            else load_model(CcsdsExportSettings, settings_file)
        )
        path, report = export_plan(read_plan(plan_file), fmt, out, settings)
    except ConfigError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    except UnflownPlan as err:
        typer.echo(f"{plan_file}: {err}", err=True)
        raise typer.Exit(code=1) from None
    except PlanError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    written = path.resolve()
    if as_json:
        row = {"format": fmt, "path": str(written), "frame": settings.ref_frame}
        if report is not None:
            row["replay_miss_distance_m"] = report.miss_distance_m
        _print_json(row)
    else:
        typer.echo(f"{fmt}: {written}")


@app.command()
def target(
    source: Annotated[
        str, typer.Argument(help="TLE or OMM file, http(s) URL, or scenario YAML with a source")
    ],
    epoch: Annotated[
        str | None,
        typer.Option("--epoch", help="fit epoch, ISO 8601 UTC (default: the scenario's, or now)"),
    ] = None,
    span_h: Annotated[
        float | None,
        typer.Option(
            "--span-h",
            help="fit span [h] (default: the scenario's target.source_settings.fit_span_h, "
            "else configs/target_sources.yaml's, 24 h)",
            show_default=False,
        ),
    ] = None,
    catalog_number: Annotated[
        int | None,
        typer.Option(
            "--catalog-number",
            help="pick one set of several (default: the only one)",
            show_default=False,
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """The project's mean elements of a TLE / OMM, fitted to its SGP4 ephemeris."""
    import warnings

    from ovtraj.target_sources import fit_source

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            fit = fit_source(source, epoch_utc=epoch, span_h=span_h, catalog_number=catalog_number)
        except ConfigError as err:
            typer.echo(str(err), err=True)
            raise typer.Exit(code=2) from None
    for warning in caught:
        typer.echo(f"warning: {warning.message}", err=True)
    row = plain(fit.to_row())
    if as_json:
        _print_json(row)
    else:
        _print_rows(f"target: {fit.source.label()}", _keyed_rows(row, digits=6))
    if not fit.converged:
        raise typer.Exit(code=1)


def _terminated(signum: int, frame: Any) -> None:
    # An exception, so that a run being written marks itself interrupted on the way out
    # (typer turns it into exit code 130).
    raise KeyboardInterrupt(f"signal {signum}")


def entry_point() -> None:
    """The ``ovtraj`` command: every fault is one line on stderr and exit 2, never a traceback.

    Exit codes: 0 done, 1 infeasible or unconverged result (or a failed check), 2 bad
    input or a fault (named), 130 interrupted (SIGINT or SIGTERM; a run being written
    says ``interrupted`` in its manifest). ``OVTRAJ_DEBUG=1`` shows tracebacks.
    """
    import signal

    signal.signal(signal.SIGTERM, _terminated)
    signal.signal(signal.SIGINT, _terminated)
    _exit(run_command())


def run_command(args: list[str] | None = None) -> int:
    """Run the command line ``args`` (default: the process's) as :func:`entry_point`
    does, and return its exit code instead of ending the process (the tests call it)."""
    import os

    from ovtraj.files import StoreError
    from ovtraj.interrupts import interrupt_of

    try:
        code = app(args=args, standalone_mode=False)
        if code == 130:
            typer.echo("interrupted", err=True)
    except typer.Exit as done:
        code = done.exit_code
    except typer.Abort:
        code = 130
        typer.echo("interrupted", err=True)
    except typer.exceptions.TyperException as err:  # usage errors: one line, exit 2
        _usage_error(err)
        code = int(getattr(err, "exit_code", 2))
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        code = 130
    except (StoreError, ConfigError) as err:
        typer.echo(str(err), err=True)
        code = 2
    except Exception as err:
        if interrupt_of(err) is not None:  # raised inside a compiled call (ovtraj.interrupts)
            typer.echo("interrupted", err=True)
            code = 130
        elif os.environ.get("OVTRAJ_DEBUG"):
            raise
        else:
            from ovtraj.formatting import printable

            typer.echo(
                f"ovtraj: internal error: {type(err).__name__}: {printable(str(err))}", err=True
            )
            code = 2
    return code if isinstance(code, int) else 0


def _usage_error(err: Exception) -> None:
    """A usage error as one line naming the command and the option, e.g. ``ovtraj run:
    Invalid value for '--samples': ...``; no arguments at all still show the help."""
    show = getattr(err, "show", None)
    message = getattr(err, "format_message", None)
    if type(err).__name__ == "NoArgsIsHelpError" or message is None:
        show() if show else typer.echo(str(err), err=True)
        return
    ctx = getattr(err, "ctx", None)
    command = ctx.command_path if ctx is not None else "ovtraj"
    text = " ".join(str(message()).split())
    typer.echo(f"{command}: {text} (see `{command} --help`)", err=True)


def _exit(code: int) -> None:
    """End the process with ``code`` once its output is flushed, without the interpreter's
    teardown: Arrow's thread pools can abort the process there after a Parquet read
    (``terminate called without an active exception``, exit -6; apache/arrow#34314, once
    in our CI after `ovtraj verify` had printed its result). Nothing is left to run at
    exit: every file is written and closed, and the kernel releases the locks."""
    import os
    import sys

    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass  # a closed pipe: nothing more can be said there
    os._exit(code)
