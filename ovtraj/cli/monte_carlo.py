"""A stored Monte Carlo flown by a command in its own process: the one driver
(:func:`ovtraj.store.monte_carlo.drive_monte_carlo`) with its batches one after another
here (:class:`ovtraj.runs.monte_carlo_pool.PoolFlier`, serial), as the flows drive the
same study with their batches as Prefect tasks; so a command and its flow store the same
run (``ovtraj fly PLAN --monte-carlo N``, ``ovtraj deorbit-burn CONFIG --monte-carlo N``).

The heavy modules load inside the functions (``ovtraj --help`` loads this module).
"""

from __future__ import annotations

from typing import Any

import typer

from ovtraj.cli.progress import progress_bar

__all__ = ["drive_here", "format_stored"]


def drive_here(study: Any, *, as_json: bool) -> dict[str, Any]:
    """The Monte Carlo of ``study`` (a :class:`~ovtraj.store.monte_carlo.MonteCarloStudy`)
    stored by the driver, its missing runs flown in this process with a progress bar on
    stderr (not with ``as_json``); the driver's report. A failed batch or an unusable
    store: one line, exit 2 (the stored batches are kept: the same command flies the
    missing runs)."""
    from ovtraj.runs.monte_carlo_pool import PoolFlier
    from ovtraj.runs.runners import RunnerChoice
    from ovtraj.store.files import StoreError
    from ovtraj.store.monte_carlo import drive_monte_carlo

    with progress_bar("Monte Carlo runs", enabled=not as_json) as update:
        flown = {"done": 0, "total": 0}

        def opened(run: Any, todo: int) -> None:
            flown["total"] = todo

        def step() -> None:
            flown["done"] += 1
            update(flown["done"], flown["total"])

        here = PoolFlier(RunnerChoice("serial", 1), on_run=step)
        try:
            report = drive_monte_carlo(study, here, opened=opened)
        except StoreError as err:
            typer.echo(str(err), err=True)
            raise typer.Exit(code=2) from None
    if report["failed_batches"]:
        typer.echo(
            f"{report['directory']}: {len(report['failed_batches'])} batch(es) failed "
            f"({'; '.join(report['failed_batches'])}); the stored runs are kept, the same "
            "command flies the missing ones",
            err=True,
        )
        raise typer.Exit(code=2)
    return report


def format_stored(report: dict[str, Any]) -> str:
    """Where the Monte Carlo is stored: the run's directory and its pictures."""
    flown = report["simulated_runs"]
    stored = "flown now" if flown == report["runs"] else f"{flown} flown now, the rest stored"
    lines = [f"monte carlo run {report['run_id']} ({stored}): {report['directory']}"]
    lines += [f"  picture: {path}" for path in report["plots"]]
    return "\n".join(lines)
