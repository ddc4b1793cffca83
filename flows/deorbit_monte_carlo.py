"""Flow: Monte Carlo of the finite-thrust deorbit burn (``flows/deorbit_monte_carlo.py``).

1. read the problem (seed 004 case by default) and its Monte Carlo settings;
2. create (or reopen) the run directory ``<store>/<run_id>/``: the id hashes the resolved
   problem, the number of runs, the strategies, the seed and the code version;
3. simulate the runs the store does not hold yet, in batches of several runs per task (a
   task costs 0.05-0.5 s of orchestration) on the configured task runner (threads or
   processes, used as a context manager inside this flow run); each task is cached on its
   inputs and writes its own batch to Parquet;
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
    store_missing_batches,
)
from flows.runners import check_runner
from ovtraj.store.paths import store_root as store_root_of
from ovtraj.store.records import plain
from ovtraj.studies.deorbit_burn.montecarlo import monte_carlo_summary
from ovtraj.studies.deorbit_burn.plots import plot_dispersions
from ovtraj.studies.deorbit_burn.problem import load_deorbit_burn
from ovtraj.studies.deorbit_burn.published import published_comparison
from ovtraj.studies.deorbit_burn.store import MonteCarloRun
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
    logger = get_run_logger()
    prune_expired_results()
    problem = load_deorbit_burn(Path(config))
    settings = problem.config.monte_carlo
    chosen_runner = runner or settings.task_runner
    check_runner(chosen_runner, dask_address)
    n = settings.runs if runs is None else runs
    chosen = [int(s) for s in (settings.strategies if strategies is None else strategies)]
    seed = settings.seed if seed is None else int(seed)
    size = settings.batch_size if batch_size is None else batch_size
    if n < 1 or size < 1:
        raise ValueError(f"runs and batch_size must be >= 1; got runs {n}, batch_size {size}")
    resolved = problem.resolved()
    run = MonteCarloRun.create(
        store_root_of(settings.store, Path(config).resolve().parent, store),
        resolved=resolved,
        runs=n,
        strategies=chosen,
        seed=seed,
        code=code_version(),
    )
    labels = run_tags("deorbit-monte-carlo", problem.name, run.id)
    label_flow_run(f"deorbit-monte-carlo {problem.name} {run.id}", labels)
    todo = sorted(set(range(n)) - run.done_runs())
    logger.info("run %s (%s): %d runs, %d to simulate", run.id, problem.name, n, len(todo))
    url = str(run.directory.resolve())
    failures = store_missing_batches(
        run,
        todo,
        size,
        deorbit_mc_batch_task,
        lambda group: {
            "resolved_problem": resolved,
            "run_url": url,
            "strategies": chosen,
            "seed": seed,
        },
        runner=chosen_runner,
        workers=workers or settings.workers,
        dask_address=dask_address,
        retries=settings.task_retries,
        timeout_per_run_s=TIMEOUTS.deorbit_mc_batch_per_run_s,
        deadline=deadline,
        limit=LIMIT,
    )
    frame = run.results()
    summary = monte_carlo_summary(frame)
    plots = plot_dispersions(frame, run.directory / "plots", problem.entry.radius_m)
    comparison = [
        row.as_dict()
        for row in published_comparison(problem, summary=summary)
        if row.figure.startswith("strategy")
    ]
    report = {
        "run_id": run.id,
        "directory": str(run.directory),
        "name": problem.name,
        "runs": n,
        "stored_runs": len(run.done_runs()),
        "strategies": chosen,
        "seed": seed,
        "simulated_runs": len(todo),
        "status": "incomplete" if failures else "complete",
        "statistics": [plain(row) for row in summary.to_dict(orient="records")],
        "published": comparison,
        "plots": [str(p) for p in plots],
    }
    run.write_summary(report)
    run.update_info(
        status=report["status"], failures=[f"runs from {k}: {why}" for k, why in failures.items()]
    )
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
        description=f"Deorbit-burn Monte Carlo {run.id} of {problem.name} ({n} runs)",
    )
    create_markdown_artifact(
        key="deorbit-monte-carlo-plots",
        markdown="\n\n".join(embedded_plots(plots)) or "no plots",
        description=f"entry errors of the Monte Carlo {run.id} (scatter, histograms)",
    )
    if failures:
        text = "; ".join(f"runs from {k}: {why}" for k, why in failures.items())
        raise RuntimeError(f"run {run.id}: {len(failures)} batch(es) failed: {text}")
    return report


if __name__ == "__main__":
    print(deorbit_monte_carlo_flow())
