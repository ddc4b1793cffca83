"""Prefect task: one batch of a plan's dispersed Monte Carlo runs, stored, cached on its inputs."""

from __future__ import annotations

from typing import Any

from prefect import task

from ovtraj.mission.montecarlo_store import store_plan_batch
from tasks.common import TIMEOUTS, cached, parameter, run_label


def _name() -> str:
    runs = parameter("runs") or ["?"]
    return f"{run_label(parameter('run_url'))}/runs-{runs[0]}-{runs[-1]}"


@task(
    name="plan-mc-batch",
    task_run_name=_name,  # no tags: see tasks.common.BATCH_TAGS
    timeout_seconds=TIMEOUTS.mission_mc_batch_per_run_s,  # the flow scales it by the batch
    **cached(),
)
def plan_mc_batch_task(
    plan: dict[str, Any],
    dispersions: dict[str, Any],
    run_url: str,
    batch: int,
    runs: list[int],
    seed: int,
    force_model: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Fly the runs closed and open loop and store them as one batch (the closed loop
    under ``force_model``'s high-fidelity sky when given):
    :func:`ovtraj.mission.montecarlo_store.store_plan_batch`, the job of every batch of a
    plan's Monte Carlo (``ovtraj fly --monte-carlo`` flies the same in its process).

    The worker writes its own Parquet part (atomic, marker last) into the run at
    ``run_url``, so the rows never travel back through Prefect; the task returns a small
    summary. The cache key hashes the inputs and the code version.
    """
    return store_plan_batch(plan, dispersions, run_url, batch, runs, seed, force_model)
