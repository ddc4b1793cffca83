"""Prefect task: one rendezvous solve, cached on its resolved inputs and the code version."""

from __future__ import annotations

from typing import Any

from prefect import task
from prefect.cache_policies import INPUTS

from ovtraj import __version__
from ovtraj.config import scenario_from_dict
from ovtraj.rendezvous import rendezvous_input, solve_rendezvous


@task(
    name="rendezvous",
    cache_policy=INPUTS,
    retries=1,
    retry_delay_seconds=1,
    persist_result=True,
)
def rendezvous_task(resolved_scenario: dict[str, Any], code_version: str = __version__) -> dict:
    """Solve the scenario's rendezvous; returns the flat result row.

    ``resolved_scenario`` is the fully resolved config (``Scenario.resolved()``):
    together with ``code_version`` it is the cache key, so a re-run with the same
    inputs and code reads the stored row instead of solving again.
    """
    result = solve_rendezvous(rendezvous_input(scenario_from_dict(resolved_scenario)))
    return result.to_row()
