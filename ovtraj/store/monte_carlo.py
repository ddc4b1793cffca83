"""The one driver of a Monte Carlo stored in batches (:class:`~.batched.BatchedRun`).

1. the study's run is created, or the stored one of the same id reopened
   (:meth:`MonteCarloStudy.open_run`: the id hashes what the rows depend on);
2. the runs it does not hold yet are grouped in batches of ``batch_size`` consecutive run
   numbers (:func:`~.batched.consecutive_batches`: a batch's first run names it), and a
   :class:`BatchFlier` flies them, each batch one call of the study's :class:`BatchJob`,
   which stores its own part;
3. the study finishes the run from what is stored (its summary, pictures and status) and
   reports it (:meth:`MonteCarloStudy.finish`).

Where the batches fly is the flier's business, nothing else: one after another in this
process, on a pool of processes or a Dask cluster
(:class:`ovtraj.runs.monte_carlo_pool.PoolFlier`), or as Prefect tasks
(``flows/monte_carlo_tasks.py``). A job carries plain values only, so every flier makes
the same call with the same inputs, and the run's id, parts, summary and pictures do not
depend on the flier (tests/test_montecarlo_store.py compares the command's run with the
flow's file by file). The studies: a mission plan's Monte Carlo
(:class:`ovtraj.runs.plan_monte_carlo.PlanMonteCarlo`) and the deorbit burn's
(:class:`ovtraj.studies.deorbit_burn.stored_monte_carlo.DeorbitMonteCarlo`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Protocol

from ovtraj.store.batched import BatchedRun, consecutive_batches

__all__ = ["BatchFlier", "BatchJob", "MonteCarloStudy", "drive_monte_carlo"]


@dataclass(frozen=True)
class BatchJob:
    """How one batch is flown and stored, by whatever process runs it:
    ``function(**inputs, batch=<its first run>, runs=<its run numbers>, on_run=None)``
    stores the batch in the run at ``inputs["run_url"]`` and returns a small summary
    (``batch``, ``runs``, ``rows``, ``failed``, ``wall_time_s``); ``on_run()``, when given,
    after each run. ``function`` is a module-level function of the library and ``inputs``
    plain (JSON) values, so the job travels as it is to a worker process, a Dask worker
    or a Prefect task (whose parameters are ``inputs``, ``batch`` and ``runs``)."""

    function: Callable[..., dict[str, Any]]
    inputs: dict[str, Any]


class MonteCarloStudy(Protocol):
    """What a stored Monte Carlo flies: ``runs`` runs (numbered from 0), stored
    ``batch_size`` consecutive runs a part."""

    runs: int
    batch_size: int

    def open_run(self) -> BatchedRun:
        """The run of the study's inputs: created, or the stored one reopened."""
        ...

    def job(self, run: BatchedRun) -> BatchJob:
        """The job that flies a batch of ``run`` and stores it there."""
        ...

    def finish(self, run: BatchedRun, simulated: int, failures: dict[int, str]) -> dict[str, Any]:
        """The run's summary, pictures and status written from what is stored, after
        ``simulated`` runs flown by this pass and the ``failures`` of its batches (by first
        run); the report returned."""
        ...


class BatchFlier(Protocol):
    """Flies the batches of a run: started on ``__enter__`` (a pool), stopped on
    ``__exit__``; entered only when there is something to fly."""

    def __enter__(self) -> BatchFlier: ...

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> bool | None: ...

    def fly(self, run: BatchedRun, job: BatchJob, batches: list[list[int]]) -> dict[int, str]:
        """Fly each batch (a list of consecutive run numbers) by ``job``, which stores it
        in ``run`` as the batch of its first run; returns the failed ones, by first run,
        with what went wrong (a stored batch stays stored: a new pass flies only the
        missing runs)."""
        ...


def drive_monte_carlo(
    study: MonteCarloStudy,
    flier: BatchFlier,
    *,
    opened: Callable[[BatchedRun, int], None] | None = None,
) -> dict[str, Any]:
    """The Monte Carlo of ``study`` stored (module notes), its missing batches flown by
    ``flier``; ``opened(run, runs to fly)`` once the run is known, before any flight.
    Returns :meth:`MonteCarloStudy.finish`'s report."""
    run = study.open_run()
    todo = sorted(set(range(study.runs)) - run.done_runs())
    if opened is not None:
        opened(run, len(todo))
    failures: dict[int, str] = {}
    batches = consecutive_batches(todo, study.batch_size)
    if batches:
        run.update_info(status="running")
        with flier:
            failures = flier.fly(run, study.job(run), batches)
    return study.finish(run, len(todo), failures)
