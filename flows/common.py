"""What the flows share: task results, names and tags, the run slot, batches under a
deadline, and running a flow from code that already has an event loop.

Figures come from ``configs/orchestration.yaml`` (``tasks.common.ORCHESTRATION``).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextvars
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from prefect import get_run_logger

from flows.runners import ClusterError, count_workers, task_runner
from ovtraj.plots.embed import png_data_uri
from ovtraj.store.batched import consecutive_batches
from ovtraj.store.result_records import is_result_record
from ovtraj.units import S_PER_HOUR
from tasks.common import ORCHESTRATION
from tasks.results import checked_storage

FLOW_TIMEOUTS = ORCHESTRATION.flows


# -- task results -------------------------------------------------------------------------
def result_storage() -> Any:
    """Where task results go: a local folder or an fsspec URL's file system
    (``configs/orchestration.yaml`` ``results.storage``; ``OVTRAJ_PREFECT_RESULTS``),
    through a storage that reads only this project's plain JSON records
    (``tasks/results.py``)."""
    location = ORCHESTRATION.results.location()
    return _saved_storage("remote" if "://" in location else "local", location)


_SAVED_BLOCKS: dict[tuple[str, str], Any] = {}


def _saved_storage(kind: str, location: str) -> Any:
    """A checked ``kind`` storage block at ``location`` (``tasks/results.py``), saved on
    the Prefect server once per process and API (Prefect takes a result storage block only
    when it is saved); its name is a hash of the location, so every flow run on that
    server shares it."""
    import hashlib

    from prefect.settings import PREFECT_API_URL

    key = (location, str(PREFECT_API_URL.value()))
    block = _SAVED_BLOCKS.get(key)
    if block is None:
        block = checked_storage(kind, location)
        name = f"ovtraj-results-{hashlib.sha256(location.encode()).hexdigest()[:12]}"
        block.save(name, overwrite=True, _sync=True)  # also when called in an event loop
        _SAVED_BLOCKS[key] = block
    return block


def prune_expired_results() -> int:
    """Delete the local result records older than ``results.expiration_h`` (Prefect no
    longer serves them); returns how many. Only result records count (regular files, no
    link followed, whose JSON is a record's envelope:
    :func:`ovtraj.store.result_records.is_result_record`); an object-store location is left to
    its own rules."""
    location = ORCHESTRATION.results.location()
    folder = Path(location)
    if "://" in location or not folder.is_dir():
        return 0
    cutoff = time.time() - ORCHESTRATION.results.expiration_h * S_PER_HOUR
    removed = 0
    for path in folder.iterdir():
        try:
            if os.lstat(path).st_mtime < cutoff and is_result_record(path):
                path.unlink()  # a regular file: never a link's target
                removed += 1
        except OSError:
            continue  # another flow removed it
    return removed


def embedded_plots(paths: Iterable[str | Path]) -> list[str]:
    """Markdown paragraphs that show each PNG itself, its path under it as the caption.

    The image is embedded as a ``data:`` URI (``![name](data:image/png;base64,...)``), so
    any Prefect UI shows it, one on another machine too; both UIs of Prefect 3.9 (``/``
    and ``/v2``) render it (tests/test_prefect_ui.py, in chromium). Base64 makes the
    markdown a third larger than the PNGs (~1 MB for a mission plan's five plots); the
    server stores artifacts of tens of MB.
    """
    return [f"![{str(p).rsplit('/', 1)[-1]}]({png_data_uri(p)})\n\n`{p}`" for p in paths]


def prepared(task: Any, *, timeout_s: float | None = None, **options: Any) -> Any:
    """``task`` with the configured result storage (and a timeout or other options)."""
    if timeout_s is not None:
        options["timeout_seconds"] = timeout_s
    return task.with_options(result_storage=result_storage(), **options)


# -- names and tags -------------------------------------------------------------------------
def config_label(config: str | None) -> str:
    """A config parameter as a short label (the file's stem)."""
    return Path(str(config)).stem if config else "default"


def flow_parameter(name: str) -> Any:
    from prefect.runtime import flow_run

    return flow_run.parameters.get(name)


def run_name(kind: str, parameter: str = "config") -> Callable[[], str]:
    """A ``flow_run_name`` callable: ``<kind> <the parameter>`` (a config as its file's
    stem), the name a flow run has until it is renamed once its run is known."""

    def name() -> str:
        value = flow_parameter(parameter)
        return f"{kind} {config_label(value) if parameter == 'config' else value}"

    return name


def label_flow_run(name: str, tags: list[str]) -> None:
    """Rename the running flow run and add tags, once the scenario and run are known."""
    from prefect.client.orchestration import get_client
    from prefect.runtime import flow_run

    flow_run_id = flow_run.id
    if not flow_run_id:
        return
    with get_client(sync_client=True) as client:
        current = client.read_flow_run(flow_run_id)
        client.update_flow_run(flow_run_id, name=name, tags=sorted({*current.tags, *tags}))


def run_tags(kind: str, scenario: str | None, run_id: str | None = None) -> list[str]:
    """``ovtraj``, the flow's kind, ``scenario:<name>`` and ``run:<id>``."""
    tags = ["ovtraj", kind]
    if scenario:
        tags.append(f"scenario:{scenario}")
    if run_id:
        tags.append(f"run:{run_id}")
    return tags


# -- one flow run per run id --------------------------------------------------------------
@contextmanager
def run_slot(run_id: str) -> Iterator[None]:
    """Hold the run's global concurrency slot (limit 1, created when missing): a second
    flow run evaluating the same run waits here (``concurrency.run_slot_wait_s``)."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.actions import GlobalConcurrencyLimitCreate
    from prefect.concurrency.sync import concurrency
    from prefect.exceptions import ObjectAlreadyExists, ObjectNotFound

    name = f"ovtraj-run-{run_id}"
    with get_client(sync_client=True) as client:
        try:
            client.read_global_concurrency_limit_by_name(name)
        except ObjectNotFound:
            try:
                limit = GlobalConcurrencyLimitCreate(name=name, limit=1)
                client.create_global_concurrency_limit(limit)
            except ObjectAlreadyExists:
                pass  # another flow run created it meanwhile
    settings = ORCHESTRATION.concurrency
    with concurrency(
        name,
        occupy=1,
        timeout_seconds=settings.run_slot_wait_s,
        lease_duration=settings.lease_s,
        strict=True,
    ):
        yield


# -- batches that store their own results ----------------------------------------------------
class FlowDeadline(TimeoutError):
    """The flow's wall-time limit passed with batches still running."""


def _dask_client(runner: Any) -> Any:
    return runner.client if type(runner).__name__ == "DaskTaskRunner" else None


def describe_stored_batch(k: int, summary: dict[str, Any]) -> str:
    """A log line for a Monte Carlo batch task's summary (its first run ``k``)."""
    return (
        f"runs {k}-{k + summary['runs'] - 1} stored: {summary['rows']} rows, "
        f"{summary['failed']} failed, {summary['wall_time_s']:.1f} s"
    )


def store_missing_batches(
    run: Any,
    todo: list[int],
    size: int,
    task: Any,
    parameters: Callable[[list[int]], dict[str, Any]],
    *,
    runner: str,
    workers: int,
    dask_address: str | None,
    retries: int,
    timeout_per_run_s: float,
    deadline: float,
    limit: str,
    describe: Callable[[int, dict[str, Any]], str] = describe_stored_batch,
) -> dict[int, str]:
    """Run ``task`` on the runs of ``todo`` a batch at a time (``parameters(runs)`` plus the
    batch's first run and its runs), each task storing its own batch in ``run`` (a
    :class:`ovtraj.store.batched.BatchedRun`); the failed batches by first run. A fault of
    the runner marks the run ``failed`` in its ``run.json`` and is raised."""
    if not todo:
        return {}
    run.update_info(status="running")
    batch_task = prepared(task, timeout_s=timeout_per_run_s * size, retries=retries)
    groups = {runs[0]: runs for runs in consecutive_batches(todo, size)}
    arguments = {
        first: {**parameters(group), "batch": first, "runs": group}
        for first, group in groups.items()
    }

    def stored(first: int) -> bool:
        return set(groups[first]) <= run.done_runs()

    try:
        with task_runner(runner, workers, dask_address) as started:
            failures, _ = run_batches(
                started,
                batch_task,
                arguments,
                stored,
                deadline=deadline,
                limit=limit,
                describe=describe,
            )
    except Exception as err:
        run.update_info(status="failed", failures=[f"{type(err).__name__}: {err}"[:1000]])
        raise
    return failures


def run_batches(
    runner: Any,
    task: Any,
    parameters: dict[int, dict[str, Any]],
    stored: Callable[[int], bool],
    *,
    deadline: float,
    limit: str,
    describe: Callable[[int, dict[str, Any]], str],
) -> tuple[dict[int, str], dict[int, dict[str, Any]]]:
    """Submit one task per batch and wait for them as they end; returns ({batch: error},
    {batch: the task's summary}).

    Each task stores its own batch. A task served from the cache whose batch is not in
    the store (deleted since) runs again at once with a refreshed cache, so the store,
    not the cache, decides: a missing batch is computed once, a stored one never.

    ``deadline`` (``time.monotonic()``) is the flow's limit (``limit`` names it): past it
    the batches not started are cancelled and :class:`FlowDeadline` is raised. On a Dask
    cluster left with no worker for ``dask.no_worker_timeout_s``, :class:`ClusterError`.
    """
    client = _dask_client(runner)
    no_worker = ORCHESTRATION.dask.no_worker_timeout_s
    tasks = _BatchTasks(runner, task, parameters, stored, describe)
    for k in parameters:
        tasks.submit(k)
    workers_gone_since: float | None = None
    while tasks.pending:
        now = time.monotonic()
        if now >= deadline:
            tasks.cancel()
            raise FlowDeadline(
                f"{len(tasks.pending)} batch(es) still running when the flow's limit passed "
                f"({limit}); the stored batches are kept, a new flow run resumes"
            )
        wait = deadline - now if client is None else min(deadline - now, no_worker / 10)
        tasks.finished.wait(timeout=wait)
        tasks.finished.clear()
        if client is not None:
            workers_gone_since = _watch_workers(client, workers_gone_since, no_worker, tasks)
        tasks.collect()
    return tasks.failures, tasks.summaries


class _BatchTasks:
    """The batch tasks of :func:`run_batches` in flight: each pending task's batch, the
    batches submitted again with a refreshed cache, the failures and the summaries;
    ``finished`` is set whenever a task ends."""

    def __init__(
        self,
        runner: Any,
        task: Any,
        parameters: dict[int, dict[str, Any]],
        stored: Callable[[int], bool],
        describe: Callable[[int, dict[str, Any]], str],
    ) -> None:
        self.logger = get_run_logger()
        self.runner, self.task, self.parameters = runner, task, parameters
        self.stored, self.describe = stored, describe
        self.finished = threading.Event()
        self.pending: dict[Any, int] = {}
        self.refreshed: set[int] = set()
        self.failures: dict[int, str] = {}
        self.summaries: dict[int, dict[str, Any]] = {}

    def submit(self, k: int, refresh: bool = False) -> None:
        chosen = self.task.with_options(refresh_cache=True) if refresh else self.task
        future = self.runner.submit(chosen, self.parameters[k])
        future.wrapped_future.add_done_callback(lambda _: self.finished.set())
        self.pending[future] = k

    def cancel(self) -> None:
        for future in self.pending:
            future.wrapped_future.cancel()

    def collect(self) -> None:
        """Take in every task that has ended: its summary, its failure, or (a cached
        result whose batch is not in the store) its batch submitted again, once."""
        for future in [f for f in self.pending if f.wrapped_future.done()]:
            k = self.pending.pop(future)
            try:
                summary = future.result()
            except Exception as err:
                self.failures[k] = f"{type(err).__name__}: {err}"
                self.logger.error("batch %d failed: %s", k, self.failures[k])
                continue
            if not self.stored(k):
                if k in self.refreshed:
                    self.failures[k] = "its task completed but the batch is not in the store"
                    self.logger.error("batch %d: %s", k, self.failures[k])
                    continue
                self.logger.info("batch %d: cached result, but not in the store: computing it", k)
                self.refreshed.add(k)
                self.submit(k, True)
                continue
            self.summaries[k] = summary
            self.logger.info(self.describe(k, summary))


def _watch_workers(
    client: Any, since: float | None, no_worker: float, tasks: _BatchTasks
) -> float | None:
    """Since when (``time.monotonic()``) the Dask cluster has had no worker, None while it
    has one; past ``no_worker`` seconds the pending tasks are cancelled and
    :class:`ClusterError` raised."""
    if count_workers(client) > 0:
        return None
    if since is None:
        return time.monotonic()
    if time.monotonic() - since >= no_worker:
        tasks.cancel()
        raise ClusterError(
            f"the Dask cluster has had no worker for {no_worker:g} s "
            "(configs/orchestration.yaml dask.no_worker_timeout_s) with "
            f"{len(tasks.pending)} batch(es) waiting: its workers died or left (a worker "
            "that cannot import ovtraj exits on its first task); see their logs"
        )
    return since


# -- sync wrappers ------------------------------------------------------------------------
def run_to_completion(make: Callable[[], Any]) -> Any:
    """Run the coroutine ``make()`` returns to completion from synchronous code.

    With no event loop running here, ``asyncio.run``; inside a running loop (a notebook,
    an async application) the coroutine runs on a loop of its own in another thread,
    with this context (Prefect's settings and run context) copied, and this call waits.
    """
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return asyncio.run(make())
    context = contextvars.copy_context()
    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(context.run, lambda: asyncio.run(make())).result()


def call_flow(flow_function: Callable[..., Any], **parameters: Any) -> Any:
    """Call a synchronous flow; inside a running event loop, from another thread (with
    this context), so that the flow never meets the caller's loop."""
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return flow_function(**parameters)
    context = contextvars.copy_context()
    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(context.run, lambda: flow_function(**parameters)).result()
