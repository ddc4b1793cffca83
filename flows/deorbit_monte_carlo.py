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

from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger
from prefect.artifacts import create_table_artifact
from prefect.task_runners import ProcessPoolTaskRunner, ThreadPoolTaskRunner

from ovtraj.config.deorbit_burn import MonteCarloConfig
from ovtraj.deorbit.burn.montecarlo import monte_carlo_summary
from ovtraj.deorbit.burn.plots import plot_dispersions
from ovtraj.deorbit.burn.problem import load_deorbit_burn
from ovtraj.deorbit.burn.published import published_comparison
from ovtraj.deorbit.burn.store import MonteCarloRun
from ovtraj.paths import store_root as store_root_of
from ovtraj.records import plain
from ovtraj.version import code_version
from tasks.deorbit_monte_carlo import deorbit_mc_batch_task


def task_runner(settings: MonteCarloConfig, workers: int | None = None) -> Any:
    """The configured task runner: local threads or processes."""
    count = workers or settings.workers
    if settings.task_runner == "threads":
        return ThreadPoolTaskRunner(max_workers=count)
    return ProcessPoolTaskRunner(max_workers=count)


def _batches(todo: list[int], size: int) -> list[list[int]]:
    """Consecutive runs still to simulate, grouped ``size`` at a time."""
    groups: list[list[int]] = []
    for run in todo:
        if groups and len(groups[-1]) < size and groups[-1][-1] == run - 1:
            groups[-1].append(run)
        else:
            groups.append([run])
    return groups


def _submit(
    runner: Any,
    batch_task: Any,
    batches: list[list[int]],
    common: dict[str, Any],
    logger: Any,
) -> dict[int, str]:
    """Submit the batches, wait for them, log each; returns {first run: error} of failures."""
    futures = [
        (runs, runner.submit(batch_task, {**common, "batch": runs[0], "runs": runs}))
        for runs in batches
    ]
    failures = {}
    for runs, future in futures:
        try:
            summary = future.result()
        except Exception as err:
            failures[runs[0]] = f"runs {runs[0]}-{runs[-1]}: {type(err).__name__}: {err}"
            logger.error("runs %d-%d failed: %s", runs[0], runs[-1], err)
            continue
        logger.info(
            "runs %d-%d stored: %d rows, %d failed, %.1f s",
            runs[0],
            runs[-1],
            summary["rows"],
            summary["failed"],
            summary["wall_time_s"],
        )
    return failures


@flow(name="deorbit-monte-carlo", log_prints=True)
def deorbit_monte_carlo_flow(
    config: str = "configs/cases/shuttle_deorbit.yaml",
    runs: int | None = None,
    strategies: list[int] | None = None,
    seed: int | None = None,
    store_root: str | None = None,
    batch_size: int | None = None,
    workers: int | None = None,
) -> dict[str, Any]:
    """Monte Carlo of the deorbit burn; returns the run's summary (id, statistics, figures).

    Arguments left ``None`` take the config's ``monte_carlo`` values. Raises
    ``RuntimeError`` naming the failed batches if a task fails (after its retries); the
    stored batches are kept and a re-run simulates only the missing runs.
    """
    logger = get_run_logger()
    problem = load_deorbit_burn(Path(config))
    settings = problem.config.monte_carlo
    n = runs or settings.runs
    chosen = [int(s) for s in (strategies or settings.strategies)]
    seed = settings.seed if seed is None else int(seed)
    size = batch_size or settings.batch_size
    resolved = problem.resolved()
    code = code_version()
    run = MonteCarloRun.create(
        store_root_of(settings.store, Path(config).resolve().parent, store_root),
        resolved=resolved,
        runs=n,
        strategies=chosen,
        seed=seed,
        code=code,
    )
    todo = sorted(set(range(n)) - run.done_runs())
    logger.info("run %s (%s): %d runs, %d to simulate", run.id, problem.name, n, len(todo))
    failures: dict[int, str] = {}
    if todo:
        run.update_info(status="running")
        common = {
            "resolved_problem": resolved,
            "run_dir": str(run.directory),
            "strategies": chosen,
            "seed": seed,
            "code": code,
        }
        batch_task = deorbit_mc_batch_task.with_options(
            retries=settings.task_retries, retry_delay_seconds=1
        )
        batches = _batches(todo, size)
        with task_runner(settings, workers) as runner:
            failures = _submit(runner, batch_task, batches, common, logger)
            failed_runs = {r for runs in batches if runs[0] in failures for r in runs}
            missing = sorted(set(range(n)) - run.done_runs() - failed_runs)
            if missing:  # cached task results whose files are gone: simulate them again
                logger.info("runs %s cached but not stored: refreshing", missing)
                refresh = batch_task.with_options(refresh_cache=True)
                failures |= _submit(runner, refresh, _batches(missing, size), common, logger)
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
    run.update_info(status=report["status"], failures=list(failures.values()))
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
    if failures:
        text = "; ".join(failures.values())
        raise RuntimeError(f"run {run.id}: {len(failures)} batch(es) failed: {text}")
    return report


if __name__ == "__main__":
    print(deorbit_monte_carlo_flow())
