"""The Monte Carlo driver's batches as Prefect tasks: the flows' flier
(:class:`ovtraj.store.monte_carlo.BatchFlier`) of ``ovtraj.store.monte_carlo.drive_monte_carlo``.

A Monte Carlo flow reads its inputs, builds the library's study, and hands the driver a
:class:`MonteCarloTasks`: every batch a cached task on the flow's task runner, whose body
is the study's job (``tasks/mission_monte_carlo.py``, ``tasks/deorbit_monte_carlo.py``),
so the flow stores what the command's process or pool stores for the same inputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import TracebackType
from typing import Any

from flows.common import store_missing_batches
from flows.runners import check_runner
from ovtraj.store.batched import BatchedRun
from ovtraj.store.monte_carlo import BatchJob


@dataclass
class MonteCarloTasks:
    """Each batch the Prefect task ``task`` (its parameters: the job's inputs, ``batch`` and
    ``runs``), cached on its inputs, with ``retries`` and a timeout of
    ``timeout_per_run_s`` times ``batch_size``, on the task runner ``runner`` of
    ``workers`` (``dask_address``: the ``dask`` runner's scheduler), started when there
    are batches to fly (:func:`flows.common.store_missing_batches`). Past ``deadline``
    (``time.monotonic()``; ``limit`` names the setting) the batches not started are
    cancelled and the flow fails."""

    task: Any
    runner: str
    workers: int
    dask_address: str | None
    retries: int
    timeout_per_run_s: float
    batch_size: int
    deadline: float
    limit: str

    @classmethod
    def configured(
        cls,
        task: Any,
        settings: Any,
        timeout_per_run_s: float,
        *,
        runner: str | None,
        workers: int | None,
        dask_address: str | None,
        batch_size: int,
        deadline: float,
        limit: str,
    ) -> MonteCarloTasks:
        """The flier of a flow's parameters: ``runner`` and ``workers``, else the Monte
        Carlo ``settings``' ``task_runner`` and ``workers`` (with its ``task_retries``).
        A runner that is not one, or an address without ``dask``, raises ``ValueError``
        naming it (:func:`flows.runners.check_runner`)."""
        chosen = runner or settings.task_runner
        check_runner(chosen, dask_address)
        return cls(
            task,
            runner=chosen,
            workers=workers or settings.workers,
            dask_address=dask_address,
            retries=settings.task_retries,
            timeout_per_run_s=timeout_per_run_s,
            batch_size=batch_size,
            deadline=deadline,
            limit=limit,
        )

    def __enter__(self) -> MonteCarloTasks:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        return None

    def fly(self, run: BatchedRun, job: BatchJob, batches: list[list[int]]) -> dict[int, str]:
        """The batches as tasks (``store_missing_batches`` groups their runs into the same
        batches again: consecutive runs, ``batch_size`` at a time)."""
        return store_missing_batches(
            run,
            [k for runs in batches for k in runs],
            self.batch_size,
            self.task,
            lambda group: job.inputs,
            runner=self.runner,
            workers=self.workers,
            dask_address=self.dask_address,
            retries=self.retries,
            timeout_per_run_s=self.timeout_per_run_s,
            deadline=self.deadline,
            limit=self.limit,
        )


def raise_failed_batches(report: dict[str, Any], failed: list[str]) -> None:
    """A flow run fails naming the batches that failed (after their retries): the stored
    ones are kept, and a new flow run flies only the missing runs."""
    if failed:
        raise RuntimeError(
            f"run {report['run_id']}: {len(failed)} batch(es) failed: {'; '.join(failed)}"
        )
