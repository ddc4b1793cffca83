"""The ``run`` command (a DoE of the whole mission into the run store) and what the
``pipeline`` and ``window`` commands share with it: the runner and sample options, and
the launch fit a run needs (:func:`launch_fit_or_exit`, solved here by
:func:`solve_here` when configs/orchestration.yaml says so)."""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Annotated

import typer

from ovtraj.cli.common import (
    ConfigArg,
    JsonOpt,
    StoreOpt,
    TargetOpt,
    app,
    exits_on,
    keyed_rows,
    option_limits,
    print_json,
    print_rows,
    run_store,
)
from ovtraj.cli.progress import echo, progress_bar
from ovtraj.config import Scenario
from ovtraj.config.mission import DoeSettings
from ovtraj.config.orchestration import load_orchestration
from ovtraj.store.files import StoreError
from ovtraj.version import code_version

if TYPE_CHECKING:  # the run store and the launch fit load the numerics: imported when run
    from ovtraj.launch.launch_fit import LaunchFit
    from ovtraj.runs import Run, RunStore
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
    from ovtraj.runs.preparation import mission_scenario, runner_choice

    with exits_on(ValueError):
        scenario = mission_scenario(config, target)
        choice = runner_choice(scenario.mission.doe, runner, dask_address, workers, as_options=True)
    fit = launch_fit_or_exit(scenario, target, as_json)
    store = run_store(store_root, scenario, config)
    stored = _evaluated_run(scenario, fit, store, choice, samples, seed, append, as_json)
    summary = stored.summary()
    if as_json:
        print_json(summary | {"stored_in": str(stored.url)})
        return
    print_rows(f"run {stored.id}", keyed_rows(summary))
    typer.echo(f"stored in {stored.url}")


def _evaluated_run(
    scenario: Scenario,
    fit: LaunchFit,
    store: RunStore,
    choice: RunnerChoice,
    samples: int | None,
    seed: int | None,
    append: str | None,
    as_json: bool,
) -> Run:
    """The DoE run of the options (``--append``: a child of that run), its batches
    evaluated on the library's pool of ``choice`` (a line per batch on stdout, on stderr
    with --json); a fault is one line on stderr, exit 2."""
    from ovtraj.runs import prepare_run, run_doe
    from ovtraj.runs.execute import BatchesFailed
    from ovtraj.runs.runners import ClusterError

    settings = scenario.mission.doe
    with exits_on(StoreError, ValueError, ClusterError, BatchesFailed):
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
    return stored


def solve_here(scenario: Scenario, *, as_json: bool = False) -> None:
    """A missing launch fit solved in this process, as ``ovtraj launch-fit`` solves it
    (configs/orchestration.yaml ``preparation.launch_fit: fit``; a progress bar on
    stderr), stored where the run finds it."""
    from ovtraj.runs.preparation import solve_launch_fit

    with progress_bar("launch fit", enabled=not as_json) as update:
        solve_launch_fit(scenario, on_progress=update)


def launch_fit_or_exit(
    scenario: Scenario, target: str | None = None, as_json: bool = False
) -> LaunchFit:
    """The launch fit a run of ``scenario`` needs (``--target``: ``target``), solved here
    first or refused in one line, exit 2, as configs/orchestration.yaml
    ``preparation.launch_fit`` says (:func:`ovtraj.runs.preparation.required_launch_fit`)."""
    from ovtraj.runs.preparation import required_launch_fit

    with exits_on(ValueError):
        fit = required_launch_fit(scenario, partial(solve_here, as_json=as_json), target=target)
    return fit
