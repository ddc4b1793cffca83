"""The ``run`` command (a DoE of the whole mission into the run store) and what the
``pipeline`` and ``window`` commands share with it: the runner options and their choice
(:func:`runner_choice`), the sample options, the launch fit a run needs."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any

import typer

from ovtraj.cli.common import (
    ConfigArg,
    JsonOpt,
    StoreOpt,
    TargetOpt,
    app,
    keyed_rows,
    loaded_scenario,
    option_limits,
    print_json,
    print_rows,
    run_store,
)
from ovtraj.cli.progress import echo, progress_bar
from ovtraj.config import Scenario
from ovtraj.config.mission import DoeSettings

if TYPE_CHECKING:
    from ovtraj.runs.runners import RunnerChoice

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

WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        **option_limits(DoeSettings, "workers"),
        help="batches at once on --runner threads, processes or a local Dask cluster "
        "(default: the config's mission.doe.workers; the batches and their results are the "
        "same for any number)",
        show_default=False,
    ),
]


SamplesOpt = Annotated[
    int | None,
    typer.Option(
        "--samples",
        **option_limits(DoeSettings, "samples"),
        help="DoE samples (default: the config's mission.doe.samples)",
        show_default=False,
    ),
]
SeedOpt = Annotated[
    int | None,
    typer.Option(
        "--seed",
        **option_limits(DoeSettings, "seed"),
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
    workers: WorkersOpt = None,
    dask_address: DaskAddressOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """DoE of the whole mission into the run store (a progress bar on stderr; a line per
    batch on stdout, on stderr with --json).

    ``--runner`` says where the batches run (``serial`` here; a pool of ``--workers``
    ``threads`` or ``processes``; ``dask``: the cluster at ``--dask-address`` or a local
    one of ``--workers`` processes); each batch is stored where the run is by the process
    that computed it. No Prefect: the flows (``flows/doe.py``) run the same batches as
    Prefect tasks.

    Example: `ovtraj run --samples 24 --runner processes --workers 2`
    """
    scenario = loaded_scenario(config, target)
    if scenario.mission is None:
        typer.echo(f"{config}: the scenario has no mission section", err=True)
        raise typer.Exit(code=2)
    settings = scenario.mission.doe
    choice = runner_choice(settings, runner, dask_address, workers)
    from ovtraj.config.orchestration import load_orchestration
    from ovtraj.runs import StoreError, prepare_run, run_doe
    from ovtraj.runs.execute import BatchesFailed
    from ovtraj.runs.runners import ClusterError
    from ovtraj.version import code_version

    fit = launch_fit_or_exit(scenario, target)
    store = run_store(store_root, scenario, config)
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
        orchestration = load_orchestration()
        with progress_bar("DoE samples", enabled=not as_json) as update:
            run_doe(
                scenario,
                stored,
                fit,
                batch_size=stored.batch_size(settings),
                runner=choice.runner,
                workers=choice.workers,
                dask_address=choice.dask_address,
                dask=orchestration.dask,
                time_limit_s=orchestration.flows.doe_s,
                progress=say,
                on_progress=update,
            )
    except (StoreError, ValueError, ClusterError, BatchesFailed) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    summary = stored.summary()
    if as_json:
        print_json(summary | {"stored_in": str(stored.url)})
        return
    print_rows(f"run {stored.id}", keyed_rows(summary))
    typer.echo(f"stored in {stored.url}")


def runner_choice(
    settings: DoeSettings,
    runner: str | None,
    dask_address: str | None,
    workers: int | None = None,
) -> RunnerChoice:
    """The runner chosen (:func:`ovtraj.runs.runners.choose_runner`: the options, else the
    config's ``mission.doe``), its pool of ``workers`` (``--workers``) when given; a bad
    choice is one line naming the option, exit 2.

    ``--workers`` sizes the pool only: a run's batches are cut by the config's
    ``mission.doe.workers`` (:meth:`ovtraj.config.mission.DoeSettings.batch_size_for`), so
    the stored run is the same for any number of workers."""
    from dataclasses import replace

    from ovtraj.runs.runners import choose_runner

    try:
        choice = choose_runner(settings, runner, dask_address, as_options=True)
    except ValueError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    return choice if workers is None else replace(choice, workers=workers)


def launch_fit_or_exit(scenario: Scenario, target: str | None = None) -> Any:
    from ovtraj.launch.launch_fit import find_launch_fit

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
