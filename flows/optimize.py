"""Flow: NSGA-II on a stored run's surrogates (``flows/optimize.py:optimize_flow``).

1. fit (or reuse) the surrogates of the run (the surrogate flow's task);
2. run NSGA-II on them: a task cached on the fit and the settings;
3. publish the front as a table artifact; return its summary.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow
from prefect.artifacts import create_table_artifact

from flows.surrogate import fit_run_surrogates, publish_validation
from ovtraj.pipeline import run_scenario
from ovtraj.pipeline.steps import front_frame
from ovtraj.runs import RunStore
from ovtraj.version import code_version
from tasks.pipeline import surrogate_front_task


def front_table(frame: Any) -> list[dict[str, Any]]:
    return [
        {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}
        for row in frame.to_dict(orient="records")
    ]


@flow(name="optimize", log_prints=True)
def optimize_flow(
    run_id: str, config: str | None = None, store_root: str | None = None
) -> dict[str, Any]:
    """Surrogate front of a stored run (no simulation); returns its summary."""
    run = RunStore(store_root).run(run_id)
    scenario = run_scenario(run, config)
    code = code_version()
    fitted = fit_run_surrogates(scenario, run, code)
    publish_validation(fitted, run)
    front = surrogate_front_task(scenario.resolved(), str(run.directory), fitted["fit_id"], code)
    create_table_artifact(
        key="surrogate-front",
        table=front_table(front_frame(Path(front["directory"]))),
        description=f"NSGA-II front on the surrogates of run {run.id} (predicted values), "
        f"hypervolume {front['hypervolume']:.4f}",
    )
    return front | {"fit_id": fitted["fit_id"]}


if __name__ == "__main__":
    import sys

    print(optimize_flow(sys.argv[1]))
