"""The surrogate pipeline's commands: the whole pipeline, the surrogate front of a stored
run, the mission plan of a front point (pipeline, optimize, plan)."""

from __future__ import annotations

import logging
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from ovtraj.cli.common import (
    AllowUnconvergedOpt,
    ConfigArg,
    JsonOpt,
    StoreOpt,
    TargetOpt,
    app,
    exits_on,
    print_json,
    print_rows,
    renamed_options,
    run_store,
)
from ovtraj.cli.doe import (
    DaskAddressOpt,
    RunnerOpt,
    SamplesOpt,
    SeedOpt,
    WorkersOpt,
    launch_fit_or_exit,
    solve_here,
)
from ovtraj.cli.picking import (
    MaxDvOpt,
    MaxTimeOpt,
    MinLoadOpt,
    PickCommand,
    PickIndexOpt,
    WeightsOpt,
    pick_from_options,
    print_plan,
)
from ovtraj.cli.progress import echo, progress_bar
from ovtraj.config import Scenario
from ovtraj.config.orchestration import load_orchestration
from ovtraj.formatting import number
from ovtraj.store.backends import location
from ovtraj.store.files import StoreError
from ovtraj.units import S_PER_HOUR
from ovtraj.version import code_version

if TYPE_CHECKING:  # the driver, the store and the surrogates load the numerics: imported when run
    from ovtraj.pipeline import FitOutcome, FrontOutcome
    from ovtraj.pipeline.drive import PipelineOutcome
    from ovtraj.pipeline.prepare import PipelineInputs
    from ovtraj.runs import Run


# A pipeline result named by any run of its family, as `front` and `plan` take it.
FamilyRunArg = Annotated[
    str,
    typer.Argument(
        help="any run of a pipeline family: its DoE run, an infill run (also a pruned one) or "
        "the final run"
    ),
]
PipelineIdOpt = Annotated[
    str | None, typer.Option("--pipeline", help="pipeline id (default: the newest)")
]


def _run_scenario(stored: Run, config: Path | None) -> Scenario:
    """The scenario a stored run holds (``config``: another file's settings on it); a bad
    one is one line, exit 2."""
    from ovtraj.pipeline import run_scenario

    with exits_on(ValueError):
        scenario = run_scenario(stored, config)
    return scenario


def _print_front(front: Any) -> None:
    typer.echo(
        "  front  sample   H_P0 [km]  H_dp [km]  t_dsp [h]   T [h]  dV [m/s]  M [kg]  origin"
    )
    for row in front.itertuples(index=False):
        typer.echo(
            f"  {row.front_index:5d}  {row.sample_id:6d}  {row.parking_altitude_km:9.2f}  "
            f"{row.preparation_altitude_km:9.2f}  {row.separation_delay_h:9.2f}  "
            f"{row.t_total_s / S_PER_HOUR:6.1f}  {row.dv_total_mps:8.2f}  {row.m_load_kg:6.1f}  "
            f"{row.origin}"
        )
    typer.echo(
        "  H_P0: parking (launch insertion) altitude, H_dp: preparation orbit altitude, "
        "t_dsp: separation delay after docking; T, dV lower and M (payload) higher is better"
    )


@app.command(cls=PickCommand)
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
    workers: WorkersOpt = None,
    dask_address: DaskAddressOpt = None,
    allow_unconverged: AllowUnconvergedOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """The whole pipeline: DoE, surrogates, NSGA-II, verification and infill, the plan
    and its HTML report. Says whether the verification loop converged and why it stopped.

    Exit 0: the loop converged. Exit 1: it did not (the verdict line says why; the front,
    plan and report are stored and printed all the same; --allow-unconverged: exit 0), or
    the plan does not fly its front point, or the optimiser stopped. Exit 2: bad input or
    a fault, one line naming it. The mission flow says the same by its state: Failed with
    the verdict as its message (require_converged=false: Completed, named "Not
    converged").

    Example: `ovtraj pipeline --samples 24 --weights 1,1,2 --max-dv-mps 250`"""
    from ovtraj.pipeline.prepare import prepare_pipeline

    # refused before any work
    chosen = pick_from_options(pick, weights, max_time_h, max_dv, min_payload)
    with exits_on(ValueError):
        inputs = prepare_pipeline(
            config,
            pick=chosen,
            fit_missing=partial(solve_here, as_json=as_json),
            samples=samples,
            seed=seed,
            from_run=from_run,
            refit=refit,
            store=store_root,
            target=target,
            runner=runner,
            workers=workers,
            dask_address=dask_address,
            as_options=True,
        )
    outcome = _drive(inputs, as_json)
    if as_json:
        print_plan(outcome.planned, True, _outcome_json(outcome))
    else:
        _print_outcome(outcome)
        print_plan(outcome.planned, False, {})
    if not outcome.converged and not allow_unconverged:
        raise typer.Exit(code=1)


def _views(directory: Any) -> tuple[Path, list[Path]]:
    """The verified front's plot and the last round's views drawn with the result (parity
    plots and the surrogate front), absolute."""
    front_plot = location(directory / "front.png").resolve()
    views = sorted(
        path.resolve() for path in location(directory).glob("*.png") if path.name != "front.png"
    )
    return front_plot, views


def _outcome_json(outcome: PipelineOutcome) -> dict[str, Any]:
    """``ovtraj pipeline --json``'s fields before the plan's."""
    result = outcome.result
    front_plot, views = _views(result.directory)
    return {
        "doe_run": outcome.doe_run.id,
        "final_run": result.final_run,
        "pipeline_id": result.pipeline_id,
        "converged": outcome.converged,
        "stop_reason": result.summary["stop_reason"],
        "verdict": outcome.verdict,
        "real_evaluations": result.summary["real_evaluations"],
        "hypervolume": result.summary["hypervolume"],
        "front_points": len(result.front),
        "front": str(location(result.front_path).resolve()),
        "front_plot": str(front_plot),
        "views": [str(p) for p in views],
    }


def _print_outcome(outcome: PipelineOutcome) -> None:
    """The verified front, the verdict and the paths of the front and its plots."""
    result = outcome.result
    front_plot, views = _views(result.directory)
    typer.echo(
        f"verified front of DoE run {outcome.doe_run.id} (pipeline {result.pipeline_id}, final "
        f"run {result.final_run}):"
    )
    _print_front(result.front)
    typer.echo(outcome.verdict)
    typer.echo(f"front: {location(result.front_path).resolve()}")
    typer.echo(f"plot: {front_plot}")
    for path in views:
        typer.echo(f"plot: {path}")


def _drive(inputs: PipelineInputs, as_json: bool) -> PipelineOutcome:
    """The library's driver (:func:`ovtraj.pipeline.drive.drive_pipeline`, as the mission
    flow) with the batches on the library's pool of ``inputs.choice``, a progress bar per
    run; a failure is one line on stderr, exit 1 (the optimiser stopped, a plan that does
    not fly its front point) or 2."""
    from ovtraj.mission.plan_check import PlanMismatch
    from ovtraj.pipeline import OptimiserStopped, PipelineError
    from ovtraj.pipeline.drive import drive_pipeline
    from ovtraj.runs.execute import BatchesFailed, PoolBatches
    from ovtraj.runs.runners import ClusterError
    from ovtraj.surrogate import SurrogateError

    say = logging.getLogger("ovtraj.pipeline").info if as_json else echo
    orchestration = load_orchestration()
    batches = PoolBatches(
        inputs.scenario,
        inputs.launch_fit,
        inputs.choice,
        dask=orchestration.dask,
        time_limit_s=orchestration.flows.doe_s,
        progress=say,
        progress_bar=lambda label: progress_bar(label, enabled=not as_json),
    )
    faults = (StoreError, PipelineError, SurrogateError, ValueError, ClusterError, BatchesFailed)
    # The unmet results first: the optimiser's stop is a PipelineError too.
    with exits_on(*faults), exits_on(OptimiserStopped, PlanMismatch, code=1):
        outcome = drive_pipeline(
            inputs.scenario,
            inputs.launch_fit,
            inputs.store,
            code_version(),
            batches,
            inputs.request,
            progress=say,
        )
    return outcome


# The scenario was an option, `--config FILE`, before it was an argument as everywhere
# else: still taken for one release.
@app.command(cls=renamed_options({"--config": "CONFIG"}))
def optimize(
    run_id: Annotated[
        str, typer.Argument(metavar="RUN_ID", help="a stored DoE run (`ovtraj runs`)")
    ],
    config: Annotated[
        Path | None,
        typer.Argument(
            metavar="CONFIG",
            help="scenario YAML whose surrogate and optimisation settings to use (default: "
            "the run's own)",
            show_default=False,
        ),
    ] = None,
    refit: Annotated[
        bool, typer.Option("--refit", help="refit and re-optimise even when stored")
    ] = False,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Fit the surrogates on a stored run's samples and run NSGA-II on them (no simulation).

    Example: `ovtraj optimize 1fe6042587a62a93 --refit`"""
    stored, fitted, front = _fitted_front(run_id, config, refit, store_root)
    if as_json:
        print_json(_optimized_json(stored, fitted, front))
    else:
        print_rows(f"surrogate front of run {stored.id}", _optimized_rows(fitted, front))
    if front.matches_stored is False:
        raise typer.Exit(code=1)


def _fitted_front(
    run_id: str, config: Path | None, refit: bool, store_root: str | None
) -> tuple[Run, FitOutcome, FrontOutcome]:
    """The stored run, its surrogates fitted and their NSGA-II front (each loaded from the
    run when stored, unless ``refit``); a fault is one line, exit 2, the optimiser's stop
    exit 1."""
    from ovtraj.pipeline import (
        OptimiserStopped,
        PipelineError,
        fit_step,
        front_step,
        training_data,
    )
    from ovtraj.pipeline.steps import fitting_pool
    from ovtraj.surrogate import SurrogateError

    faults = (StoreError, PipelineError, SurrogateError, ValueError)
    with exits_on(*faults), exits_on(OptimiserStopped, code=1):
        stored = run_store(store_root).run(run_id)
        scenario = _run_scenario(stored, config)
        code = code_version()
        data = training_data(stored)
        with fitting_pool(scenario, len(data)) as pool:
            fitted = fit_step(stored, data, scenario, code, refit=refit, executor=pool)
        front = front_step(stored, fitted, scenario, code, refit=refit)
    return stored, fitted, front


def _models(fitted: FitOutcome) -> list[tuple[str, str]]:
    """``(output, model)`` of each output: the candidate the validation selected, then
    the outputs no regressor fits."""
    from ovtraj.pipeline.features import unregressed

    validation = fitted.surrogates.validation
    chosen = validation[validation["selected"].astype(bool)]
    return [
        *((row.model, row.candidate) for row in chosen.itertuples(index=False)),
        *unregressed(fitted.surrogates).items(),
    ]


def _optimized_json(stored: Run, fitted: FitOutcome, front: FrontOutcome) -> dict[str, Any]:
    return {
        "run_id": stored.id,
        "surrogates": str(fitted.directory.resolve()),
        "loaded_from_store": fitted.reused,
        "models": [{"model": output, "candidate": model} for output, model in _models(fitted)],
        "front": str((front.directory / "front.parquet").resolve()),
        "front_points": len(front.front),
        "hypervolume": front.front.hypervolume,
        "identical_to_stored_front": front.matches_stored,
    }


def _optimized_rows(fitted: FitOutcome, front: FrontOutcome) -> list[tuple[str, Any]]:
    rows: list[tuple[str, Any]] = [
        ("surrogates", str(fitted.directory.resolve())),
        ("loaded from the store", fitted.reused),
    ]
    rows += [(f"{output} model", model) for output, model in _models(fitted)]
    rows += [
        ("front", str((front.directory / "front.parquet").resolve())),
        ("front points", len(front.front)),
        ("hypervolume", number(front.front.hypervolume, "", 6)),
    ]
    if front.matches_stored is not None:
        rows.append(("identical to the stored front", front.matches_stored))
    return rows


@app.command()
def front(
    run_id: FamilyRunArg,
    pipeline_id: PipelineIdOpt = None,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """The verified front of a run's pipeline result, as `ovtraj pipeline` printed it:
    the indices `plan --pick` and `pipeline --pick` take, each point's design and real
    objectives, and the loop's verdict.

    Example: `ovtraj front 1fe6042587a62a93` then `ovtraj plan 1fe6042587a62a93 --pick 3`."""
    from ovtraj.pipeline import PipelineError
    from ovtraj.pipeline.catalog import family_root
    from ovtraj.pipeline.planning import find_pipeline

    with exits_on(StoreError, PipelineError, ValueError):
        stored = family_root(run_store(store_root), run_id)
        result = find_pipeline(stored, pipeline_id)
    summary = result.summary
    converged = bool(summary.get("converged"))
    if as_json:
        print_json(
            {
                "doe_run": stored.id,
                "pipeline_id": result.pipeline_id,
                "final_run": result.final_run,
                "converged": converged,
                "hypervolume": summary.get("hypervolume"),
                "front": str(location(result.front_path).resolve()),
                "points": result.front.to_dict(orient="records"),
            }
        )
        return
    typer.echo(
        f"verified front of DoE run {stored.id} (pipeline {result.pipeline_id}, final run "
        f"{result.final_run}): {len(result.front)} points, hypervolume "
        f"{number(summary.get('hypervolume'), '', 6)}, "
        + ("converged" if converged else "not converged")
    )
    _print_front(result.front)
    typer.echo(f"front: {location(result.front_path).resolve()}")


@app.command(cls=PickCommand)
def plan(
    run_id: FamilyRunArg,
    pick: PickIndexOpt = None,
    weights: WeightsOpt = None,
    max_time_h: MaxTimeOpt = None,
    max_dv: MaxDvOpt = None,
    min_payload: MinLoadOpt = None,
    pipeline_id: PipelineIdOpt = None,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Write the mission plan (JSON and YAML), its plots and its HTML report, of a point
    of the verified front of a run's pipeline result.

    Example: `ovtraj plan 1fe6042587a62a93 --max-time-h 150 --min-payload-kg 400`"""
    from ovtraj.mission.plan import PlanError
    from ovtraj.mission.plan_check import PlanMismatch
    from ovtraj.pipeline import PipelineError
    from ovtraj.pipeline.catalog import family_root
    from ovtraj.pipeline.planning import find_pipeline, write_mission_plan

    # refused before any work
    chosen = pick_from_options(pick, weights, max_time_h, max_dv, min_payload)
    # A plan that does not fly its front point is an unmet result (a PlanError too).
    with exits_on(StoreError, PipelineError, PlanError, ValueError), exits_on(PlanMismatch, code=1):
        store = run_store(store_root)
        stored = family_root(store, run_id)
        scenario = _run_scenario(stored, None)
        result = find_pipeline(stored, pipeline_id)
        fit = launch_fit_or_exit(scenario, as_json=as_json)
        planned = write_mission_plan(scenario, fit, store, result, chosen)
    print_plan(planned, as_json, {"doe_run": stored.id, "pipeline_id": result.pipeline_id})
