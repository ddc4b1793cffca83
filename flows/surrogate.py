"""Flow: surrogates of a stored run (``flows/surrogate.py:surrogate_flow``).

1. open the run and read its evaluated samples (no simulation);
2. fit and validate the surrogates: a task cached on the training data's hash, the
   settings and the code version (the run store keeps the fitted set too, and a cached
   result whose fit is gone from the run is fitted again);
3. publish the validation table and the parity plots as artifacts: the plots themselves,
   embedded in the markdown (:func:`embedded_plots`), their paths as captions.
"""

from __future__ import annotations

from typing import Any

from prefect import flow, tags
from prefect.artifacts import create_markdown_artifact, create_table_artifact

from flows.common import (
    FLOW_TIMEOUTS,
    embedded_plots,
    label_flow_run,
    prepared,
    prune_expired_results,
    run_name,
    run_tags,
)
from ovtraj.config import Scenario
from ovtraj.pipeline import run_scenario, training_data
from ovtraj.pipeline.steps import MARKER
from ovtraj.runs import Run, RunStore
from ovtraj.store.backends import location
from ovtraj.surrogate import training_data_hash
from tasks.pipeline import fit_surrogates_task


def stored_product(summary: dict[str, Any]) -> bool:
    """Whether the product a cached task result points at is still in the run (its
    ``meta.json``, written last, is there)."""
    return (location(summary["directory"]) / MARKER).is_file()


def call_stored(task: Any, **parameters: Any) -> dict[str, Any]:
    """Call a task that stores a product in the run; when its cached result points at a
    product no longer stored, call it again with a refreshed cache (the store decides)."""
    summary = task(**parameters)
    if not stored_product(summary):
        summary = task.with_options(refresh_cache=True)(**parameters)
    return summary


def fit_run_surrogates(
    scenario: Scenario,
    run: Run,
    candidates: dict[str, str] | None = None,
    *,
    views: bool = True,
) -> dict[str, Any]:
    data = training_data(run)
    data_hash = training_data_hash(data.designs, data.outputs, data.feasible)
    return call_stored(
        prepared(fit_surrogates_task),
        resolved_scenario=scenario.resolved(),
        run_url=run.url,
        data_hash=data_hash,
        candidates=candidates,
        views=views,
    )


def publish_validation(summary: dict[str, Any], run: Run) -> None:
    create_table_artifact(
        key="surrogate-validation",
        table=summary["validation"],
        description=f"surrogate candidates of run {run.id} (fit {summary['fit_id']}): k-fold CV "
        "and held-out metrics; `selected` marks the model used",
    )
    plots = sorted(str(p) for p in location(summary["directory"]).glob("*.png"))
    if not plots:
        return  # a pipeline round's fit: its views are drawn once, with the pipeline's result
    create_markdown_artifact(
        key="surrogate-parity-plots",
        markdown="\n\n".join(embedded_plots(plots)) or "no plots",
        description=f"parity plots of fit {summary['fit_id']}",
    )


@flow(
    name="surrogate",
    flow_run_name=run_name("surrogate", "run_id"),
    timeout_seconds=FLOW_TIMEOUTS.surrogate_s,
    log_prints=True,
)
def surrogate_flow(
    run_id: str, config: str | None = None, store: str | None = None
) -> dict[str, Any]:
    """Fit and validate the surrogates of a stored run; returns the fit's summary."""
    prune_expired_results()
    run = RunStore(store).run(run_id)
    scenario = run_scenario(run, config)
    labels = run_tags("surrogate", scenario.name, run.id)
    label_flow_run(f"surrogate {scenario.name} {run.id}", labels)
    with tags(*labels):
        summary = fit_run_surrogates(scenario, run)
    publish_validation(summary, run)
    return summary


if __name__ == "__main__":
    import sys

    print(surrogate_flow(sys.argv[1]))
