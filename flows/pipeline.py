"""Flow: the whole mission pipeline (``flows/pipeline.py:mission_flow``).

1. DoE: create (or reopen) the run and evaluate its batches as parallel tasks on the
   configured task runner (the DoE flow's machinery);
2. surrogates: fit and validate (a task cached on the training data's hash);
3. optimisation: NSGA-II on the surrogates (a task cached on the fit);
4. verification: evaluate front points with the real chain in child runs (the same
   batch tasks), refit and repeat until the error on the front is below tolerance or
   the budget of real evaluations is spent (``ovtraj.pipeline.run_pipeline``);
5. plan: the picked point of the verified front becomes the mission plan (JSON, YAML,
   plots), written in the pipeline's directory;
6. artifacts: validation table, parity plots, verified front, verification table, and the
   mission plan: its files and its plots, shown in the markdown (embedded PNGs, their
   paths as captions).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger
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
from flows.doe import ensure_launch_fit, evaluate_run, execution
from flows.optimize import front_table, surrogate_front
from flows.runners import task_runner
from flows.surrogate import fit_run_surrogates, publish_validation
from ovtraj.config import Scenario
from ovtraj.launch.fit import LaunchFit
from ovtraj.pipeline import (
    PipelineResult,
    PipelineSteps,
    fit_step,
    front_step,
    pipeline_doe_run,
    run_pipeline,
)
from ovtraj.pipeline.report import stop_explanation
from ovtraj.runs import Run, RunStore
from ovtraj.storage import location
from ovtraj.target_sources import load_scenario_with_target
from tasks.common import code_version
from tasks.pipeline import plan_task

LIMIT = "flows.mission_s of configs/orchestration.yaml"


def _steps(runner: Any, scenario: Scenario, fit: LaunchFit, deadline: float) -> PipelineSteps:
    """The pipeline's steps as tasks: batches on the runner, fit and front cached."""

    def fit_surrogates(
        run: Run,
        data: Any,
        scenario: Scenario,
        code: str,
        candidates: Any = None,
        views: bool = True,
    ) -> Any:
        publish_validation(fit_run_surrogates(scenario, run, candidates, views=views), run)
        # loads what the task stored
        return fit_step(run, data, scenario, code, candidates=candidates, views=views)

    def front(
        run: Run,
        fitted: Any,
        scenario: Scenario,
        code: str,
        views: bool = True,
        previous: Any = None,
    ) -> Any:
        warm = previous is not None and scenario.mission.optimize.warm_start_generations
        earlier = str(previous.directory) if warm else None
        surrogate_front(scenario, run, fitted.fit_id, views=views, previous_front=earlier)
        return front_step(run, fitted, scenario, code, views=views, previous=previous)

    def evaluate(run: Run) -> Run:
        return evaluate_run(scenario, run, fit, deadline=deadline, limit=LIMIT, runner=runner)

    return PipelineSteps(evaluate=evaluate, fit=fit_surrogates, front=front)


def mission_plan(
    scenario: Scenario,
    store: RunStore,
    result: PipelineResult,
    pick_index: int | None,
    weights: list[float] | None,
) -> dict[str, Any]:
    """The plan task; run again when its cached plan is no longer on disk."""
    task = prepared(plan_task)
    parameters = {
        "resolved_scenario": scenario.resolved(),
        "store_url": str(store.root),
        "pipeline_dir": str(result.directory),
        "pick_index": pick_index,
        "weights": None if weights is None else [float(w) for w in weights],
    }
    planned = task(**parameters)
    if not location(planned["json"]).is_file():
        planned = task.with_options(refresh_cache=True)(**parameters)
    return planned


@flow(
    name="mission",
    flow_run_name=run_name("mission"),
    timeout_seconds=FLOW_TIMEOUTS.mission_s,
    log_prints=True,
)
def mission_flow(
    config: str = "configs/scenario.yaml",
    samples: int | None = None,
    seed: int | None = None,
    from_run: str | None = None,
    store_root: str | None = None,
    pick_index: int | None = None,
    weights: list[float] | None = None,
    target: str | None = None,
    runner: str | None = None,
    dask_address: str | None = None,
) -> dict[str, Any]:
    """DoE -> surrogates -> NSGA-II -> verification and infill -> plan; returns the paths.

    ``target``: a TLE/OMM file or URL that replaces the scenario's target: the re-plan
    from an updated element set (a changed one gives a new run and launch fit, the same
    one reuses every stored result). ``runner`` (``serial | threads | processes |
    dask``) overrides ``mission.doe``'s for the DoE and infill batches; ``dask_address``:
    the ``dask`` runner's scheduler (else ``OVTRAJ_DASK_ADDRESS``, else a local cluster).
    """
    deadline = time.monotonic() + FLOW_TIMEOUTS.mission_s
    logger = get_run_logger()
    prune_expired_results()
    scenario = load_scenario_with_target(Path(config), target)
    if scenario.mission is None:
        raise ValueError(f"{config}: the scenario has no mission section")
    choice = execution(scenario.mission.doe, runner, dask_address)
    fit = ensure_launch_fit(config, scenario, target)
    store = RunStore.for_scenario(scenario, config, store_root)
    code = code_version()
    doe_run, scenario = pipeline_doe_run(
        scenario,
        store,
        code,
        samples=samples,
        seed=seed,
        from_run=from_run,
        config=config if from_run else None,
    )
    labels = run_tags("mission", scenario.name, doe_run.id)
    label_flow_run(f"mission {scenario.name} {doe_run.id}", labels)
    logger.info("DoE run %s: %d samples, runner %s", doe_run.id, len(doe_run.samples()), choice[0])
    # The flow run carries the tags; its task runs their own (none on the batches: see
    # tasks.common.BATCH_TAGS).
    with task_runner(*choice) as runner_:
        steps = _steps(runner_, scenario, fit, deadline)
        steps.evaluate(doe_run)
        result = run_pipeline(
            scenario, doe_run, store=store, code=code, steps=steps, progress=logger.info
        )
    planned = mission_plan(scenario, store, result, pick_index, weights)
    verdict = stop_explanation(result.summary, scenario.mission.verify)
    logger.info(verdict)
    logger.info("picked %s; report %s", planned.get("pick"), planned.get("report"))
    _publish(result, planned, verdict)
    return {
        "doe_run": result.doe_run,
        "final_run": result.final_run,
        "pipeline_id": result.pipeline_id,
        "front": str(result.front_path),
        "front_points": len(result.front),
        "hypervolume": result.summary["hypervolume"],
        "stop_reason": result.summary["stop_reason"],
        "real_evaluations": result.summary["real_evaluations"],
        "plan_json": planned["json"],
        "plan_yaml": planned["yaml"],
        "report": planned.get("report"),
        "converged": result.summary["converged"],
    }


def _publish(result: PipelineResult, planned: dict[str, Any], verdict: str = "") -> None:
    create_table_artifact(
        key="verified-front",
        table=front_table(result.front),
        description=f"verified front (real values) of pipeline {result.pipeline_id}, "
        f"hypervolume {result.summary['hypervolume']:.4f}",
    )
    if len(result.verification):
        create_table_artifact(
            key="front-verification",
            table=front_table(result.verification),
            description="front points evaluated with the real chain: predicted, real, errors",
        )
    plots = sorted(str(p) for p in result.directory.glob("*.png")) + planned["plots"]
    create_markdown_artifact(
        key="mission-plan",
        markdown="\n\n".join(
            [
                *([f"**{verdict}**"] if verdict else []),
                *([f"Picked {planned['pick']}."] if planned.get("pick") else []),
                f"- plan: `{planned['json']}`\n- plan: `{planned['yaml']}`"
                + (f"\n- report: `{planned['report']}`" if planned.get("report") else ""),
                *embedded_plots(plots),
            ]
        ),
        description=f"mission plan of pipeline {result.pipeline_id}",
    )


if __name__ == "__main__":
    print(mission_flow())
