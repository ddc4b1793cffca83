"""Prefect task: one batch of mission evaluations, stored by the worker in the run.

The task carries everything a worker needs, so a Dask worker anywhere needs only the
installed package: the run's absolute URL (``Run.url``, reopened by ``Run.open``), the
resolved scenario, the launch fit's coefficients (``LaunchFit.to_dict()``) and the batch's
samples. Nothing is looked up in the worker's folder or on its disk.
"""

from __future__ import annotations

from typing import Any

from prefect import task

from ovtraj.runs import execute
from tasks.common import TIMEOUTS, cached, parameter, run_label


def _name() -> str:
    batch = parameter("batch")
    size = len(batch) if isinstance(batch, list) else "?"
    scenario = (parameter("resolved_scenario") or {}).get("name", "?")
    return f"{scenario}/{run_label(parameter('run_url'))}/batch-{parameter('batch_index')}x{size}"


@task(
    name="mission-batch",
    task_run_name=_name,  # no tags: see tasks.common.BATCH_TAGS
    timeout_seconds=TIMEOUTS.mission_batch_per_sample_s,  # the flows scale it by the batch
    **cached(),
)
def mission_batch_task(
    resolved_scenario: dict[str, Any],
    run_url: str,
    batch_index: int,
    batch: list[dict[str, float]],
    launch_fit: dict[str, Any],
) -> dict[str, Any]:
    """Evaluate the mission chain for each sample row and store the batch in the run
    (``ovtraj.runs.execute.store_batch_job``, the job of every runner).

    The worker writes the batch itself under its claim (atomic parts, marker last), so
    the records never travel back through Prefect; the task returns a small summary. A
    batch the store already holds is not evaluated again (``stored_here`` false).
    """
    summary = execute.store_batch_job(run_url, resolved_scenario, launch_fit, batch_index, batch)
    return {
        "batch": batch_index,
        "samples": summary.get("samples", 0),
        "feasible": summary.get("feasible", 0),
        "stored_here": bool(summary["stored"]),
        "wall_time_s": summary["wall_time_s"],
    }
