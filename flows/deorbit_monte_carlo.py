"""Flow: Monte Carlo of the finite-thrust deorbit burn (``flows/deorbit_monte_carlo.py``).

A thin adapter of the library's one Monte Carlo driver
(:func:`ovtraj.store.monte_carlo.drive_monte_carlo` with the study
:class:`ovtraj.studies.deorbit_burn.stored_monte_carlo.DeorbitMonteCarlo`):

1. read the problem (seed 004 case by default) and its Monte Carlo settings;
2. the driver creates (or reopens) the run directory ``<store>/<run_id>/``: the id hashes
   the resolved problem, the number of runs, the strategies, the seed and the code version;
3. it simulates the runs the store does not hold yet, in batches of several runs per task
   (a task costs 0.05-0.5 s of orchestration) on the configured task runner
   (:class:`flows.monte_carlo_tasks.MonteCarloTasks`); each task is cached on its inputs
   and writes its own batch to Parquet;
4. summary statistics per strategy, scatter and histogram plots of the entry errors and the
   published figures into the run directory; a table artifact; the summary is returned.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger
from prefect.artifacts import create_markdown_artifact, create_table_artifact

from flows.common import (
    FLOW_TIMEOUTS,
    embedded_plots,
    label_flow_run,
    prune_expired_results,
    run_name,
    run_tags,
)
from flows.monte_carlo_tasks import MonteCarloTasks, raise_failed_batches
from ovtraj.store.monte_carlo import drive_monte_carlo
from ovtraj.store.paths import store_root as store_root_of
from ovtraj.studies.deorbit_burn.problem import load_deorbit_burn
from ovtraj.studies.deorbit_burn.store import MonteCarloRun
from ovtraj.studies.deorbit_burn.stored_monte_carlo import DeorbitMonteCarlo
from tasks.common import TIMEOUTS, code_version
from tasks.deorbit_monte_carlo import deorbit_mc_batch_task

LIMIT = "flows.deorbit_monte_carlo_s of configs/orchestration.yaml"


@flow(
    name="deorbit-monte-carlo",
    flow_run_name=run_name("deorbit-monte-carlo"),
    timeout_seconds=FLOW_TIMEOUTS.deorbit_monte_carlo_s,
    log_prints=True,
)
def deorbit_monte_carlo_flow(
    config: str = "configs/cases/shuttle_deorbit.yaml",
    runs: int | None = None,
    strategies: list[int] | None = None,
    seed: int | None = None,
    store: str | None = None,
    batch_size: int | None = None,
    workers: int | None = None,
    runner: str | None = None,
    dask_address: str | None = None,
) -> dict[str, Any]:
    """Monte Carlo of the deorbit burn; returns the run's summary (id, statistics, figures).

    The parameters are named as ``ovtraj deorbit-burn CONFIG --monte-carlo RUNS``'s
    options and ``ovtraj run``'s (``store``, ``runner``, ...; tests/test_flows.py).
    Arguments left ``None`` take the config's ``monte_carlo`` values (``store``: its
    ``store``, else the workspace's; ``runner``: its ``task_runner``;
    ``serial | threads | processes | dask``). Raises ``RuntimeError``
    naming the failed batches if a task fails (after its retries); the stored batches
    are kept and a re-run simulates only the missing runs.
    """
    deadline = time.monotonic() + FLOW_TIMEOUTS.deorbit_monte_carlo_s
    prune_expired_results()
    study, tasks = _prepared(
        config,
        runs,
        strategies,
        seed,
        store,
        batch_size,
        workers,
        runner,
        dask_address,
        deadline,
    )
    name = study.problem.name

    def opened(run: MonteCarloRun, todo: int) -> None:
        label_flow_run(
            f"deorbit-monte-carlo {name} {run.id}", run_tags("deorbit-monte-carlo", name, run.id)
        )
        get_run_logger().info(
            "run %s (%s): %d runs, %d to simulate", run.id, name, study.runs, todo
        )

    report = drive_monte_carlo(study, tasks, opened=opened)
    _publish(report)
    raise_failed_batches(report, report.pop("failed_batches"))
    return report


def _prepared(
    config: str,
    runs: int | None,
    strategies: list[int] | None,
    seed: int | None,
    store: str | None,
    batch_size: int | None,
    workers: int | None,
    runner: str | None,
    dask_address: str | None,
    deadline: float,
) -> tuple[DeorbitMonteCarlo, MonteCarloTasks]:
    """The flow's parameters as the driver's study and flier: the problem of ``config``
    and its ``monte_carlo`` values for those left None."""
    problem = load_deorbit_burn(Path(config))
    settings = problem.config.monte_carlo
    tasks = MonteCarloTasks.configured(
        deorbit_mc_batch_task,
        settings,
        TIMEOUTS.deorbit_mc_batch_per_run_s,
        runner=runner,
        workers=workers,
        dask_address=dask_address,
        batch_size=settings.batch_size if batch_size is None else batch_size,
        deadline=deadline,
        limit=LIMIT,
    )
    study = DeorbitMonteCarlo(
        problem,
        runs=settings.runs if runs is None else runs,
        strategies=[int(s) for s in (settings.strategies if strategies is None else strategies)],
        seed=settings.seed if seed is None else int(seed),
        root=store_root_of(settings.store, Path(config).resolve().parent, store),
        code=code_version(),
        batch_size=tasks.batch_size,
    )
    return study, tasks


def _publish(report: dict[str, Any]) -> None:
    """A table artifact of the statistics per strategy and a markdown artifact showing the
    plots."""
    run_id = report["run_id"]
    create_table_artifact(
        key="deorbit-monte-carlo",
        table=[
            {
                "strategy": row["strategy"],
                "runs": row["runs"],
                "failed": row["failed"],
                "along_track_km_max_abs": row["along_track_error_km_max_abs"],
                "along_track_km_std": row["along_track_error_km_std"],
                "fpa_deg_max_abs": row["entry_fpa_error_deg_max_abs"],
                "fpa_deg_std": row["entry_fpa_error_deg_std"],
                "speed_mps_max_abs": row["entry_speed_error_mps_max_abs"],
                "dv_mps_mean": row["dv_mps_mean"],
            }
            for row in report["statistics"]
        ],
        description=(
            f"Deorbit-burn Monte Carlo {run_id} of {report['name']} ({report['runs']} runs)"
        ),
    )
    create_markdown_artifact(
        key="deorbit-monte-carlo-plots",
        markdown="\n\n".join(embedded_plots(report["plots"])) or "no plots",
        description=f"entry errors of the Monte Carlo {run_id} (scatter, histograms)",
    )


if __name__ == "__main__":
    print(deorbit_monte_carlo_flow())
