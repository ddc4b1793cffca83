"""Prefect task: one launch solve at one target altitude, cached on its inputs."""

from __future__ import annotations

from typing import Any

from prefect import task

from ovtraj.config import scenario_from_dict
from ovtraj.launch import launch_input, solve_launch
from ovtraj.launch.launch_fit import design_of, predicted_design
from tasks.common import TIMEOUTS, cached, parameter


def _solved(row: dict[str, Any] | None) -> tuple[float, dict[str, float]] | None:
    if row is None or not row["feasible"]:
        return None
    return row["target_altitude_km"] * 1e3, design_of(row)


def _name() -> str:
    scenario = (parameter("resolved_scenario") or {}).get("name", "?")
    return f"{scenario}/launch-{parameter('altitude_km')}km"


@task(
    name="launch-point",
    task_run_name=_name,
    tags=["ovtraj", "launch-fit"],
    retries=1,
    retry_delay_seconds=1,
    timeout_seconds=TIMEOUTS.launch_point_s,
    **cached(),
)
def launch_point_task(
    resolved_scenario: dict[str, Any],
    altitude_km: float,
    seed_row: dict[str, Any] | None = None,
    previous_row: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Maximum-payload launch to ``altitude_km``; returns the flat result row.

    Without a feasible ``seed_row`` the full genetic + local search runs; with one
    (the chain's last solved grid point, ``previous_row`` the one before it) only
    the local phases, from the secant prediction through them. The scenario, the
    altitude, the seed rows and the code version (the cache policy's) form the cache key.
    """
    inp = launch_input(scenario_from_dict(resolved_scenario), altitude_km=altitude_km)
    seed = _solved(seed_row)
    if seed is None:
        return solve_launch(inp).to_row()
    start = predicted_design(altitude_km * 1e3, seed, _solved(previous_row))
    return solve_launch(inp, seed_design=start, global_search=False).to_row()
