"""The study commands: a problem of its own YAML file, not a scenario's stage
(optimal-entry, maneuver, deorbit-burn; the seed studies 001, 003 and 004)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from ovtraj.cli.common import (
    JsonOpt,
    RowSpec,
    app,
    option_limits,
    print_json,
    print_rows,
    spec_rows,
)
from ovtraj.cli.monte_carlo import drive_here, format_stored
from ovtraj.config import ConfigError
from ovtraj.config.deorbit_burn import MonteCarloConfig
from ovtraj.formatting import duration, number
from ovtraj.paths import workspace
from ovtraj.store.records import plain

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
    """Optimal lifting entry by Gauss pseudospectral collocation (seed 001).

    Example: `ovtraj optimal-entry configs/cases/suborbital_return.yaml --transcription lgr`"""
    from ovtraj.studies.optimal_entry import (
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
        print_json(row | {k: str(v) for k, v in paths.items()})
    else:
        shown: list[tuple[str, Any]] = [("converged", row["converged"])]
        shown += spec_rows(row, _OPTIMAL_ENTRY_ROWS)
        shown += [(f"{name} file", str(path)) for name, path in paths.items()]
        print_rows(f"optimal entry: {result.name}", shown)
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
    """Quick multi-impulse manoeuvre of an upper stage, then finite burns (seed 003).

    Example: `ovtraj maneuver configs/cases/upper_stage_rendezvous.yaml --json`"""
    from ovtraj.studies.maneuver import comparison_rows, load_maneuver, solve_maneuver

    try:
        problem = load_maneuver(config)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    result = solve_maneuver(problem)
    if as_json:
        print_json(result.to_json())
    else:
        doc = plain(result.to_json())
        shown: list[tuple[str, Any]] = [("converged", doc["converged"])]
        shown += spec_rows(doc, _MANEUVER_ROWS)
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
        print_rows(f"manoeuvre: {config.stem}", shown)
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
            **option_limits(MonteCarloConfig, "runs"),
            help="also fly this many dispersed runs, stored with their pictures as the deorbit "
            "Monte Carlo flow stores them (the path is printed; default: none; a progress "
            "bar on stderr)",
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
    """Finite-thrust deorbit burn by osculating-element prediction (seed 004); with
    --monte-carlo, the dispersed runs stored with their pictures as the deorbit Monte Carlo
    flow stores them, in the config's monte_carlo.store (else the workspace's runs/; the
    run's directory and pictures are printed; runs already stored are not flown again).

    Example: `ovtraj deorbit-burn configs/cases/shuttle_deorbit.yaml --monte-carlo 100`"""
    from ovtraj.studies.deorbit_burn import deorbit_burn_report, format_report, load_deorbit_burn

    try:
        problem = load_deorbit_burn(config)
    except (ConfigError, ValueError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    stored = None
    if monte_carlo:
        stored = _deorbit_monte_carlo(problem, config, monte_carlo, strategy, as_json)
    report = deorbit_burn_report(problem, strategy=strategy, monte_carlo=stored)
    if as_json:
        # The solve's fields at the top level, the history and statistics alongside.
        flat = report["result"] | {k: v for k, v in report.items() if k != "result"}
        print_json(flat)
    else:
        typer.echo(format_report(report))
        if stored is not None:
            typer.echo(format_stored(stored))
    if not report["result"]["converged"]:
        raise typer.Exit(code=1)


def _deorbit_monte_carlo(
    problem: Any, config: Path, runs: int, strategy: int | None, as_json: bool
) -> dict[str, Any]:
    """The deorbit Monte Carlo stored by the one driver and study
    (:class:`~ovtraj.studies.deorbit_burn.stored_monte_carlo.DeorbitMonteCarlo`), as the
    flow ``flows/deorbit_monte_carlo.py`` stores it: ``runs`` runs of ``strategy`` (else
    the config's strategies) with the config's seed and batches, in its ``monte_carlo.store``
    (relative to the config's folder; else the workspace's runs/), flown in this process;
    the driver's report. A failed batch or an unusable store: one line, exit 2."""
    from ovtraj.store.paths import store_root
    from ovtraj.studies.deorbit_burn.stored_monte_carlo import DeorbitMonteCarlo
    from ovtraj.version import code_version

    settings = problem.config.monte_carlo
    study = DeorbitMonteCarlo(
        problem,
        runs=runs,
        strategies=[strategy] if strategy is not None else [int(s) for s in settings.strategies],
        seed=settings.seed,
        root=store_root(settings.store, config.resolve().parent, None),
        code=code_version(),
        batch_size=settings.batch_size,
    )
    return drive_here(study, as_json=as_json)
