"""The deorbit burn's stored Monte Carlo: a study of the one Monte Carlo driver
(:func:`ovtraj.store.monte_carlo.drive_monte_carlo`), which the deorbit Monte Carlo flow
(``flows/deorbit_monte_carlo.py``) runs with its batches as Prefect tasks.

1. the run ``<store>/<run_id>/`` (:class:`~.store.MonteCarloRun`) is created, or the stored
   one reopened: its id hashes the resolved problem (what counts for results), the runs,
   the strategies, the seed and the code version;
2. the runs it does not hold yet fly in batches of consecutive runs, every strategy on the
   same draws, each batch storing its own part (:func:`store_deorbit_batch`);
3. ``summary.json``: the statistics per strategy (:func:`~.montecarlo.monte_carlo_summary`)
   and the published figures beside them, with the scatter and histogram plots of the
   entry errors (:func:`~.plots.plot_dispersions`) in ``plots/``, and the run's status.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ovtraj.store.monte_carlo import BatchJob
from ovtraj.store.records import plain
from ovtraj.studies.deorbit_burn.montecarlo import (
    MonteCarloContext,
    monte_carlo_summary,
    simulate_runs,
)
from ovtraj.studies.deorbit_burn.plots import plot_dispersions
from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem, deorbit_burn_from_dict
from ovtraj.studies.deorbit_burn.published import published_comparison
from ovtraj.studies.deorbit_burn.store import MonteCarloRun

__all__ = ["DeorbitMonteCarlo", "store_deorbit_batch"]

# Nominal plans kept per process: a few problems at once.
CONTEXTS = 4
_CONTEXTS: dict[str, MonteCarloContext] = {}


def _context(resolved_json: str) -> MonteCarloContext:
    """The nominal plan, solved once per process (a pool's or a Dask worker's, which keeps
    this module between batches) and problem, the oldest dropped beyond :data:`CONTEXTS`."""
    context = _CONTEXTS.get(resolved_json)
    if context is None:
        problem = deorbit_burn_from_dict(json.loads(resolved_json), "resolved")
        context = _CONTEXTS[resolved_json] = MonteCarloContext(problem)
        while len(_CONTEXTS) > CONTEXTS:
            _CONTEXTS.pop(next(iter(_CONTEXTS)))
    return context


def store_deorbit_batch(
    resolved_problem: dict[str, Any],
    run_url: str,
    batch: int,
    runs: list[int],
    strategies: list[int],
    seed: int,
    on_run: Callable[[], None] | None = None,
) -> dict[str, Any]:
    """Simulate the runs (every strategy on the same draws) and store them as the batch
    ``batch`` (its first run) of the run at ``run_url`` (absolute); a small summary back
    (``batch``, ``runs``, ``rows``, ``failed``, ``wall_time_s``); ``on_run()`` after each
    run. The job of every batch (:class:`~ovtraj.store.monte_carlo.BatchJob`), wherever
    it runs; its inputs plain (``resolved_problem``: ``DeorbitBurnProblem.resolved()``)."""
    start = time.perf_counter()
    context = _context(json.dumps(resolved_problem, sort_keys=True))
    progress = None if on_run is None else lambda *_: on_run()
    frame = simulate_runs(context, runs, strategies, seed, progress)
    MonteCarloRun(Path(run_url)).write_batch(batch, frame)
    return {
        "batch": batch,
        "runs": len(runs),
        "rows": len(frame),
        "failed": int((~frame["ok"]).sum()),
        "wall_time_s": time.perf_counter() - start,
    }


class DeorbitMonteCarlo:
    """What a deorbit-burn Monte Carlo flies and where it is stored
    (:class:`~ovtraj.store.monte_carlo.MonteCarloStudy`): ``runs`` runs of ``problem``,
    each strategy of ``strategies`` on the same draws, in ``root``, ``batch_size`` runs a
    part; ``code`` the code version its id hashes. Fewer than one run or a batch of none
    raises ``ValueError``."""

    def __init__(
        self,
        problem: DeorbitBurnProblem,
        *,
        runs: int,
        strategies: list[int],
        seed: int,
        root: str | Path,
        code: str,
        batch_size: int,
    ) -> None:
        if runs < 1 or batch_size < 1:
            raise ValueError(
                f"runs and batch_size must be >= 1; got runs {runs}, batch_size {batch_size}"
            )
        self.problem, self.runs, self.strategies, self.seed = problem, runs, strategies, seed
        self.root, self.code, self.batch_size = root, code, batch_size
        self.resolved = problem.resolved()

    def open_run(self) -> MonteCarloRun:
        """The run of these inputs: created, or the stored one (same id) reopened."""
        return MonteCarloRun.create(
            self.root,
            resolved=self.resolved,
            runs=self.runs,
            strategies=self.strategies,
            seed=self.seed,
            code=self.code,
        )

    def job(self, run: MonteCarloRun) -> BatchJob:
        """A batch of ``run``: :func:`store_deorbit_batch` of the resolved problem."""
        return BatchJob(
            store_deorbit_batch,
            {
                "resolved_problem": self.resolved,
                "run_url": str(run.directory.resolve()),
                "strategies": self.strategies,
                "seed": self.seed,
            },
        )

    def finish(
        self, run: MonteCarloRun, simulated: int, failures: dict[int, str]
    ) -> dict[str, Any]:
        """The statistics, the published figures and the plots from the stored runs, as
        ``summary.json`` holds them (``status`` incomplete when a batch failed), the
        run's status; the report returned with ``failed_batches`` (a line for each)."""
        problem = self.problem
        frame = run.results()
        summary = monte_carlo_summary(frame)
        plots = plot_dispersions(frame, run.directory / "plots", problem.entry.radius_m)
        comparison = [
            row.as_dict()
            for row in published_comparison(problem, summary=summary)
            if row.figure.startswith("strategy")
        ]
        report = {
            "run_id": run.id,
            "directory": str(run.directory),
            "name": problem.name,
            "runs": self.runs,
            "stored_runs": len(run.done_runs()),
            "strategies": self.strategies,
            "seed": self.seed,
            "simulated_runs": simulated,
            "status": "incomplete" if failures else "complete",
            "statistics": [plain(row) for row in summary.to_dict(orient="records")],
            "published": comparison,
            "plots": [str(p) for p in plots],
        }
        run.write_summary(report)
        failed = [f"runs from {k}: {why}" for k, why in failures.items()]
        run.update_info(status=report["status"], failures=failed)
        return {**report, "failed_batches": failed}
