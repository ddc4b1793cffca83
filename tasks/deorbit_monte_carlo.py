"""Prefect task: one batch of deorbit-burn Monte Carlo runs, stored, cached on its inputs."""

from __future__ import annotations

from typing import Any

from prefect import task

from ovtraj.studies.deorbit_burn.stored_monte_carlo import store_deorbit_batch
from tasks.common import TIMEOUTS, cached, parameter, run_label


def _name() -> str:
    runs = parameter("runs") or ["?"]
    return f"{run_label(parameter('run_url'))}/runs-{runs[0]}-{runs[-1]}"


@task(
    name="deorbit-mc-batch",
    task_run_name=_name,  # no tags: see tasks.common.BATCH_TAGS
    timeout_seconds=TIMEOUTS.deorbit_mc_batch_per_run_s,  # the flow scales it by the batch
    **cached(),
)
def deorbit_mc_batch_task(
    resolved_problem: dict[str, Any],
    run_url: str,
    batch: int,
    runs: list[int],
    strategies: list[int],
    seed: int,
) -> dict[str, Any]:
    """Simulate the runs (every strategy on the same draws) and store them as one batch:
    :func:`ovtraj.studies.deorbit_burn.stored_monte_carlo.store_deorbit_batch`, the job of
    every batch of a deorbit-burn Monte Carlo (its nominal plan solved once per worker
    process and problem).

    The worker writes its own Parquet part (atomic, marker last) into the run at
    ``run_url`` (absolute), so the rows never travel back through Prefect; the task
    returns a small summary. The cache key hashes the inputs (problem, run, runs,
    strategies, seed) and the code version: the flow submits only runs the store does
    not hold, and runs again with a refreshed cache a batch whose files went missing
    after a cached run.
    """
    return store_deorbit_batch(resolved_problem, run_url, batch, runs, strategies, seed)
