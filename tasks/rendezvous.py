"""Prefect task: one rendezvous solve, cached on its resolved inputs and the code version."""

from __future__ import annotations

from typing import Any

from prefect import task

from ovtraj.config import scenario_from_dict
from ovtraj.rendezvous import rendezvous_input, solve_rendezvous
from tasks.common import TIMEOUTS, cached, parameter


def _name() -> str:
    return f"{(parameter('resolved_scenario') or {}).get('name', '?')}/rendezvous"


@task(
    name="rendezvous",
    task_run_name=_name,
    tags=["ovtraj", "rendezvous"],
    retries=1,
    retry_delay_seconds=1,
    timeout_seconds=TIMEOUTS.rendezvous_s,
    **cached(),
)
def rendezvous_task(resolved_scenario: dict[str, Any]) -> dict:
    """Solve the scenario's rendezvous; returns the flat result row.

    ``resolved_scenario`` is the fully resolved config (``Scenario.resolved()``): with
    the code version (the cache policy's) it is the cache key, so a re-run with the same
    inputs and code reads the stored row instead of solving again, and a code change
    solves again.
    """
    result = solve_rendezvous(rendezvous_input(scenario_from_dict(resolved_scenario)))
    return result.to_row()
