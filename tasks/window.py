"""Prefect task: one launch day of a window, its whole pipeline in the task's process.

The task carries the day as plain data (:class:`ovtraj.window.scan.DayJob`: the day's
resolved scenario, the run store's root, the code version, the DoE and the pick), so a
process or a Dask worker needs the installed package only; it runs the library's day
(:func:`ovtraj.window.scan.run_day`: the day's launch fit, then ``ovtraj pipeline``'s
driver with the batches in series) and returns the day's record.

Not cached by Prefect: the window keeps each day's record in the run store, checked
against the plan it names, and submits only the days without one; a Prefect cache could
hand back a record whose plan the store no longer holds.
"""

from __future__ import annotations

from typing import Any

from prefect import task
from prefect.cache_policies import NO_CACHE

from ovtraj.window.scan import DayJob, run_day
from tasks.common import ORCHESTRATION, parameter


def _name() -> str:
    job = parameter("job") or {}
    scenario = (job.get("resolved") or {}).get("name", "?")
    return f"{scenario}/window-{job.get('window_id', '?')}/day-{job.get('date', '?')}"


@task(
    name="window-day",
    task_run_name=_name,
    tags=["ovtraj", "window"],
    # a day is a whole pipeline: the mission flow's limit (configs/orchestration.yaml)
    timeout_seconds=ORCHESTRATION.flows.mission_s,
    cache_policy=NO_CACHE,
    persist_result=False,
)
def window_day_task(job: dict[str, Any]) -> dict[str, Any]:
    """The day's pipeline and its record (``ovtraj.window.scan.run_day``)."""
    return run_day(DayJob(**job))
