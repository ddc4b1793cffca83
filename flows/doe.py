"""Flow: a DoE of the whole mission into the run store (``flows/doe.py:doe_flow``).

1. read the scenario and its DoE settings; make sure the launch fit exists (when it does
   not, the launch-fit flow runs as a subflow, or the flow run fails naming it, as
   configs/orchestration.yaml ``preparation.launch_fit`` says);
2. create (or reopen) the run: its id hashes the resolved config, seed, sample
   count, parent run and code version; the flow run is renamed ``doe <scenario>
   <run id>`` and tagged ``scenario:<name>``, ``run:<id>`` (its task runs too);
3. take the run's concurrency slot (one flow run evaluates a run at a time), then
   evaluate the batches the store does not hold yet as tasks on the runner
   (``serial | threads | processes | dask``: the ``runner`` parameter, else
   ``mission.doe.task_runner``); each task carries the run's absolute URL and the
   launch fit's coefficients and stores its own batch (the records never travel back);
4. finish the manifest: ``complete``; ``incomplete`` (batches failed or missing: the
   flow fails, naming them); ``failed`` (the cluster, a timeout: the flow fails with
   the cause); never left ``running``. A table artifact of the run.
"""

from __future__ import annotations

import asyncio
import time
from contextlib import ExitStack
from typing import Any

from prefect import flow, get_run_logger
from prefect.artifacts import acreate_table_artifact

from flows.common import (
    FLOW_TIMEOUTS,
    label_flow_run,
    prepared,
    prune_expired_results,
    run_batches,
    run_name,
    run_slot,
    run_tags,
    run_to_completion,
)
from flows.launch_fit import launch_fit_subflow
from flows.runners import task_runner
from ovtraj.config import Scenario
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.paths import scenario_file
from ovtraj.runs import RunStore, prepare_run
from ovtraj.runs.execute import finish
from ovtraj.runs.preparation import required_launch_fit
from ovtraj.runs.runners import RunnerChoice, choose_runner
from ovtraj.runs.store import Run
from ovtraj.target_sources import load_scenario_with_target
from tasks.common import TIMEOUTS, code_version
from tasks.doe import mission_batch_task


class RunIncomplete(RuntimeError):
    """Batches failed or are missing at the end: the manifest says ``incomplete``."""


def fail_run(run: Run, err: BaseException) -> None:
    """End the run's manifest after ``err`` stopped its evaluation: ``complete`` if every
    batch is stored after all, else ``failed`` with the cause (``running`` only while
    another process still works on it)."""
    try:
        finish(run)
        if run.manifest.get("status") == "incomplete":
            run.update_manifest(status="failed", failure=f"{type(err).__name__}: {err}"[:1000])
    except Exception as store_err:  # the cause is reported; never hide it behind this
        get_run_logger().error("run %s: manifest not updated: %s", run.id, store_err)


def _describe(batches: int) -> Any:
    def describe(k: int, summary: dict[str, Any]) -> str:
        return (
            f"batch {k + 1}/{batches} stored: {summary['samples']} samples, "
            f"{summary['feasible']} feasible, {summary['wall_time_s']:.1f} s"
            + ("" if summary["stored_here"] else " (already stored)")
        )

    return describe


def evaluate_batches(
    runner: Any, scenario: Scenario, run: Run, fit: LaunchFit, deadline: float, limit: str
) -> dict[str, Any]:
    """Submit every batch the run does not hold; each task stores its own batch.

    The runner is started by the caller, inside the flow run (a subflow with the runner
    as an option would cost a second flow run per DoE). Raises :class:`RunIncomplete`
    naming the batches when some are not stored at the end (the manifest says
    ``incomplete``).
    """
    logger = get_run_logger()
    settings = scenario.mission.doe
    batch_size = run.batch_size(settings)
    batches = dict(run.batches(batch_size))
    done = run.done_batches()
    todo = [k for k in batches if k not in done]
    resolved, coefficients = scenario.resolved(), fit.to_dict()
    batch_task = prepared(
        mission_batch_task,
        timeout_s=TIMEOUTS.mission_batch_per_sample_s * batch_size,
        retries=settings.task_retries,
    )
    parameters = {
        k: {
            "resolved_scenario": resolved,
            "run_url": run.url,
            "batch_index": k,
            "batch": batches[k].to_dict(orient="records"),
            "launch_fit": coefficients,
        }
        for k in todo
    }
    with run.working() as removed:
        if removed:
            logger.info("removed %d temporary file(s) of an interrupted write", len(removed))
        run.update_manifest(batches=len(batches), batch_size=batch_size)
        logger.info(
            "run %s: %d batches, %d stored, %d to evaluate",
            run.id,
            len(batches),
            len(done),
            len(todo),
        )
        failures, summaries = run_batches(
            runner,
            batch_task,
            parameters,
            run.is_stored,
            deadline=deadline,
            limit=limit,
            describe=_describe(len(batches)),
        )
    finish(run)
    missing = sorted(k for k in batches if not run.is_stored(k))
    if missing:
        texts = [f"batch {k}: {failures.get(k, 'not stored')}" for k in missing]
        run.update_manifest(status="incomplete", failures=texts)
        raise RunIncomplete(
            f"run {run.id} incomplete: {len(missing)} of {len(batches)} batch(es) not "
            f"stored: {'; '.join(texts)}"
        )
    return {
        "evaluated_batches": len(todo),
        "task_time_s": sum(summary["wall_time_s"] for summary in summaries.values()),
    }


def evaluate_run(
    scenario: Scenario,
    run: Run,
    fit: LaunchFit,
    *,
    deadline: float,
    limit: str,
    runner: Any = None,
    choice: RunnerChoice | None = None,
    stats: dict[str, Any] | None = None,
) -> Run:
    """Evaluate the run's pending batches under its concurrency slot; finish it.

    ``runner``: a started task runner (the pipeline's), else one of ``choice`` is started
    here, only when there is something to evaluate. Any failure ends the manifest
    (:func:`fail_run`) and is raised. ``stats`` receives what :func:`evaluate_batches`
    reports (batches evaluated here, their tasks' summed time).
    """
    stats = {} if stats is None else stats
    stats.update(evaluated_batches=0, task_time_s=0.0)
    batch_size = run.batch_size(scenario.mission.doe)
    if not run.pending_batches(batch_size):
        return finish(run)
    try:
        with run_slot(run.id):
            if not run.pending_batches(batch_size):  # another flow run evaluated it meanwhile
                return finish(run)
            if runner is not None:
                stats.update(evaluate_batches(runner, scenario, run, fit, deadline, limit))
            else:
                with task_runner(choice.runner, choice.workers, choice.dask_address) as started:
                    stats.update(evaluate_batches(started, scenario, run, fit, deadline, limit))
    except RunIncomplete:
        raise
    except Exception as err:  # an interrupt leaves the store's own `interrupted`
        fail_run(run, err)
        raise
    return run


class TaskBatches:
    """The pipeline driver's :class:`ovtraj.pipeline.drive.BatchExecutor` on Prefect: each
    batch a cached task (:func:`evaluate_run`) on the task runner of ``choice``, started
    once for the DoE and every infill run. The flow run is named and tagged
    ``<kind> <scenario> <run id>`` after the first run it evaluates (the DoE run)."""

    def __init__(
        self,
        scenario: Scenario,
        fit: LaunchFit,
        choice: RunnerChoice,
        *,
        deadline: float,
        limit: str,
        kind: str,
    ) -> None:
        self.scenario, self.fit, self.choice = scenario, fit, choice
        self.deadline, self.limit, self.kind = deadline, limit, kind
        self._stack = ExitStack()
        self._runner: Any = None
        self._labelled = False

    def __enter__(self) -> TaskBatches:
        choice = self.choice
        self._runner = self._stack.enter_context(
            task_runner(choice.runner, choice.workers, choice.dask_address)
        )
        return self

    def __exit__(self, *exc: object) -> None:
        self._runner = None
        self._stack.close()

    def evaluate(self, run: Run) -> Run:
        if not self._labelled:
            self._labelled = True
            name = self.scenario.name
            label_flow_run(f"{self.kind} {name} {run.id}", run_tags(self.kind, name, run.id))
        return evaluate_run(
            self.scenario,
            run,
            self.fit,
            deadline=self.deadline,
            limit=self.limit,
            runner=self._runner,
        )

    def side_pool(self) -> None:
        """None: the task runner's workers run batches only (their results travel as
        records; the fits and plots run in the flow's process)."""
        return None


LIMIT = "flows.doe_s of configs/orchestration.yaml"


@flow(name="doe", flow_run_name=run_name("doe"), log_prints=True)
async def doe_flow(
    config: str | None = None,
    samples: int | None = None,
    seed: int | None = None,
    append: str | None = None,
    store: str | None = None,
    target: str | None = None,
    runner: str | None = None,
    dask_address: str | None = None,
) -> dict[str, Any]:
    """DoE of the mission chain; returns the run's summary (run id, counts, ranges).

    The parameters are ``ovtraj run``'s options by the same names (tests/test_flows.py).
    ``config``: the scenario file (default: the shipped one). ``append``: a stored run
    this one extends with new samples. ``store``: the run store (else
    ``mission.doe.store``, else the workspace's). ``target``: a TLE/OMM file or URL that
    replaces the scenario's target. ``runner``
    (``serial | threads | processes | dask``) overrides ``mission.doe.task_runner``;
    ``dask_address``: the scheduler of the ``dask`` runner (else ``OVTRAJ_DASK_ADDRESS``,
    else a local cluster).

    The flow's wall-time limit is ``flows.doe_s`` of ``configs/orchestration.yaml``,
    enforced inside (the batches not started are cancelled and the manifest ends
    ``failed``) rather than by Prefect, which would leave the work thread running.

    Async although every step blocks: Prefect joins a synchronous flow run's heartbeat
    thread at exit, and that thread sleeps in 1 s steps (0.5-1 s per run measured here,
    about 4 points of overhead on a 64-sample DoE); an async flow run's is not joined.
    The steps run in a worker thread (the flow run's context goes with them). From
    synchronous code call :func:`run_doe_flow`.
    """
    deadline = time.monotonic() + FLOW_TIMEOUTS.doe_s
    summary = await asyncio.to_thread(
        _doe, config, samples, seed, append, store, target, runner, dask_address, deadline
    )
    await acreate_table_artifact(
        key="doe-run",
        table=[dict(summary)],
        description=f"DoE run {summary['run_id']} of {summary['scenario']}",
    )
    return summary


def run_doe_flow(**parameters: Any) -> dict[str, Any]:
    """Run :func:`doe_flow` to completion from synchronous code (scripts, tests), also
    inside a running event loop (a notebook): then in a thread of its own."""
    return run_to_completion(lambda: doe_flow(**parameters))


def _doe(
    config: str | None,
    samples: int | None,
    seed: int | None,
    append: str | None,
    store: str | None,
    target: str | None,
    runner: str | None,
    dask_address: str | None,
    deadline: float,
) -> dict[str, Any]:
    logger = get_run_logger()
    pruned = prune_expired_results()
    if pruned:
        logger.info("removed %d expired task result(s)", pruned)
    path = scenario_file(config)
    scenario: Scenario = load_scenario_with_target(path, target)
    if scenario.mission is None:
        raise ValueError(f"{path}: the scenario has no mission section")
    settings = scenario.mission.doe
    choice = choose_runner(settings, runner, dask_address)
    fit = required_launch_fit(scenario, launch_fit_subflow(config, target), target=target)
    run_store = RunStore.for_scenario(scenario, config, store)
    parent = run_store.run(append) if append else None
    run = prepare_run(
        scenario,
        samples=samples or settings.samples,
        seed=settings.seed if seed is None else seed,
        code=code_version(),
        store=run_store,
        parent=parent,
    )
    labels = run_tags("doe", scenario.name, run.id)
    label_flow_run(f"doe {scenario.name} {run.id}", labels)
    logger.info(
        "run %s (%s), %d samples, runner %s%s, store %s",
        run.id,
        scenario.name,
        len(run.samples()),
        choice.runner,
        f" at {choice.dask_address}" if choice.dask_address else "",
        run.url,
    )
    # The flow run carries the tags, the batches' task runs none (tasks.common.BATCH_TAGS).
    stats: dict[str, Any] = {}
    evaluate_run(scenario, run, fit, deadline=deadline, limit=LIMIT, choice=choice, stats=stats)
    return run.summary() | stats


if __name__ == "__main__":
    print(run_doe_flow())
