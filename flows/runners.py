"""The task runners behind the one runner option (``serial | threads | processes | dask``).

``ovtraj run --runner``, ``mission.doe.task_runner`` and the flows' ``runner`` parameter
name the same choices (``ovtraj.config.mission.RUNNERS``):

- ``serial``: one task after another in the flow's process (a pool of one thread);
- ``threads`` / ``processes``: Prefect's pools of ``workers`` threads or processes;
- ``dask``: the Dask cluster at ``dask_address`` (workers started anywhere, with ovtraj
  installed), or a local cluster of ``workers`` processes when there is no address.

With Dask, the ``tasks`` and ``flows`` modules travel by value (cloudpickle), so a worker
needs the installed package only, no checkout and no shared working folder. Before the
first batch the flow checks the cluster within ``dask.connect_timeout_s``
(``configs/orchestration.yaml``): the scheduler answers, a worker is up, and every worker
imports ovtraj (a worker that cannot would exit on the first task it deserialises, leaving
the flow waiting); any failure is one error naming the worker and the cause.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from prefect.task_runners import ProcessPoolTaskRunner, ThreadPoolTaskRunner
from threadpoolctl import threadpool_limits

from ovtraj.parallel import EVALUATION_BLAS_THREADS
from ovtraj.runs.runners import ClusterError, check_cluster, check_runner, count_workers
from tasks.common import ORCHESTRATION

__all__ = ["ClusterError", "check_runner", "count_workers", "dask_runner", "task_runner"]


@contextmanager
def task_runner(runner: str, workers: int, dask_address: str | None = None) -> Iterator[Any]:
    """The started Prefect task runner of ``runner`` (checked first when it is Dask)."""
    check_runner(runner, dask_address)
    if runner in ("serial", "threads"):
        # BLAS's thread count is process-wide: set for the pool's life, not per batch
        # (ovtraj.runs.runners.batch_pool does the same)
        with (
            threadpool_limits(limits=EVALUATION_BLAS_THREADS, user_api="blas"),
            ThreadPoolTaskRunner(max_workers=1 if runner == "serial" else workers) as started,
        ):
            yield started
        return
    if runner == "processes":
        with ProcessPoolTaskRunner(max_workers=workers) as started:
            yield started
        return
    with dask_runner(workers, dask_address) as started:
        yield started


def _ship_by_value() -> None:
    """Pickle ``tasks`` and ``flows`` by value: Dask workers need not have a checkout."""
    import sys

    import cloudpickle

    # The packages and each loaded module: distributed looks a function's own module up.
    for name, module in sorted(sys.modules.items()):
        if name.split(".")[0] in ("tasks", "flows") and module is not None:
            if name not in cloudpickle.list_registry_pickle_by_value():
                cloudpickle.register_pickle_by_value(module)


@contextmanager
def dask_runner(workers: int, address: str | None) -> Iterator[Any]:
    """Prefect's Dask task runner on the cluster at ``address`` (else a local one),
    checked by :func:`ovtraj.runs.runners.check_cluster` before the first batch."""
    from prefect_dask import DaskTaskRunner

    _ship_by_value()
    settings = ORCHESTRATION.dask
    if address:
        runner = DaskTaskRunner(
            address=address, client_kwargs={"timeout": settings.connect_timeout_s}
        )
    else:
        runner = DaskTaskRunner(
            cluster_kwargs={
                "n_workers": workers,
                "processes": True,
                "threads_per_worker": settings.threads_per_worker,
                "dashboard_address": None,
            }
        )
    with runner as started:
        check_cluster(started.client, address or "a local cluster", settings)
        yield started
