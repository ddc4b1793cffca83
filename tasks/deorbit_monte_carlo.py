"""Prefect task: one batch of deorbit-burn Monte Carlo runs, stored, cached on its inputs."""

from __future__ import annotations

import functools
import json
import time
from pathlib import Path
from typing import Any

from prefect import task
from prefect.cache_policies import INPUTS

from ovtraj.deorbit.burn.montecarlo import MonteCarloContext, simulate_runs
from ovtraj.deorbit.burn.problem import deorbit_burn_from_dict
from ovtraj.deorbit.burn.store import MonteCarloRun


@functools.lru_cache(maxsize=4)
def _context(resolved_json: str) -> MonteCarloContext:
    """The nominal plan, solved once per worker process (or thread pool) and problem."""
    return MonteCarloContext(deorbit_burn_from_dict(json.loads(resolved_json), "resolved"))


@task(name="deorbit-mc-batch", cache_policy=INPUTS, persist_result=True)
def deorbit_mc_batch_task(
    resolved_problem: dict[str, Any],
    run_dir: str,
    batch: int,
    runs: list[int],
    strategies: list[int],
    seed: int,
    code: str,
) -> dict[str, Any]:
    """Simulate the runs (every strategy on the same draws) and store them as one batch.

    The worker writes its own Parquet part (atomic, marker last), so the rows never travel
    back through Prefect; the task returns a small summary. The cache key hashes the inputs
    (problem, run directory, runs, strategies, seed, code version): the flow submits only
    runs the store does not hold, and resubmits with a refreshed cache a batch whose files
    went missing after a cached run.
    """
    start = time.perf_counter()
    context = _context(json.dumps(resolved_problem, sort_keys=True))
    frame = simulate_runs(context, runs, strategies, seed)
    MonteCarloRun(Path(run_dir)).write_batch(batch, frame)
    return {
        "batch": batch,
        "runs": len(runs),
        "rows": len(frame),
        "failed": int((~frame["ok"]).sum()),
        "wall_time_s": time.perf_counter() - start,
    }
