"""Prefect task: one launch solve at one target altitude, cached on its inputs."""

from __future__ import annotations

from typing import Any

from prefect import task
from prefect.cache_policies import INPUTS

from ovtraj import __version__
from ovtraj.config import scenario_from_dict
from ovtraj.launch import launch_input, solve_launch
from ovtraj.launch.fit import design_of


@task(
    name="launch-point",
    cache_policy=INPUTS,
    retries=1,
    retry_delay_seconds=1,
    persist_result=True,
)
def launch_point_task(
    resolved_scenario: dict[str, Any],
    altitude_km: float,
    seed_row: dict[str, Any] | None = None,
    code_version: str = __version__,
) -> dict[str, Any]:
    """Maximum-payload launch to ``altitude_km``; returns the flat result row.

    Without ``seed_row`` the full genetic + local search runs; with one (a
    neighbouring grid point's row) only the local phases, from its design. The
    scenario, altitude, seed and ``code_version`` form the cache key.
    """
    inp = launch_input(scenario_from_dict(resolved_scenario), altitude_km=altitude_km)
    if seed_row is None or not seed_row["feasible"]:
        return solve_launch(inp).to_row()
    return solve_launch(inp, seed_design=design_of(seed_row), global_search=False).to_row()
