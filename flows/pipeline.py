"""Flow: the whole mission pipeline (``flows/pipeline.py:mission_flow``).

The library's one preparation (:func:`ovtraj.pipeline.prepare.prepare_pipeline`) and one
driver (:func:`ovtraj.pipeline.drive.drive_pipeline`), as ``ovtraj pipeline``'s, with the
batches as cached Prefect tasks on the flow's task runner (:class:`flows.doe.TaskBatches`)
and a launch fit not stored yet solved by the launch-fit flow as a subflow (or refused:
configs/orchestration.yaml ``preparation.launch_fit``):

1. DoE: create (or reopen) the run and evaluate its batches as parallel tasks;
2. the loop: surrogates, NSGA-II on them, verification of front points with the real
   chain in child runs (the same batch tasks) and infill, until the error on the front
   is below tolerance or the budget of real evaluations is spent;
3. plan: the picked point of the verified front becomes the mission plan (JSON, YAML,
   plots, report), written in the pipeline's directory;
4. artifacts: the last fit's validation table, the verified front, the verification
   table, and the mission plan: its files and its plots, shown in the markdown (embedded
   PNGs, their paths as captions);
5. the state: Completed when the verification loop converged, else Failed with the verdict
   as its message (``ovtraj pipeline``'s exit 1; ``require_converged=False``: Completed,
   named "Not converged"), everything stored and published first (``flows/verdict.py``).

Fits and fronts are stored in the run and reused by content (a second flow run loads
them); only the batches are tasks, cached on their inputs.
"""

from __future__ import annotations

import time
from typing import Any

from prefect import flow, get_run_logger
from prefect.artifacts import create_markdown_artifact, create_table_artifact
from prefect.runtime import deployment

from flows.common import (
    FLOW_TIMEOUTS,
    embedded_plots,
    prune_expired_results,
    run_name,
)
from flows.doe import TaskBatches
from flows.launch_fit import launch_fit_subflow
from flows.optimize import front_table
from flows.surrogate import publish_validation
from flows.verdict import run_from_command_line, verdict_state
from ovtraj.pipeline import PipelineResult
from ovtraj.pipeline.drive import PipelineOutcome, drive_pipeline
from ovtraj.pipeline.pick import checked_pick
from ovtraj.pipeline.planning import last_surrogates
from ovtraj.pipeline.prepare import PipelineInputs, prepare_pipeline
from ovtraj.plots.history import history_plot
from ovtraj.runs import RunStore
from ovtraj.store.records import plain
from ovtraj.tracking.catalog import refresh, set_tags
from ovtraj.tracking.catalog_rows import plan_file, plan_id, plan_values
from ovtraj.tracking.history import history, previous_plan
from ovtraj.tracking.keys import history_key
from tasks.common import code_version

LIMIT = "flows.mission_s of configs/orchestration.yaml"


@flow(
    name="mission",
    flow_run_name=run_name("mission"),
    timeout_seconds=FLOW_TIMEOUTS.mission_s,
    log_prints=True,
)
def mission_flow(
    config: str | None = None,
    samples: int | None = None,
    seed: int | None = None,
    run: str | None = None,
    refit: bool = False,
    pick: int | None = None,
    weights: list[float] | None = None,
    max_time_h: float | None = None,
    max_dv_mps: float | None = None,
    min_payload_kg: float | None = None,
    store: str | None = None,
    target: str | None = None,
    runner: str | None = None,
    workers: int | None = None,
    dask_address: str | None = None,
    require_converged: bool = True,
) -> Any:
    """DoE -> surrogates -> NSGA-II -> verification and infill -> plan; returns the paths,
    the pick, whether the verification loop converged and its verdict.

    The parameters are ``ovtraj pipeline``'s options by the same names (``--run`` is
    ``run``, ``--max-dv-mps`` ``max_dv_mps``, ...) and build the same request of the same
    driver (tests/test_pipeline_flow.py). ``config``: the scenario file (default: the
    shipped scenario, as ``ovtraj``'s). ``run``: start from this stored DoE run (no new
    DoE). ``refit``: refit and re-optimise even when stored. ``pick``: the verified
    front's index to plan (``ovtraj front RUN``), else the best by ``weights`` (T, dV, M
    on the normalised objectives; equal by default) among the points within
    ``max_time_h`` [h], ``max_dv_mps`` [m/s] and ``min_payload_kg`` [kg]. ``store``: the
    run store (else ``mission.doe.store``, else the workspace's). ``target``: a TLE/OMM
    file or URL that replaces the scenario's target: the re-plan from an updated element
    set (a changed one gives a new run and launch fit, the same one reuses every stored
    result). ``runner`` (``serial | threads | processes | dask``) overrides
    ``mission.doe``'s for the DoE and infill batches; ``workers``: the pool's size (else
    ``mission.doe.workers``; the batches are cut by the config's, so the stored run is
    the same); ``dask_address``: the ``dask`` runner's scheduler (else
    ``OVTRAJ_DASK_ADDRESS``, else a local cluster).
    ``require_converged`` (the command's ``--allow-unconverged`` turned around): a loop
    that did not converge ends the flow run Failed, the verdict as its message (False:
    Completed, named "Not converged"); the result is stored and published either way
    (``flows/verdict.py``).
    """
    deadline = time.monotonic() + FLOW_TIMEOUTS.mission_s
    prune_expired_results()
    chosen = checked_pick(pick, weights, max_time_h, max_dv_mps, min_payload_kg)
    inputs = prepare_pipeline(
        config,
        pick=chosen,
        fit_missing=launch_fit_subflow(config, target),
        samples=samples,
        seed=seed,
        from_run=run,
        refit=refit,
        store=store,
        target=target,
        runner=runner,
        workers=workers,
        dask_address=dask_address,
    )
    outcome = _drive(inputs, deadline)
    _publish_outcome(inputs.store, outcome)
    return verdict_state(
        _summary(outcome),
        outcome.verdict,
        converged=outcome.converged,
        require_converged=require_converged,
    )


def _drive(inputs: PipelineInputs, deadline: float) -> PipelineOutcome:
    """The library's driver (as ``ovtraj pipeline``'s) with each batch a cached task on
    the flow's task runner of ``inputs.choice``, stopped at ``deadline`` (monotonic)."""
    logger = get_run_logger()
    logger.info("runner %s", inputs.choice.runner)
    # The flow run is named and tagged after the DoE run, the first run it evaluates.
    batches = TaskBatches(
        inputs.scenario,
        inputs.launch_fit,
        inputs.choice,
        deadline=deadline,
        limit=LIMIT,
        kind="mission",
    )
    return drive_pipeline(
        inputs.scenario,
        inputs.launch_fit,
        inputs.store,
        code_version(),
        batches,
        inputs.request,
        progress=logger.info,
    )


def _publish_outcome(store: RunStore, outcome: PipelineOutcome) -> None:
    """The verdict and the pick in the log; the verified front, the plan, the last fit's
    validation and the target's re-plan history as artifacts."""
    logger = get_run_logger()
    logger.info(outcome.verdict)
    logger.info("picked %s; report %s", outcome.planned.get("pick"), outcome.planned.get("report"))
    _publish(outcome.result, outcome.planned, outcome.verdict)
    _publish_last_fit(store, outcome)
    _publish_history(store, outcome.planned)


def _summary(outcome: PipelineOutcome) -> dict[str, Any]:
    """What the flow returns: the runs, the verified front, the plan and the verdict."""
    result, planned = outcome.result, outcome.planned
    return {
        "doe_run": result.doe_run,
        "final_run": result.final_run,
        "pipeline_id": result.pipeline_id,
        "front": str(result.front_path),
        "front_points": len(result.front),
        "hypervolume": result.summary["hypervolume"],
        "stop_reason": result.summary["stop_reason"],
        "real_evaluations": result.summary["real_evaluations"],
        "plan_json": str(planned["json"]),
        "plan_yaml": str(planned["yaml"]),
        "report": str(planned["report"]),
        "pick": planned["pick"],
        "converged": outcome.converged,
        "verdict": outcome.verdict,
    }


def _publish_history(store: RunStore, planned: dict[str, Any]) -> None:
    """The target's re-plan history (``ovtraj history``) as a table artifact and its trend
    plot as a markdown artifact, both under a stable key per target (``history-<target>``,
    ``history-<target>-plot``): the UI lists every re-plan's version of them, and each
    version names this plan and the previous one. A run from a deployment tags its
    pipeline result ``deployment=<name>`` (``ovtraj history --deployment``)."""
    plan = planned["plan"].to_dict()
    values = plan_values(plan)
    if deployment.name:
        set_tags(store.root, values["pipeline_id"], {"deployment": str(deployment.name)})
    catalog = refresh(store.root)
    rows = history(catalog, target=values["target"])
    key = history_key(values["target"] or "target")
    plot = history_plot(
        rows, store.root / "catalog" / "history" / f"{key}.png", f"re-plans of {values['target']}"
    )
    table = plain(rows.drop(columns=["source"]).to_dict(orient="records"))
    create_table_artifact(
        key=key,
        table=table,
        description=f"re-plans of {values['target']}: {len(rows)} plans in element-set order "
        "(dV_total [m/s], T_total [s], M_load [kg], landing miss [m]; `ovtraj history`)",
    )
    previous = previous_plan(catalog, plan)
    lines = [
        f"**{len(rows)} re-plans of {values['target']}**",
        f"- this plan: `{planned['json']}` (element set of {values['element_set_epoch_utc']})",
    ]
    if previous is not None:
        lines.append(
            f"- previous plan: `{plan_file(store.root, previous['source'])}` (plan "
            f"{previous['plan_id']}, element set of {previous['element_set_epoch_utc']}); "
            f"`ovtraj diff {previous['plan_id']} {plan_id(plan)}`"
        )
    create_markdown_artifact(
        key=f"{key}-plot",
        markdown="\n\n".join(["\n".join(lines), *embedded_plots([plot])]),
        description=f"trend of the re-plans of {values['target']}",
    )


def _publish_last_fit(store: RunStore, outcome: PipelineOutcome) -> None:
    """The validation table of the pipeline's last surrogate fit (its models' choice)."""
    surrogates = last_surrogates(store, outcome.result)
    if surrogates is None:
        return
    last = outcome.result.summary["iterations"][-1]
    frame = surrogates.validation
    rows = frame.astype(object).where(frame.notna(), None).to_dict(orient="records")
    rows = [{k: (round(v, 6) if isinstance(v, float) else v) for k, v in r.items()} for r in rows]
    directory = store.root / last["run_id"] / "surrogates" / last["fit_id"]
    summary = {"validation": rows, "fit_id": last["fit_id"], "directory": str(directory)}
    publish_validation(summary, store.run(last["run_id"]))


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
    plots = sorted(str(p) for p in result.directory.glob("*.png")) + [
        str(p) for p in planned["plots"]
    ]
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
    run_from_command_line(mission_flow)
