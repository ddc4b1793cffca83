"""What ``ovtraj deorbit-burn`` prints: the solve, its history, an optional stored Monte
Carlo.

:func:`deorbit_burn_report` gathers plain JSON types; :func:`format_report` renders them
as text. The CLI loads the problem (``ConfigError`` -> exit 2), has the Monte Carlo stored
by the one driver (the flow's study, flown in its process) and prints one of them.
"""

from __future__ import annotations

from typing import Any

from ovtraj.formatting import number, quantity, split_unit
from ovtraj.store.records import plain
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

# The stored Monte Carlo's report but its run: the statistics and figures the report
# carries, and the failed batches (a command stops on one).
_NOT_THE_RUN = ("statistics", "published", "failed_batches")


def deorbit_burn_report(
    problem: DeorbitBurnProblem,
    *,
    strategy: int | None = None,
    monte_carlo: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Solve with ``strategy`` (else the config's) and gather the report beside the stored
    Monte Carlo ``monte_carlo``, when given: the report of its run
    (:class:`~.stored_monte_carlo.DeorbitMonteCarlo` flown by
    :func:`ovtraj.store.monte_carlo.drive_monte_carlo`), which this flies nothing of.

    Returns ``{"result": to_row(), "history": [...], "monte_carlo": [per-strategy
    statistics] | None, "published": [...], "monte_carlo_run": {...} | None}``: the
    statistics and the dispersion figures of ``published`` are the stored run's
    (``statistics``, ``published``); ``monte_carlo_run`` is the rest of its report (id,
    directory, plots, runs flown now, status).
    """
    solver = BurnSolver(problem)
    result = solver.solve(strategy=strategy)
    published = [row.as_dict() for row in published_comparison(problem, result=result)]
    report: dict[str, Any] = {
        "result": result.to_row(),
        "history": [plain(record.as_dict()) for record in result.history],
        "monte_carlo": None,
    }
    run = None
    if monte_carlo is not None:
        report["monte_carlo"] = monte_carlo["statistics"]
        stored = {row["figure"]: row for row in monte_carlo["published"]}
        published = [stored.get(row["figure"], row) for row in published]
        run = {k: v for k, v in monte_carlo.items() if k not in _NOT_THE_RUN}
    report["published"] = published
    report["monte_carlo_run"] = run
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
