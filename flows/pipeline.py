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
6. artifacts: validation table, verified front, verification table, plot paths.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger, task
from prefect.artifacts import create_markdown_artifact, create_table_artifact
from prefect.cache_policies import NO_CACHE

from flows.doe import ensure_launch_fit, evaluate_run, task_runner
from flows.optimize import front_table
from flows.surrogate import fit_run_surrogates, publish_validation
from ovtraj.config import Scenario
from ovtraj.launch.fit import find_launch_fit
from ovtraj.pipeline import (
    Pick,
    PipelineResult,
    PipelineSteps,
    fit_step,
    front_step,
    pipeline_doe_run,
    run_pipeline,
)
from ovtraj.pipeline.planning import write_mission_plan
from ovtraj.runs import Run, RunStore
from ovtraj.target_sources import load_scenario_with_target
from ovtraj.version import code_version
from tasks.pipeline import surrogate_front_task


@task(name="mission-plan", retries=1, cache_policy=NO_CACHE)
def plan_task(
    scenario: Scenario, store_root: str, result: PipelineResult, pick: Pick
) -> dict[str, Any]:
    """The mission plan of the picked front point (one chain evaluation)."""
    fit = find_launch_fit(scenario)
    planned = write_mission_plan(scenario, fit, RunStore(store_root), result, pick)
    return {
        "json": str(planned["json"]),
        "yaml": str(planned["yaml"]),
        "plots": [str(p) for p in planned["plots"]],
    }


def _steps(runner: Any, scenario: Scenario, code: str) -> PipelineSteps:
    """The pipeline's steps as tasks: batches on the runner, fit and front cached."""

    def fit(run: Run, data: Any, scenario: Scenario, code: str) -> Any:
        publish_validation(fit_run_surrogates(scenario, run, code), run)
        return fit_step(run, data, scenario, code)  # loads what the task stored

    def front(run: Run, fitted: Any, scenario: Scenario, code: str) -> Any:
        surrogate_front_task(scenario.resolved(), str(run.directory), fitted.fit_id, code)
        return front_step(run, fitted, scenario, code)

    def evaluate(run: Run) -> Run:
        return evaluate_run(runner, scenario, run, code)

    return PipelineSteps(evaluate=evaluate, fit=fit, front=front)


@flow(name="mission", log_prints=True)
def mission_flow(
    config: str = "configs/scenario.yaml",
    samples: int | None = None,
    seed: int | None = None,
    from_run: str | None = None,
    store_root: str | None = None,
    pick_index: int | None = None,
    weights: list[float] | None = None,
    target: str | None = None,
) -> dict[str, Any]:
    """DoE -> surrogates -> NSGA-II -> verification and infill -> plan; returns the paths.

    ``target``: a TLE/OMM file or URL that replaces the scenario's target: the re-plan
    from an updated element set (a changed one gives a new run and launch fit, the same
    one reuses every stored result).
    """
    logger = get_run_logger()
    scenario = load_scenario_with_target(Path(config), target)
    if scenario.mission is None:
        raise ValueError(f"{config}: the scenario has no mission section")
    ensure_launch_fit(config, scenario, target)
    settings = scenario.mission.doe
    store = RunStore.for_scenario(scenario, config, store_root)
    root = str(store.root)
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
    logger.info("DoE run %s: %d samples", doe_run.id, len(doe_run.samples()))
    with task_runner(settings) as runner:
        steps = _steps(runner, scenario, code)
        steps.evaluate(doe_run)
        result = run_pipeline(
            scenario, doe_run, store=store, code=code, steps=steps, progress=logger.info
        )
    pick = Pick(index=pick_index, weights=None if weights is None else tuple(weights))
    planned = plan_task(scenario, root, result, pick)
    _publish(result, planned)
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
    }


def _publish(result: PipelineResult, planned: dict[str, Any]) -> None:
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
        markdown="\n".join(
            [f"- plan: `{planned['json']}`", f"- plan: `{planned['yaml']}`"]
            + [f"- plot: `{p}`" for p in plots]
        ),
        description=f"mission plan of pipeline {result.pipeline_id}",
    )


if __name__ == "__main__":
    print(mission_flow())
