"""Prefect tasks of the surrogate and optimize flows: fit, front (thin wrappers).

Each task stores its outputs in the run (``ovtraj.pipeline.steps``) and returns a
small summary. The fit is cached on the training data's hash with the settings and
the code version; the front on the fit id; both steps also reuse what the run store
holds, so a cache miss costs a load, not a refit. The run is given by its absolute URL
(``Run.url``).
"""

from __future__ import annotations

from typing import Any

from prefect import task

from ovtraj.config import scenario_from_dict
from ovtraj.pipeline import fit_step, front_step, training_data
from ovtraj.pipeline.steps import fitting_pool
from ovtraj.runs.store import Run
from tasks.common import TIMEOUTS, cached, code_version, parameter, run_label


def _validation_rows(outcome: Any) -> list[dict[str, Any]]:
    frame = outcome.surrogates.validation
    rows = frame.astype(object).where(frame.notna(), None).to_dict(orient="records")
    return [{k: (round(v, 6) if isinstance(v, float) else v) for k, v in r.items()} for r in rows]


def _fit_name() -> str:
    return f"{run_label(parameter('run_url'))}/surrogates"


def _front_name() -> str:
    return f"{run_label(parameter('run_url'))}/front-of-{parameter('fit_id')}"


@task(
    name="fit-surrogates",
    task_run_name=_fit_name,
    tags=["ovtraj", "surrogate"],
    retries=1,
    timeout_seconds=TIMEOUTS.fit_surrogates_s,
    **cached(),
)
def fit_surrogates_task(
    resolved_scenario: dict[str, Any],
    run_url: str,
    data_hash: str,
    candidates: dict[str, str] | None = None,
    views: bool = True,
) -> dict[str, Any]:
    """Fit (or load) the run's surrogates; ``data_hash`` keys the cache on the samples.

    ``candidates``: the models an earlier fit of the pipeline selected, refitted unchanged;
    ``views``: with its parity plots (a pipeline's rounds: without).
    """
    run = Run.open(run_url)
    scenario = scenario_from_dict(resolved_scenario)
    code = code_version()
    data = training_data(run)
    with fitting_pool(scenario, len(data)) as pool:
        outcome = fit_step(
            run, data, scenario, code, candidates=candidates, views=views, executor=pool
        )
    return {
        "fit_id": outcome.fit_id,
        "directory": str(outcome.directory),
        "data_hash": data_hash,
        "selected": dict(outcome.surrogates.selected),
        "validation": _validation_rows(outcome),
    }


@task(
    name="surrogate-front",
    task_run_name=_front_name,
    tags=["ovtraj", "optimize"],
    retries=1,
    timeout_seconds=TIMEOUTS.surrogate_front_s,
    **cached(),
)
def surrogate_front_task(
    resolved_scenario: dict[str, Any],
    run_url: str,
    fit_id: str,
    views: bool = True,
) -> dict[str, Any]:
    """NSGA-II on the fitted surrogates (loaded from the run); ``views``: with its plot."""
    run = Run.open(run_url)
    scenario = scenario_from_dict(resolved_scenario)
    code = code_version()
    fit = fit_step(run, training_data(run), scenario, code, views=views)
    if fit.fit_id != fit_id:
        raise RuntimeError(f"run {run.id}: surrogates {fit_id} expected, found {fit.fit_id}")
    outcome = front_step(run, fit, scenario, code, views=views)
    return {
        "front_id": outcome.front_id,
        "directory": str(outcome.directory),
        "points": len(outcome.front),
        "hypervolume": outcome.front.hypervolume,
    }
