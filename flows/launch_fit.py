"""Flow: the launch fit of a scenario (``flows/launch_fit.py:launch_fit_flow``).

1. solve the launch at the scenario's target altitude (genetic + local search);
2. solve the grid altitudes above and below it as two chains of tasks running in
   parallel, each point starting from the secant prediction through the chain's
   last two optima;
3. fit the Fourier series (patent 5.1) and save coefficients and grid.

Every point is a task cached on its inputs (scenario, altitude, seed rows) and the code
version, so a re-run recomputes nothing and a code change recomputes everything; the
summary counts the cached points. The points run on ``runner`` (default: two processes,
one per chain; ``serial | threads | processes | dask``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger

from flows.common import (
    FLOW_TIMEOUTS,
    label_flow_run,
    prepared,
    prune_expired_results,
    run_name,
    run_tags,
)
from flows.runners import task_runner
from ovtraj.config import Scenario
from ovtraj.launch.launch_fit import (
    LaunchFit,
    continuation_chains,
    fit_roots,
    fit_rows,
    launch_fit_key,
)
from ovtraj.paths import scenario_file
from ovtraj.runs.preparation import LaunchFitter
from ovtraj.target_sources import load_scenario_with_target
from tasks.launch import launch_point_task

# The upward and the downward chain of grid points run side by side.
CHAINS = 2


@flow(
    name="launch-fit",
    flow_run_name=run_name("launch-fit"),
    timeout_seconds=FLOW_TIMEOUTS.launch_fit_s,
)
def launch_fit_flow(
    config: str | None = None,
    out: str | None = None,
    target: str | None = None,
    runner: str = "processes",
    dask_address: str | None = None,
) -> dict[str, Any]:
    """Solve the altitude grid, fit payload, insertion time and u; save and summarise.

    The parameters are ``ovtraj launch-fit``'s options by the same names
    (tests/test_flows.py), and where the points run. ``config``: the scenario file
    (default: the shipped one). ``out``: the fit's folder (default: the fit store's, by
    the fit's key). ``target``: a TLE/OMM file or URL that replaces the scenario's target
    (its plane).
    ``runner``/``dask_address``: where the points run (two workers: one per chain).
    """
    logger = get_run_logger()
    prune_expired_results()
    path = scenario_file(config)
    scenario = load_scenario_with_target(path, target)
    if scenario.launch is None:
        raise ValueError(f"{path}: the scenario has no launch section")
    settings = scenario.launch
    key = launch_fit_key(scenario)
    labels = run_tags("launch-fit", scenario.name, key)
    label_flow_run(f"launch-fit {scenario.name} {key}", labels)
    rows, cached = _solved_points(scenario, runner, dask_address)
    on_grid = [rows[h] for h in settings.fit.altitudes_km() if h in rows]
    for row in on_grid:
        logger.info(
            "%.1f km: payload %.2f kg, feasible %s, %.1f s",
            row["target_altitude_km"],
            row["payload_kg"] or float("nan"),
            row["feasible"],
            row["wall_time_s"],
        )
    fit = fit_rows(on_grid, settings.fit, settings.launcher.name, key=key)
    directory = Path(out) if out else fit_roots()[0] / key
    fit.save(directory)
    summary = {
        "points": len(on_grid),
        "solved_points": len(rows),
        "cached_points": cached,
        "payload_kg": [row["payload_kg"] for row in on_grid],
        "altitude_range_km": list(fit.altitude_range_km),
        "directory": str(directory),
        "key": key,
    }
    return summary | _fit_errors(fit)


def _solved_points(
    scenario: Scenario, runner: str, dask_address: str | None
) -> tuple[dict[float, dict[str, Any]], int]:
    """The reference point, then the grid's upward and downward chains side by side, each
    point a task seeded by the chain's previous optima; returns the rows by altitude [km]
    and how many of them were cached."""
    resolved = scenario.resolved()
    reference_km = scenario.launch.target_altitude_km
    point = prepared(launch_point_task)
    with task_runner(runner, CHAINS, dask_address) as started:
        reference = started.submit(
            point, {"resolved_scenario": resolved, "altitude_km": reference_km}
        )
        futures = {reference_km: reference}
        up, down = continuation_chains(scenario.launch.fit.altitudes_km(), reference_km)
        for chain in (up, down):
            previous, seed = None, reference
            for altitude_km in chain:
                parameters = {
                    "resolved_scenario": resolved,
                    "altitude_km": altitude_km,
                    "seed_row": seed,
                    "previous_row": previous,
                }
                previous, seed = seed, started.submit(point, parameters)
                futures[altitude_km] = seed
        rows = {h: future.result() for h, future in futures.items()}
    cached = sum(1 for future in futures.values() if future.state.name == "Cached")
    return rows, cached


def _fit_errors(fit: LaunchFit) -> dict[str, float]:
    """Each series' leave-one-out errors for the summary (absolute and relative to its
    range), each logged with its residual."""
    logger = get_run_logger()
    errors = {}
    for name, series in fit.series.items():
        errors[f"{name}_loo_max"] = series.loo_max_error
        errors[f"{name}_loo_relative"] = fit.loo_relative_error(name)
        logger.info(
            "fit %s: rms %.3g %s, leave-one-out max %.3g %s (%.2f %% of range)",
            name,
            series.rms_residual,
            series.unit,
            series.loo_max_error,
            series.unit,
            100 * fit.loo_relative_error(name),
        )
    return errors


def launch_fit_subflow(config: str | None, target: str | None = None) -> LaunchFitter:
    """How a flow solves a scenario's missing launch fit (configs/orchestration.yaml
    ``preparation.launch_fit: fit``, :func:`ovtraj.runs.preparation.required_launch_fit`):
    this flow as a subflow on the same ``config`` and ``target``, stored under its key."""

    def fit(scenario: Scenario) -> None:
        get_run_logger().info("no launch fit for this scenario yet: running the launch-fit flow")
        launch_fit_flow(config, target=target)

    return fit


if __name__ == "__main__":
    launch_fit_flow()
