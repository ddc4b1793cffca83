"""Prefect tasks of the surrogate pipeline: fit, front, plan (thin wrappers).

Each task stores its outputs in the run (``ovtraj.pipeline.steps``) and returns a
small summary. The fit is cached on the training data's hash with the settings and
the code version; the front on the fit id; both steps also reuse what the run store
holds, so a cache miss costs a load, not a refit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import task
from prefect.cache_policies import INPUTS

from ovtraj.config import scenario_from_dict
from ovtraj.pipeline import fit_step, front_step, training_data
from ovtraj.runs.store import Run


def _validation_rows(outcome: Any) -> list[dict[str, Any]]:
    frame = outcome.surrogates.validation
    rows = frame.astype(object).where(frame.notna(), None).to_dict(orient="records")
    return [{k: (round(v, 6) if isinstance(v, float) else v) for k, v in r.items()} for r in rows]


@task(name="fit-surrogates", cache_policy=INPUTS, persist_result=True, retries=1)
def fit_surrogates_task(
    resolved_scenario: dict[str, Any], run_dir: str, data_hash: str, code: str
) -> dict[str, Any]:
    """Fit (or load) the run's surrogates; ``data_hash`` keys the cache on the samples."""
    run = Run(Path(run_dir))
    scenario = scenario_from_dict(resolved_scenario)
    outcome = fit_step(run, training_data(run), scenario, code)
    return {
        "fit_id": outcome.fit_id,
        "directory": str(outcome.directory),
        "data_hash": data_hash,
        "selected": dict(outcome.surrogates.selected),
        "validation": _validation_rows(outcome),
    }


@task(name="surrogate-front", cache_policy=INPUTS, persist_result=True, retries=1)
def surrogate_front_task(
    resolved_scenario: dict[str, Any], run_dir: str, fit_id: str, code: str
) -> dict[str, Any]:
    """NSGA-II on the fitted surrogates (loaded from the run)."""
    run = Run(Path(run_dir))
    scenario = scenario_from_dict(resolved_scenario)
    fit = fit_step(run, training_data(run), scenario, code)
    if fit.fit_id != fit_id:
        raise RuntimeError(f"run {run.id}: surrogates {fit_id} expected, found {fit.fit_id}")
    outcome = front_step(run, fit, scenario, code)
    return {
        "front_id": outcome.front_id,
        "directory": str(outcome.directory),
        "points": len(outcome.front),
        "hypervolume": outcome.front.hypervolume,
    }
