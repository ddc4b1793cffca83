"""What ``ovtraj deorbit-burn`` prints: the solve, its history, an optional Monte Carlo.

:func:`deorbit_burn_report` gathers plain JSON types; :func:`format_report` renders them
as text. The CLI only loads the problem (``ConfigError`` -> exit 2) and prints one of them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ovtraj.formatting import number, quantity, split_unit
from ovtraj.store.records import plain
from ovtraj.studies.deorbit_burn.montecarlo import (
    MonteCarloContext,
    monte_carlo_summary,
    run_monte_carlo,
)
from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem
from ovtraj.studies.deorbit_burn.published import published_comparison
from ovtraj.studies.deorbit_burn.solve import BurnSolver

__all__ = ["REPORT_KEYS", "deorbit_burn_report", "format_report"]

# The fields of the solve that the CLI prints; ``--json`` gives them all.
REPORT_KEYS = (
    "converged",
    "reason",
    "strategy",
    "iterations",
    "u_open_deg",
    "burn_duration_s",
    "dv_mps",
    "burn_angle_deg",
    "entry_u_error_deg",
    "along_track_error_km",
    "entry_fpa_error_deg",
    "entry_speed_error_mps",
    "impulsive_dv_mps",
    "impulsive_burn_angle_deg",
    "solve_time_s",
)


def deorbit_burn_report(
    problem: DeorbitBurnProblem,
    *,
    strategy: int | None = None,
    monte_carlo_runs: int | None = None,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """Solve (and with ``monte_carlo_runs``, run the Monte Carlo in this process;
    ``on_progress(runs done, runs, label)`` after each run).

    Returns ``{"result": to_row(), "history": [...], "monte_carlo": [per-strategy
    statistics] | None, "published": [...]}``. The Monte Carlo flies ``strategy`` if given,
    else the config's strategies, with the config's seed.
    """
    solver = BurnSolver(problem)
    result = solver.solve(strategy=strategy)
    report: dict[str, Any] = {
        "result": result.to_row(),
        "history": [plain(record.as_dict()) for record in result.history],
        "monte_carlo": None,
    }
    summary = None
    if monte_carlo_runs:
        config = problem.config.monte_carlo
        strategies = [strategy] if strategy is not None else list(config.strategies)
        frame = run_monte_carlo(
            problem,
            monte_carlo_runs,
            strategies,
            config.seed,
            context=MonteCarloContext(problem),
            on_progress=on_progress,
        )
        summary = monte_carlo_summary(frame)
        report["monte_carlo"] = [plain(row) for row in summary.to_dict(orient="records")]
    report["published"] = [
        row.as_dict() for row in published_comparison(problem, result=result, summary=summary)
    ]
    return report


def format_report(report: dict[str, Any]) -> str:
    """Text for a terminal: the solve's fields (their units from the key names; a reason
    only when there is one), then the Monte Carlo statistics."""
    row = report["result"]
    lines = [f"deorbit burn: {row['name']}"]
    shown = [
        (*split_unit(key), row.get(key)) for key in REPORT_KEYS if key != "reason" or row.get(key)
    ]
    width = max(len(name) for name, _, _ in shown)
    for name, unit, value in shown:
        lines.append(f"  {name.replace('_', ' '):<{width}}  {quantity(value, unit)}")
    for stats in report.get("monte_carlo") or []:
        lines.append(
            f"  Monte Carlo strategy {stats['strategy']}: {stats['runs']} runs, "
            f"{stats['failed']} failed; along-track max |err| "
            f"{number(stats['along_track_error_km_max_abs'], 'km')} (std "
            f"{number(stats['along_track_error_km_std'], 'km')}); fpa max |err| "
            f"{number(stats['entry_fpa_error_deg_max_abs'], 'deg', 3)} (std "
            f"{number(stats['entry_fpa_error_deg_std'], 'deg', 3)}); dv mean "
            f"{number(stats['dv_mps_mean'], 'm/s', 5)}"
        )
    return "\n".join(lines)
