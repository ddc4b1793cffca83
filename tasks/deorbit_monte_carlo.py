"""Prefect task: one batch of deorbit-burn Monte Carlo runs, stored, cached on its inputs."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from prefect import task

from ovtraj.studies.deorbit_burn.montecarlo import MonteCarloContext, simulate_runs
from ovtraj.studies.deorbit_burn.problem import deorbit_burn_from_dict
from ovtraj.studies.deorbit_burn.store import MonteCarloRun
from tasks.common import TIMEOUTS, cached, parameter, run_label
from tasks.process_cache import process_cache, remember

# Nominal plans kept per process: a few problems at once.
CONTEXTS = 4


def _context(resolved_json: str) -> MonteCarloContext:
    """The nominal plan, solved once per worker process (or thread pool) and problem."""
    cache = process_cache("deorbit-mc-context")
    if resolved_json not in cache:
        problem = deorbit_burn_from_dict(json.loads(resolved_json), "resolved")
        remember(cache, resolved_json, MonteCarloContext(problem), CONTEXTS)
    return cache[resolved_json]


def _name() -> str:
    runs = parameter("runs") or ["?"]
    return f"{run_label(parameter('run_url'))}/runs-{runs[0]}-{runs[-1]}"


@task(
    name="deorbit-mc-batch",
    task_run_name=_name,  # no tags: see tasks.common.BATCH_TAGS
    timeout_seconds=TIMEOUTS.deorbit_mc_batch_per_run_s,  # the flow scales it by the batch
    **cached(),
)
def deorbit_mc_batch_task(
    resolved_problem: dict[str, Any],
    run_url: str,
    batch: int,
    runs: list[int],
    strategies: list[int],
    seed: int,
) -> dict[str, Any]:
    """Simulate the runs (every strategy on the same draws) and store them as one batch.

    The worker writes its own Parquet part (atomic, marker last) into the run at
    ``run_url`` (absolute), so the rows never travel back through Prefect; the task
    returns a small summary. The cache key hashes the inputs (problem, run, runs,
    strategies, seed) and the code version: the flow submits only runs the store does
    not hold, and runs again with a refreshed cache a batch whose files went missing
    after a cached run.
    """
    start = time.perf_counter()
    context = _context(json.dumps(resolved_problem, sort_keys=True))
    frame = simulate_runs(context, runs, strategies, seed)
    MonteCarloRun(Path(run_url)).write_batch(batch, frame)
    return {
        "batch": batch,
        "runs": len(runs),
        "rows": len(frame),
        "failed": int((~frame["ok"]).sum()),
        "wall_time_s": time.perf_counter() - start,
    }
