"""Flow: surrogates of a stored run (``flows/surrogate.py:surrogate_flow``).

1. open the run and read its evaluated samples (no simulation);
2. fit and validate the surrogates: a task cached on the training data's hash, the
   settings and the code version (the run store keeps the fitted set too);
3. publish the validation table and the parity plots' paths as artifacts.
"""

from __future__ import annotations

from typing import Any

from prefect import flow
from prefect.artifacts import create_markdown_artifact, create_table_artifact

from ovtraj.config import Scenario
from ovtraj.pipeline import run_scenario, training_data
from ovtraj.runs import Run, RunStore
from ovtraj.surrogate import training_data_hash
from ovtraj.version import code_version
from tasks.pipeline import fit_surrogates_task


def fit_run_surrogates(scenario: Scenario, run: Run, code: str) -> dict[str, Any]:
    data = training_data(run)
    data_hash = training_data_hash(data.designs, data.outputs, data.feasible)
    return fit_surrogates_task(scenario.resolved(), str(run.directory), data_hash, code)


def publish_validation(summary: dict[str, Any], run: Run) -> None:
    create_table_artifact(
        key="surrogate-validation",
        table=summary["validation"],
        description=f"surrogate candidates of run {run.id} (fit {summary['fit_id']}): k-fold CV "
        "and held-out metrics; `selected` marks the model used",
    )
    plots = sorted(p for p in __import__("pathlib").Path(summary["directory"]).glob("*.png"))
    create_markdown_artifact(
        key="surrogate-parity-plots",
        markdown="\n".join(f"- `{p}`" for p in plots) or "no plots",
        description=f"parity plots of fit {summary['fit_id']}",
    )


@flow(name="surrogate", log_prints=True)
def surrogate_flow(
    run_id: str, config: str | None = None, store_root: str | None = None
) -> dict[str, Any]:
    """Fit and validate the surrogates of a stored run; returns the fit's summary."""
    run = RunStore(store_root).run(run_id)
    scenario = run_scenario(run, config)
    summary = fit_run_surrogates(scenario, run, code_version())
    publish_validation(summary, run)
    return summary


if __name__ == "__main__":
    import sys

    print(surrogate_flow(sys.argv[1]))
