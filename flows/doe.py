"""Flow: a DoE of the whole mission into the run store (``flows/doe.py:doe_flow``).

1. read the scenario and its DoE settings; make sure the launch fit exists (the
   launch-fit flow runs as a subflow when it does not);
2. create (or reopen) the run: its id hashes the resolved config, seed, sample
   count, parent run and code version;
3. evaluate the batches the store does not hold yet as parallel tasks on the
   configured task runner (threads, processes, or Dask; started only when there
   is something to evaluate), each cached on its inputs and storing its own
   batch (the records never travel back);
4. finish the manifest and publish a table artifact of the run.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger
from prefect.artifacts import acreate_table_artifact
from prefect.task_runners import ProcessPoolTaskRunner, ThreadPoolTaskRunner

from ovtraj.config import Scenario
from ovtraj.config.mission import DoeSettings
from ovtraj.launch.fit import find_launch_fit
from ovtraj.runs import RunStore, prepare_run
from ovtraj.runs.execute import finish
from ovtraj.target_sources import load_scenario_with_target
from ovtraj.version import code_version
from tasks.doe import mission_batch_task


def task_runner(settings: DoeSettings) -> Any:
    """The configured task runner: local threads or processes, or a Dask cluster."""
    if settings.task_runner == "threads":
        return ThreadPoolTaskRunner(max_workers=settings.workers)
    if settings.task_runner == "processes":
        return ProcessPoolTaskRunner(max_workers=settings.workers)
    from prefect_dask import DaskTaskRunner

    if settings.dask_address:
        return DaskTaskRunner(address=settings.dask_address)
    return DaskTaskRunner(
        cluster_kwargs={"n_workers": settings.workers, "processes": False, "threads_per_worker": 1}
    )


def _failed(k: int, failures: list[str]) -> bool:
    return any(f.startswith(f"batch {k}:") for f in failures)


def _run_batches(
    runner: Any,
    batch_task: Any,
    resolved: dict[str, Any],
    run: Any,
    batches: dict[int, Any],
    todo: list[int],
    code: str,
    logger: Any,
) -> list[str]:
    """Submit the batches to the runner, wait for them, log each; returns the failures."""
    futures = {
        k: runner.submit(
            batch_task,
            {
                "resolved_scenario": resolved,
                "run_dir": str(run.directory),
                "batch_index": k,
                "batch": batches[k].to_dict(orient="records"),
                "code": code,
            },
        )
        for k in todo
    }
    failures = []
    for k, future in futures.items():
        try:
            summary = future.result()
        except Exception as err:
            failures.append(f"batch {k}: {type(err).__name__}: {err}")
            logger.error("batch %d failed: %s", k, err)
            continue
        logger.info(
            "batch %d/%d stored: %d samples, %d feasible, %.1f s",
            k + 1,
            len(batches),
            summary["samples"],
            summary["feasible"],
            summary["wall_time_s"],
        )
    return failures


def evaluate_batches(
    runner: Any,
    resolved: dict[str, Any],
    run: Any,
    batch_size: int,
    retries: int,
    code: str,
) -> dict[str, Any]:
    """Submit every batch the run does not hold; each task stores its own batch.

    The runner is the configured one, used as a context manager inside the flow run
    (a subflow with the runner as an option would cost a second flow run per DoE).
    """
    logger = get_run_logger()
    batches = dict(run.batches(batch_size))
    done = run.done_batches()
    todo = [k for k in batches if k not in done]
    with run.working() as removed:
        if removed:
            logger.info("removed %d temporary file(s) of an interrupted write", len(removed))
        run.update_manifest(batches=len(batches))
        logger.info(
            "run %s: %d batches, %d stored, %d to evaluate",
            run.id,
            len(batches),
            len(done),
            len(todo),
        )
        batch_task = mission_batch_task.with_options(retries=retries, retry_delay_seconds=1)
        failures = _run_batches(runner, batch_task, resolved, run, batches, todo, code, logger)
        missing = [k for k in todo if k not in run.done_batches() and not _failed(k, failures)]
        if missing:  # cached results whose files are gone: evaluate them again
            logger.info("batches %s cached but not stored: refreshing", missing)
            refresh = batch_task.with_options(refresh_cache=True)
            failures += _run_batches(runner, refresh, resolved, run, batches, missing, code, logger)
    finish(run)
    if failures:
        run.update_manifest(status="incomplete", failures=failures)
        raise RuntimeError(f"run {run.id}: {len(failures)} batch(es) failed: {'; '.join(failures)}")
    return {"evaluated_batches": len(todo), "stored_batches": len(done)}


@flow(name="doe", log_prints=True)
async def doe_flow(
    config: str = "configs/scenario.yaml",
    samples: int | None = None,
    seed: int | None = None,
    append_to: str | None = None,
    store_root: str | None = None,
    target: str | None = None,
) -> dict[str, Any]:
    """DoE of the mission chain; returns the run's summary (run id, counts, ranges).

    ``target``: a TLE/OMM file or URL that replaces the scenario's target.

    Async although every step blocks: Prefect joins a synchronous flow run's heartbeat
    thread at exit, and that thread sleeps in 1 s steps (0.5-1 s per run measured here,
    about 4 points of overhead on a 64-sample DoE); an async flow run's is not joined.
    The steps run in a worker thread (the flow run's context goes with them). From
    synchronous code call :func:`run_doe_flow`.
    """
    summary = await asyncio.to_thread(_doe, config, samples, seed, append_to, store_root, target)
    await acreate_table_artifact(
        key="doe-run",
        table=[dict(summary)],
        description=f"DoE run {summary['run_id']} of {summary['scenario']}",
    )
    return summary


def run_doe_flow(**parameters: Any) -> dict[str, Any]:
    """Run :func:`doe_flow` to completion from synchronous code (scripts, tests)."""
    return asyncio.run(doe_flow(**parameters))


def ensure_launch_fit(config: str, scenario: Scenario, target: str | None = None) -> None:
    """Run the launch-fit flow when no stored fit matches the scenario."""
    if find_launch_fit(scenario) is None:
        from flows.launch_fit import launch_fit_flow

        get_run_logger().info("no launch fit for this scenario yet: running the launch-fit flow")
        launch_fit_flow(config, target=target)


def evaluate_run(runner: Any, scenario: Scenario, run: Any, code: str) -> Any:
    """Evaluate the run's pending batches on the runner (nothing to do: just finish)."""
    settings = scenario.mission.doe
    if run.pending_batches(settings.batch_size):
        evaluate_batches(
            runner, scenario.resolved(), run, settings.batch_size, settings.task_retries, code
        )
    else:
        finish(run)
    return run


def _doe(
    config: str,
    samples: int | None,
    seed: int | None,
    append_to: str | None,
    store_root: str | None,
    target: str | None,
) -> dict[str, Any]:
    logger = get_run_logger()
    scenario: Scenario = load_scenario_with_target(Path(config), target)
    if scenario.mission is None:
        raise ValueError(f"{config}: the scenario has no mission section")
    settings = scenario.mission.doe
    ensure_launch_fit(config, scenario, target)
    store = RunStore.for_scenario(scenario, config, store_root)
    parent = store.run(append_to) if append_to else None
    code = code_version()
    run = prepare_run(
        scenario,
        samples=samples or settings.samples,
        seed=settings.seed if seed is None else seed,
        code=code,
        store=store,
        parent=parent,
    )
    logger.info("run %s (%s), %d samples", run.id, scenario.name, len(run.samples()))
    if run.pending_batches(settings.batch_size):
        with task_runner(settings) as runner:
            evaluate_run(runner, scenario, run, code)
    else:
        finish(run)
    return run.summary()


if __name__ == "__main__":
    print(run_doe_flow())
