"""The launch-window scan: ``ovtraj window SCENARIO --days N``, a whole pipeline per launch
day (docs/window.md)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from ovtraj.cli.common import (
    AllowUnconvergedOpt,
    ConfigArg,
    JsonOpt,
    StoreOpt,
    TargetOpt,
    app,
    exits_on,
    option_limits,
    print_json,
    run_store,
    table_console,
)
from ovtraj.cli.doe import DaskAddressOpt, SamplesOpt, SeedOpt
from ovtraj.cli.picking import (
    MaxDvOpt,
    MaxTimeOpt,
    MinLoadOpt,
    PickCommand,
    WeightsOpt,
    pick_from_options,
)
from ovtraj.cli.progress import echo, progress_bar
from ovtraj.config import Scenario
from ovtraj.config.io_limits import shown_text
from ovtraj.config.mission import DoeSettings
from ovtraj.config.orchestration import load_orchestration
from ovtraj.formatting import quantity
from ovtraj.paths import scenario_file
from ovtraj.store.files import StoreError
from ovtraj.units import S_PER_HOUR
from ovtraj.version import code_version

if TYPE_CHECKING:  # the runners load the numerics: imported when run
    from ovtraj.runs.runners import RunnerChoice

DaysOpt = Annotated[
    int,
    typer.Option(
        "--days",
        help="launch days from the scenario's launch.launch_date_utc, a whole pipeline each "
        "(1 to configs/window.yaml max_days)",
        show_default=False,
    ),
]
DaysRunnerOpt = Annotated[
    str | None,
    typer.Option(
        "--runner",
        help="serial | threads | processes | dask: where the days run, a day's pipeline "
        "whole in one process (default: the config's mission.doe.task_runner; serial and "
        "threads: one day after another)",
        show_default=False,
    ),
]
WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        **option_limits(DoeSettings, "workers"),
        help="days at once on --runner processes or a local Dask cluster (default: the "
        "config's mission.doe.workers)",
        show_default=False,
    ),
]


@app.command(cls=PickCommand)
def window(
    days: DaysOpt,
    config: ConfigArg = None,
    samples: SamplesOpt = None,
    seed: SeedOpt = None,
    weights: WeightsOpt = None,
    max_time_h: MaxTimeOpt = None,
    max_dv: MaxDvOpt = None,
    min_payload: MinLoadOpt = None,
    store_root: StoreOpt = None,
    target: TargetOpt = None,
    runner: DaysRunnerOpt = None,
    workers: WorkersOpt = None,
    dask_address: DaskAddressOpt = None,
    allow_unconverged: AllowUnconvergedOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Launch-window scan: the whole pipeline for each of ``--days`` launch days (each
    day's runs, front, plan and report in the run store, as ``ovtraj pipeline``), the
    plan each day picks by ``--weights``, and the best day. Writes a table, a plot of
    T_total, dV_total and M_load against the launch day, a porkchop (dV_total and T_total
    over the launch day and configs/window.yaml's porkchop variable, each day's plan
    swept) and an HTML page linking each day's report, in the run store's windows/
    folder. A second scan with nothing changed simulates nothing.

    Exit 0: every planned day's verification loop converged. Exit 1: no day has a plan,
    or a day's loop did not converge (the line after the table names those days; every
    day is stored and the window written all the same; --allow-unconverged: exit 0).
    Exit 2: bad input or a fault, one line naming it. The window flow says the same by
    its state: Failed with that line as its message (require_converged=false: Completed,
    named "Not converged").

    Example: `ovtraj window --days 7 --runner processes --workers 2`"""
    from ovtraj.window.records import window_verdict

    # refused before any work
    chosen = pick_from_options(None, weights, max_time_h, max_dv, min_payload)
    _check_days(days)
    scenario, choice = _scenario_and_runner(config, target, runner, dask_address, workers)
    store = run_store(store_root, scenario, config)
    outcome = _scan(scenario, days, samples, seed, chosen, store, choice, as_json)
    converged, verdict = window_verdict(outcome.records)
    if as_json:
        print_json(_window_json(outcome, store, converged, verdict))
    else:
        _print_window(outcome, store, verdict)
    if outcome.best_day is None or not (converged or allow_unconverged):
        raise typer.Exit(code=1)


def _check_days(days: int) -> None:
    """``--days`` within 1..configs/window.yaml ``max_days``, else one line, exit 2."""
    # Here: the settings' model costs ~8 ms that `ovtraj --help` does without.
    from ovtraj.window.settings import load_window_settings

    limit = load_window_settings().max_days
    if not 1 <= days <= limit:
        shown = f"must lie in 1..{limit} (configs/window.yaml max_days)"
        typer.echo(f"--days {days}: {shown}", err=True)
        raise typer.Exit(code=2)


def _scenario_and_runner(
    config: Path | None,
    target: str | None,
    runner: str | None,
    dask_address: str | None,
    workers: int | None,
) -> tuple[Scenario, RunnerChoice]:
    """The scenario (a mission and a launch section needed) and where the days run, as a
    pipeline's (:mod:`ovtraj.runs.preparation`); bad input is one line, exit 2."""
    from ovtraj.runs.preparation import mission_scenario, runner_choice

    with exits_on(ValueError):
        scenario = mission_scenario(config, target)
        if scenario.launch is None:
            raise ValueError(f"{scenario_file(config)}: the scenario has no launch section")
        choice = runner_choice(scenario.mission.doe, runner, dask_address, workers, as_options=True)
    return scenario, choice


def _window_json(outcome: Any, store: Any, converged: bool, verdict: str) -> dict[str, Any]:
    best = outcome.best_day
    return {
        "window_id": outcome.window_id,
        "reused": outcome.reused,
        "converged": converged,
        "verdict": verdict,
        "days": len(outcome.records),
        "planned_days": outcome.planned_days,
        "best_day": best,
        "best_date": None if best is None else outcome.records[best]["date"],
        "rows": _json_rows(outcome, store),
        "files": {name: str(path.resolve()) for name, path in outcome.files.items()},
    }


# The window's files as the command prints them: (label, file name).
_FILES = (
    ("table", "window.parquet"),
    ("plot", "window.png"),
    ("plot", "window.svg"),
    ("porkchop", "porkchop.parquet"),
    ("porkchop", "porkchop.png"),
    ("porkchop", "porkchop.svg"),
    ("page", "window.html"),
    ("window", "window.json"),
)


def _print_window(outcome: Any, store: Any, verdict: str) -> None:
    """The days' table, the verdict, the best day and the window's files."""
    _print_table(outcome, store)
    typer.echo(verdict)
    best = outcome.best_day
    if best is not None:
        record = outcome.records[best]
        typer.echo(f"best day: {record['date']} (day {best}), score {record['score']:.4f}")
    for label, name in _FILES:
        typer.echo(f"{label}: {outcome.files[name].resolve()}")


def _scan(
    scenario: Any,
    days: int,
    samples: int | None,
    seed: int | None,
    pick: Any,
    store: Any,
    choice: Any,
    as_json: bool,
) -> Any:
    """The library's driver (:func:`ovtraj.window.scan.scan_window`, as the window flow)
    with the days on the library's pool; a fault is one line on stderr, exit 2."""
    from ovtraj.runs.execute import BatchesFailed
    from ovtraj.runs.runners import ClusterError
    from ovtraj.surrogate import SurrogateError
    from ovtraj.window.scan import PoolDays, WindowRequest, scan_window

    say = logging.getLogger("ovtraj.window").info if as_json else echo
    request = WindowRequest(days=days, samples=samples, seed=seed, pick=pick)
    runner = PoolDays(choice, load_orchestration().dask)
    faults = (StoreError, SurrogateError, ValueError, ClusterError, BatchesFailed)
    with exits_on(*faults), progress_bar("launch grid", enabled=not as_json) as update:
        outcome = scan_window(
            scenario, request, store, code_version(), runner, progress=say, grid_progress=update
        )
    return outcome


def _plan_path(record: dict[str, Any], store: Any) -> str:
    return "-" if record["plan"] is None else str(store.root / record["plan"])


def _json_rows(outcome: Any, store: Any) -> list[dict[str, Any]]:
    rows = []
    for record in outcome.records:
        t_total = record["t_total_s"]
        rows.append(
            {
                "day": record["day"],
                "date": record["date"],
                "status": record["status"],
                "reason": record["reason"],
                "t_total_h": None if t_total is None else t_total / S_PER_HOUR,
                "dv_total_mps": record["dv_total_mps"],
                "m_load_kg": record["m_load_kg"],
                "score": record["score"],
                "converged": record["converged"],
                "verdict": record["verdict"],
                "best": record["day"] == outcome.best_day,
                "plan": None if record["plan"] is None else _plan_path(record, store),
            }
        )
    return rows


def _print_table(outcome: Any, store: Any) -> None:
    """The days as a table on stdout (rich; full width when not a terminal)."""
    table = Table(
        title=f"launch window {outcome.window_id}" + (" (stored)" if outcome.reused else ""),
        title_justify="left",
        box=None,
        pad_edge=False,
    )
    for column in ("day", "date", "T_total", "dV_total", "M_load", "score", "converged", "plan"):
        table.add_column(column, no_wrap=True)
    for record in outcome.records:
        best = record["day"] == outcome.best_day
        if record["status"] != "planned":
            date, reason = shown_text(record["date"]), shown_text(record["reason"])
            table.add_row(str(record["day"]), date, "-", "-", "-", "-", "-", reason)
            continue
        table.add_row(
            str(record["day"]),
            shown_text(record["date"]) + (" *" if best else ""),
            quantity(record["t_total_s"], "s"),
            quantity(record["dv_total_mps"], "m/s"),
            quantity(record["m_load_kg"], "kg"),
            f"{record['score']:.4f}",
            str(record["converged"]),
            shown_text(_plan_path(record, store)),
        )
    # A day's record is stored text (a reused window's is read back): escaped and cut
    # (shown_text), and no rich markup.
    table_console().print(table)
