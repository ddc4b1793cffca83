"""The mission plan's commands: fly it through the real dynamics (with its dispersed
Monte Carlo runs) and export it as a CCSDS OEM or OPM (fly, export)."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer

from ovtraj.cli.common import JsonOpt, app, option_limits, print_json
from ovtraj.cli.monte_carlo import drive_here, format_stored
from ovtraj.config import ConfigError
from ovtraj.config.base import load_model
from ovtraj.config.dispersions import DispersionsConfig, MonteCarloExecution, default_dispersions
from ovtraj.config.export import ExportFormat
from ovtraj.formatting import number, split_unit


class Fidelity(StrEnum):
    """The sky ``ovtraj fly`` flies the plan under."""

    j2 = "j2"
    high = "high"


@app.command()
def fly(
    plan_file: Annotated[Path, typer.Argument(help="mission plan (JSON or YAML)")],
    monte_carlo: Annotated[
        int,
        typer.Option(
            "--monte-carlo",
            min=0,
            max=option_limits(MonteCarloExecution, "runs")["max"],
            help="also fly this many dispersed runs, closed loop and open loop, stored with "
            "their pictures as the Monte Carlo flow stores them (the path is printed; 0: none)",
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
    fidelity: Annotated[
        Fidelity,
        typer.Option(
            "--fidelity",
            help="j2: the open-loop replay under the plan's model; high: the closed loop "
            "under the high-fidelity force model (configs/force_model.yaml) beside the plan "
            "and the J2 closed loop (the Monte Carlo's closed loop too)",
        ),
    ] = Fidelity.j2,
    force_model_file: Annotated[
        Path | None,
        typer.Option(
            "--force-model",
            help="force model YAML for --fidelity high (default: the shipped "
            "configs/force_model.yaml)",
            show_default=False,
        ),
    ] = None,
    allow_long_run: Annotated[
        bool,
        typer.Option(
            "--allow-long-run",
            help="fly --monte-carlo beyond fly_monte_carlo_max_runs of configs/io_limits.yaml "
            "(its time estimate is printed first; the Monte Carlo flow runs it in parallel)",
        ),
    ] = False,
    as_json: JsonOpt = False,
) -> None:
    """Replay a mission plan through the real dynamics from the carrier's drop: landing miss
    and constraint maxima; with --monte-carlo, the dispersed closed- and open-loop flights
    (a progress bar on stderr); with --fidelity high, the closed loop under the
    high-fidelity force model: each manoeuvre's dV against the plan's, the arrival and
    landing misses, the path-limit margins. Without --monte-carlo, the flight of a plan of
    a run store is stored beside it (<plan>-flight-j2.json, <plan>-flight-high.json; never
    overwritten: another flight already there is refused, exit 2) and the plan's report
    is written again with it (both paths printed).

    Example: `ovtraj fly plan-sample-30.json --monte-carlo 20 --seed 1`"""
    plan, dispersions, force_model = _fly_inputs(
        plan_file, fidelity.value, dispersions_file, force_model_file, bool(monte_carlo)
    )
    if monte_carlo:  # the estimate said (stderr) before the work; refused beyond the limit
        typer.echo(_monte_carlo_estimate(monte_carlo, fidelity.value, allow_long_run), err=True)
    row, landed, text = _nominal_flight(plan, dispersions, force_model, force_model_file)
    if monte_carlo:
        row["monte_carlo"] = _monte_carlo(
            plan, dispersions, monte_carlo, seed, as_json, force_model, dispersions_file
        )
    if as_json:
        print_json(row)
    else:
        typer.echo(text)
        if monte_carlo:
            typer.echo(_format_monte_carlo(row["monte_carlo"]))
            typer.echo(format_stored(row["monte_carlo"]))
    if not monte_carlo:  # the Monte Carlo's runs are stored by its own driver
        _store_flight(plan_file, plan, row, as_json)
    if not landed:
        raise typer.Exit(code=1)


def _fly_inputs(
    plan_file: Path,
    fidelity: str,
    dispersions_file: Path | None,
    force_model_file: Path | None,
    monte_carlo: bool,
) -> tuple[Any, Any, Any]:
    """The plan, the dispersions (only for a Monte Carlo or the high-fidelity flight) and
    the force model (``fidelity`` high only); a bad file: one line, exit 2."""
    from ovtraj.mission.high_fidelity import high_fidelity_settings
    from ovtraj.mission.plan import PlanError
    from ovtraj.mission.plan_store import read_plan

    try:
        plan = read_plan(plan_file)
        dispersions = _dispersions(dispersions_file) if monte_carlo or fidelity == "high" else None
        force_model = high_fidelity_settings(plan, fidelity, force_model_file)
    except PlanError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    except ConfigError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    return plan, dispersions, force_model


def _nominal_flight(
    plan: Any, dispersions: Any, force_model: Any, force_model_file: Path | None
) -> tuple[dict, bool, str]:
    """The plan flown without dispersions: the open-loop replay (no ``force_model``), else
    the closed loop under both skies (:func:`_high_fidelity`); its row, whether it landed
    within the stated miss, and its text."""
    if force_model is None:
        from ovtraj.mission.flight_report import format_flight_report
        from ovtraj.mission.fly import fly_plan

        report = fly_plan(plan)
        return report.to_dict(), report.landed_within_stated_miss, format_flight_report(report)
    from ovtraj.paths import config_path

    read = config_path("force_model.yaml") if force_model_file is None else force_model_file
    row, landed = _high_fidelity(plan, dispersions, force_model, str(Path(read).resolve()))
    return row, landed, row.pop("text")


def _store_flight(plan_file: Path, plan: Any, row: dict, as_json: bool) -> None:
    """The flight stored beside a plan of a run store, its report written again
    (:func:`ovtraj.pipeline.plan_flights.store_flight`); the paths said on stdout (stderr
    with --json). A plan elsewhere: nothing stored, said on stderr. A flight of other
    content already stored (another code version): kept, this one not stored, said on
    stderr, the exit code the flight's own. A plan's file that is not its marker's: one
    line, exit 2."""
    from ovtraj.pipeline.plan_flights import OtherFlightStored, store_flight
    from ovtraj.store.files import StoreError

    try:
        stored = store_flight(plan_file, plan, row)
    except OtherFlightStored as err:
        typer.echo(str(err), err=True)
        return
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    if stored is None:
        typer.echo(
            f"{plan_file}: not a plan of a run store (<store>/<run>/pipeline/<id>/plans/): "
            "this flight is not stored",
            err=True,
        )
        return
    said = "flight stored" if stored.new else "flight already stored"
    typer.echo(f"{said}: {stored.path}", err=as_json)
    if stored.report is not None:
        typer.echo(f"report: {stored.report}", err=as_json)
    else:
        typer.echo(
            f"{stored.path.parent}: the plan's report has no section of flights (written "
            "before flights were stored): `ovtraj plan RUN --pick N` writes it again",
            err=True,
        )


def _high_fidelity(plan: Any, dispersions: Any, force_model: Any, source: str) -> tuple[dict, bool]:
    """The nominal closed loop under both skies, reported side by side with the plan;
    ``source``: the force-model file read."""
    from ovtraj.mission.sky_flight import fidelity_report, fly_nominal, format_fidelity_report

    j2 = fly_nominal(plan, dispersions)
    high = fly_nominal(plan, dispersions, force_model)
    report = fidelity_report(plan, j2, high, force_model, source)
    return {**report, "text": format_fidelity_report(report)}, report["landed_within_stated_miss"]


def _monte_carlo_estimate(runs: int, fidelity: str, allowed: bool) -> str:
    """The line that says how long ``runs`` dispersed flights take here (one process);
    typer.Exit(2) after saying it when ``runs`` is beyond ``fly_monte_carlo_max_runs`` and
    not ``allowed``."""
    from ovtraj.config.io_limits import io_limits
    from ovtraj.formatting import duration

    limits = io_limits()
    name = f"fly_monte_carlo_{fidelity}_s_per_run"
    each = getattr(limits, name)
    line = (
        f"--monte-carlo {runs}: about {duration(runs * each)} in this process "
        f"({each:g} s a run: {name} of configs/io_limits.yaml)"
    )
    if runs > limits.fly_monte_carlo_max_runs and not allowed:
        typer.echo(
            f"{line}: more than fly_monte_carlo_max_runs = {limits.fly_monte_carlo_max_runs}; "
            "give --allow-long-run to fly it, or run the Monte Carlo flow "
            "(flows/mission_monte_carlo.py) on several workers",
            err=True,
        )
        raise typer.Exit(code=2)
    return line


def _dispersions(path: Path | None) -> Any:
    return default_dispersions() if path is None else load_model(DispersionsConfig, path)


def _monte_carlo(
    plan: Any,
    dispersions: Any,
    runs: int,
    seed: int,
    as_json: bool,
    force_model: Any = None,
    dispersions_file: Path | None = None,
) -> dict:
    """The dispersed runs, closed and open loop, flown in this process (a progress bar on
    stderr unless ``as_json``) and stored as the Monte Carlo flow stores them, by the same
    driver and study (:class:`ovtraj.runs.plan_monte_carlo.PlanMonteCarlo`): the same run
    id, rows, summary and pictures, in the dispersions file's ``execution.store`` (else the
    workspace's runs/). The report, with the run's directory and pictures; the closed loop
    under ``force_model``'s sky when given. A failed batch or an unusable store: one line,
    exit 2 (the stored batches are kept: the same command flies the missing runs)."""
    from ovtraj.runs.plan_monte_carlo import PlanMonteCarlo, store_of
    from ovtraj.version import code_version

    study = PlanMonteCarlo(
        plan=plan,
        dispersions=dispersions,
        runs=runs,
        seed=seed,
        root=store_of(dispersions, dispersions_file),
        code=code_version(),
        batch_size=dispersions.execution.batch_size,
        force_model=force_model,
    )
    return drive_here(study, as_json=as_json)


def _format_monte_carlo(summary: dict) -> str:
    stated_km = number(summary["stated_miss_m"] / 1e3, "km")
    lines = [f"monte carlo (seed {summary['seed']}): stated miss {stated_km}"]
    closed = "closed loop" + (" (high-fidelity sky)" if summary.get("fidelity") == "high" else "")
    opened = "open loop" + (" (J2 replay)" if summary.get("fidelity") == "high" else "")
    for loop, s in ((closed, summary), (opened, summary["open_loop"])):
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
    chosen: Annotated[
        ExportFormat,
        typer.Option(
            "--format",
            case_sensitive=False,
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
    """Export a mission plan as a CCSDS OEM or OPM (KVN, EME2000, UTC) for GMAT, Orekit, STK.

    Example: `ovtraj export plan-sample-30.json --format oem --out chosen.oem`"""
    from ovtraj.config.export import CcsdsExportSettings, default_export_settings
    from ovtraj.mission.ccsds import UnflownPlan, export_plan
    from ovtraj.mission.plan import PlanError
    from ovtraj.mission.plan_store import read_plan
    from ovtraj.tracking.catalog_rows import plan_id
    from ovtraj.tracking.lineage import record_export

    fmt = chosen.value
    try:
        settings = (
            default_export_settings()
            if settings_file is None
            else load_model(CcsdsExportSettings, settings_file)
        )
        plan = read_plan(plan_file)
        identity = plan_id(plan.to_dict())
        path, report = export_plan(plan, fmt, out, settings, identity)
        record_export(plan_file, plan.to_dict(), path, fmt)
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
        print_json(row)
    else:
        typer.echo(f"{fmt}: {written}")
