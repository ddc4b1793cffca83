"""Prefect task: one batch of mission evaluations, stored, cached on its inputs and code."""

from __future__ import annotations

import functools
import json
import time
from pathlib import Path
from typing import Any

from prefect import task
from prefect.cache_policies import INPUTS

from ovtraj.config import scenario_from_dict
from ovtraj.launch.fit import find_launch_fit
from ovtraj.mission import MissionContext
from ovtraj.runs import execute
from ovtraj.runs.store import Run


@functools.lru_cache(maxsize=4)
def _context(resolved_json: str) -> MissionContext:
    """The scenario's shared context, built once per worker process and scenario."""
    scenario = scenario_from_dict(json.loads(resolved_json))
    fit = find_launch_fit(scenario)
    if fit is None:
        raise RuntimeError("no launch fit for this scenario: run flows/launch_fit.py first")
    return MissionContext(scenario, fit)


@task(name="mission-batch", cache_policy=INPUTS, persist_result=True)
def mission_batch_task(
    resolved_scenario: dict[str, Any],
    run_dir: str,
    batch_index: int,
    batch: list[dict[str, float]],
    code: str,
) -> dict[str, Any]:
    """Evaluate the mission chain for each sample row and store the batch in the run.

    The worker writes the batch itself (atomic parts, marker last), so the records
    never travel back through Prefect; the task returns a small summary. The cache
    key is the hash of the inputs (scenario, run, batch, samples, code version):
    the flow submits only batches the run does not hold, and resubmits with a
    refreshed cache a batch whose files went missing after a cached run.
    """
    import pandas as pd

    start = time.perf_counter()
    context = _context(json.dumps(resolved_scenario, sort_keys=True, default=str))
    scenario = context.scenario
    frame = pd.DataFrame(batch)
    run = Run(Path(run_dir))
    stored = execute.store_batch(
        run, scenario, context, batch_index, frame, wait_s=scenario.mission.doe.claim_wait_s
    )
    totals = run.batch_totals(batch_index)
    return {
        "batch": batch_index,
        "samples": len(totals),
        "feasible": int(totals["feasible"].sum()),
        "stored_here": bool(stored),
        "wall_time_s": time.perf_counter() - start,
    }
