"""Flow: NSGA-II on a stored run's surrogates (``flows/optimize.py:optimize_flow``).

1. fit (or reuse) the surrogates of the run (the surrogate flow's task);
2. run NSGA-II on them: a task cached on the fit, the settings and the code version;
3. publish the front as a table artifact; return its summary.
"""

from __future__ import annotations

from typing import Any

from prefect import flow, tags
from prefect.artifacts import create_table_artifact

from flows.common import (
    FLOW_TIMEOUTS,
    label_flow_run,
    prepared,
    prune_expired_results,
    run_name,
    run_tags,
)
from flows.surrogate import call_stored, fit_run_surrogates, publish_validation
from ovtraj.config import Scenario
from ovtraj.pipeline import run_scenario
from ovtraj.pipeline.steps import front_frame
from ovtraj.runs import Run, RunStore
from ovtraj.store.backends import location
from tasks.pipeline import surrogate_front_task


def front_table(frame: Any) -> list[dict[str, Any]]:
    return [
        {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}
        for row in frame.to_dict(orient="records")
    ]


def surrogate_front(
    scenario: Scenario,
    run: Run,
    fit_id: str,
    *,
    views: bool = True,
) -> dict[str, Any]:
    """The front task on the run's fit (run again when its cached front is not stored)."""
    return call_stored(
        prepared(surrogate_front_task),
        resolved_scenario=scenario.resolved(),
        run_url=run.url,
        fit_id=fit_id,
        views=views,
    )


@flow(
    name="optimize",
    flow_run_name=run_name("optimize", "run_id"),
    timeout_seconds=FLOW_TIMEOUTS.optimize_s,
    log_prints=True,
)
def optimize_flow(
    run_id: str, config: str | None = None, store: str | None = None
) -> dict[str, Any]:
    """Surrogate front of a stored run (no simulation); returns its summary."""
    prune_expired_results()
    run = RunStore(store).run(run_id)
    scenario = run_scenario(run, config)
    labels = run_tags("optimize", scenario.name, run.id)
    label_flow_run(f"optimize {scenario.name} {run.id}", labels)
    with tags(*labels):
        fitted = fit_run_surrogates(scenario, run)
        publish_validation(fitted, run)
        front = surrogate_front(scenario, run, fitted["fit_id"])
    create_table_artifact(
        key="surrogate-front",
        table=front_table(front_frame(location(front["directory"]))),
        description=f"NSGA-II front on the surrogates of run {run.id} (predicted values), "
        f"hypervolume {front['hypervolume']:.4f}",
    )
    return front | {"fit_id": fitted["fit_id"]}


if __name__ == "__main__":
    import sys

    print(optimize_flow(sys.argv[1]))
