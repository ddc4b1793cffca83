"""A stored Monte Carlo's batches on the library's pools (:func:`.runners.batch_pool`):
the :class:`~ovtraj.store.monte_carlo.BatchFlier` of the command line.

``serial`` flies the batches one after another in this process (``ovtraj fly PLAN
--monte-carlo N``), a step after each run; ``threads``, ``processes`` and ``dask`` submit
every batch at once to the pool, each job carrying its plain inputs
(:class:`~ovtraj.store.monte_carlo.BatchJob`), and count its runs when it ends. The
Prefect tasks of the flows are the other flier (``flows/monte_carlo_tasks.py``).
"""

from __future__ import annotations

import concurrent.futures
import functools
import time
from collections.abc import Callable
from typing import Any

from ovtraj.config.orchestration import DaskSettings, load_orchestration
from ovtraj.runs.runners import BatchPool, ClusterError, RunnerChoice, StartedPool
from ovtraj.store.batched import BatchedRun
from ovtraj.store.monte_carlo import BatchJob

__all__ = ["PoolFlier"]


class PoolFlier(StartedPool):
    """The batches of a stored Monte Carlo on the pool of ``choice``, started on enter.

    ``on_run()`` after each run flown (on a pool: a batch's runs when it ends). A batch
    that raises is a failed batch (by its first run, with what went wrong), as a failed
    task is in the flows, and the others still fly. On a Dask cluster that has had no
    worker for ``dask.no_worker_timeout_s`` (``dask``: ``configs/orchestration.yaml``'s
    unless given), the batches still waiting are cancelled and :class:`ClusterError` is
    raised."""

    def __init__(
        self,
        choice: RunnerChoice,
        *,
        on_run: Callable[[], None] | None = None,
        dask: DaskSettings | None = None,
    ) -> None:
        super().__init__(choice, dask)
        self.on_run = on_run

    def __enter__(self) -> PoolFlier:
        if self.dask is None and self.choice.runner != "serial":  # a pool's settings only
            self.dask = load_orchestration().dask
        return super().__enter__()

    def fly(self, run: BatchedRun, job: BatchJob, batches: list[list[int]]) -> dict[int, str]:
        """Each batch flown by ``job`` (stored in ``run`` by the job itself); the failed
        batches by first run."""
        pool = self.pool
        if pool is None or pool.executor is None or self.dask is None:
            return self._fly_here(job, batches)
        return self._fly_on_pool(pool, pool.executor, self.dask.no_worker_timeout_s, job, batches)

    def _fly_here(self, job: BatchJob, batches: list[list[int]]) -> dict[int, str]:
        failures: dict[int, str] = {}
        for runs in batches:
            try:
                job.function(**job.inputs, batch=runs[0], runs=runs, on_run=self.on_run)
            except Exception as err:  # reported per batch, as the flows report a task
                failures[runs[0]] = f"{type(err).__name__}: {err}"
        return failures

    def _fly_on_pool(
        self,
        pool: BatchPool,
        executor: concurrent.futures.Executor,
        no_worker: float,
        job: BatchJob,
        batches: list[list[int]],
    ) -> dict[int, str]:
        """Every batch submitted to the pool's ``executor`` at once, collected as they end;
        ``no_worker`` [s]: how long a Dask cluster may have no worker."""
        submitted = {
            executor.submit(
                functools.partial(job.function, **job.inputs, batch=runs[0], runs=runs)
            ): runs
            for runs in batches
        }
        failures: dict[int, str] = {}
        pending = set(submitted)
        gone_since: float | None = None
        while pending:
            done, pending = concurrent.futures.wait(
                pending, timeout=no_worker / 10, return_when="FIRST_COMPLETED"
            )
            for future in done:
                failures.update(self._ended(future, submitted[future]))
            if pending:
                gone_since = _workers_gone_since(pool, gone_since, pending, no_worker)
        return failures

    def _ended(self, future: concurrent.futures.Future, runs: list[int]) -> dict[int, str]:
        """A batch's job ended: its runs counted, or its failure."""
        try:
            future.result()
        except Exception as err:
            return {runs[0]: f"{type(err).__name__}: {err}"}
        if self.on_run is not None:
            for _ in runs:
                self.on_run()
        return {}


def _workers_gone_since(
    pool: BatchPool, since: float | None, pending: set[Any], no_worker_s: float
) -> float | None:
    """Since when the pool has had no worker (``time.monotonic()``; None: it has some);
    past ``no_worker_s`` [s], the waiting batches cancelled and :class:`ClusterError`
    raised (only a Dask cluster loses its workers)."""
    if pool.workers_alive():
        return None
    now = time.monotonic()
    if since is None or now - since < no_worker_s:
        return now if since is None else since
    for future in pending:
        future.cancel()
    raise ClusterError(
        f"the Dask cluster has had no worker for {no_worker_s:g} s "
        "(configs/orchestration.yaml dask.no_worker_timeout_s) with "
        f"{len(pending)} batch(es) waiting: its workers died or left; see their logs"
    )
