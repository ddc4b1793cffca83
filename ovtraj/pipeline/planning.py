"""From a verified front to a mission plan on disk (SPEC step 6)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ovtraj.config import Scenario
from ovtraj.environment import require_pinned_kernel
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign
from ovtraj.optimize import Normalisation
from ovtraj.pipeline.catalog import pipeline_summaries
from ovtraj.pipeline.loop import PipelineError, PipelineResult, load_pipeline
from ovtraj.pipeline.pick import Pick, pick_front_point
from ovtraj.pipeline.plan_flights import REPORT_SUFFIX, stored_flights
from ovtraj.pipeline.report import pick_explanation, write_report
from ovtraj.runs import Run, RunStore, StoreError
from ovtraj.runs.ids import checked_id, within_store
from ovtraj.store.backends import location
from ovtraj.store.files import file_digest
from ovtraj.store.layout import PLAN_MARKER_SUFFIX
from ovtraj.store.products import digests_json
from ovtraj.store.seals import write_sealed
from ovtraj.tracking.catalog import plan_file, refresh


def find_pipeline(run: Run, pipeline: str | None = None) -> PipelineResult:
    """The run's pipeline result: the one named (a pipeline id, :func:`checked_id`), else the
    newest (its files checked)."""
    if pipeline is not None:
        checked_id(pipeline, "pipeline id")
    stored = pipeline_summaries(run)
    if not stored:
        raise PipelineError(
            f"run {run.id} has no pipeline result: run `ovtraj pipeline` (or the mission "
            "flow) on it first"
        )
    if pipeline is None:
        return load_pipeline(stored[-1][0])
    for directory, summary in stored:
        if summary.get("pipeline_id") == pipeline:
            return load_pipeline(directory)
    known = ", ".join(str(summary.get("pipeline_id")) for _, summary in stored)
    raise PipelineError(f"run {run.id} has no pipeline {pipeline!r}; it has {known}")


def _since_previous_plan(store: RunStore, plan: dict[str, Any]) -> Any:
    """The previous plan of this target in the store (:func:`previous_plan`) and what
    changed since (:func:`ovtraj.tracking.diff.changes`), or None for the first plan."""
    from ovtraj.mission.plan_store import read_plan
    from ovtraj.tracking.diff import changes
    from ovtraj.tracking.figures import plan_figures
    from ovtraj.tracking.history import previous_plan

    catalog = refresh(store.root)
    row = previous_plan(catalog, plan)
    if row is None:
        return None
    # the catalog is a file like any other: the path its row gives stays inside the store
    path = within_store(store.root, plan_file(store.root, row["source"]), f"{catalog.path}: source")
    previous = read_plan(path).to_dict()
    return row, changes(plan_figures(previous), plan_figures(plan))


def write_mission_plan(
    scenario: Scenario,
    launch_fit: LaunchFit,
    store: RunStore,
    result: PipelineResult,
    pick: Pick,
) -> dict[str, Any]:
    """Build the plan of the picked front point, write it (JSON, YAML) and its plots.

    The plots show the chain evaluated again for the plan, at the stages' own sampling
    (the store keeps its trajectories coarser). The report shows the flights ``ovtraj fly``
    stored beside the plan (:mod:`ovtraj.pipeline.plan_flights`). ``<name>.files.json``,
    written last, lists the size and SHA-256 of every file of the plan, its stored flights
    too (``ovtraj verify``).
    """
    from ovtraj.mission.plan_build import plan_and_record
    from ovtraj.mission.plan_check import check_front_point
    from ovtraj.mission.plan_store import write_plan
    from ovtraj.plots.mission import mission_plots

    normalisation = Normalisation.mission(scenario.mission.optimize)
    row = pick_front_point(result.front, normalisation, pick)
    sample_id = int(row["sample_id"])
    design = MissionDesign(**{name: float(row[name]) for name in DESIGN_NAMES})
    source = {
        "doe_run": result.doe_run,
        "run_id": result.final_run,
        "pipeline_id": result.pipeline_id,
        "front_index": int(row["front_index"]),
        "sample_id": sample_id,
        "front_objectives": {n: float(row[n]) for n in normalisation.names},
    }
    context = MissionContext(scenario, launch_fit)
    require_pinned_kernel()  # the plan is stored: computed on the pinned OpenBLAS kernel only
    plan, record = plan_and_record(context, design, source=source)
    run = store.run(result.final_run)
    tolerance = scenario.mission.plan.front_tolerance
    if tolerance is not None:
        check_front_point(
            record,
            source["front_objectives"],
            stored_stage_rows(run, sample_id),
            tolerance,
            f"front point {source['front_index']} (sample {sample_id})",
        )
    directory = result.directory / "plans"
    name = f"plan-sample-{sample_id}"
    json_path, yaml_path = write_plan(plan, directory, name)
    plots = mission_plots(record.trajectories, scenario, directory, prefix=name)
    ascent, entry = plan_detail_plots(plan, record.trajectories, scenario, directory, name)
    from ovtraj.plots.front import front_plot

    totals = run.totals()
    chosen = result.front[result.front["sample_id"] == sample_id]
    plots.append(
        front_plot(
            directory / f"{name}-front.png",
            normalisation,
            samples=totals[totals["feasible"].astype(bool)],
            verified=result.front,
            chosen=chosen,
            title=f"front point {int(row['front_index'])} (sample {sample_id}), "
            f"pipeline {result.pipeline_id}",
            scenario=scenario.name,
            date=f"epoch {scenario.epoch_utc}",
        )
    )
    since = _since_previous_plan(store, plan.to_dict())
    flights = stored_flights(location(directory), name, plan)  # ovtraj fly stored them
    report = write_report(
        directory / f"{name}{REPORT_SUFFIX}",
        scenario_name=scenario.name,
        normalisation=normalisation,
        summary=result.summary,
        verify=scenario.mission.verify,
        front=result.front,
        plan=plan,
        pick_text=pick_explanation(result.front, normalisation, pick, row),
        surrogates=last_surrogates(store, result),
        plots=[result.directory / "front.png", *(location(p) for p in plots)],
        since_previous=since,
        ascent_plot=ascent,
        entry_plot=entry,
        flights=[flight for _, flight in flights],
    )
    plots += [p for p in (ascent, entry) if p is not None]
    paths = [json_path, yaml_path, *(location(p) for p in plots), report]
    paths += [path for path, _ in flights]
    files = {path.name: file_digest(path) for path in paths}
    write_sealed(
        directory / f"{name}{PLAN_MARKER_SUFFIX}",
        {"plan": name, "files": digests_json(files)},
        replace=True,  # the plots are views, drawn again with the plan
    )
    refresh(store.root)  # the catalog lists the new plan (ovtraj.tracking.catalog)
    return {
        "plan": plan,
        "json": json_path,
        "yaml": yaml_path,
        "plots": [location(p) for p in plots],
        "report": report,
        "pick": pick_explanation(result.front, normalisation, pick, row),
    }


def plan_detail_plots(
    plan: Any, trajectories: dict[str, Any], scenario: Scenario, directory: Any, name: str
) -> tuple[Path | None, Path | None]:
    """The plan's ascent from the drop (its programme flown by the launch stage's model,
    :func:`ovtraj.mission.replay_ascent.ascent_trajectory`) and its entry's time histories (the
    reentry's trajectory table), drawn as ``<name>_ascent.png`` and
    ``<name>_entry_histories.png`` in ``directory``; None for a figure without its data."""
    from ovtraj.mission.flight_report import ReplayFailed
    from ovtraj.mission.replay_ascent import ascent_trajectory
    from ovtraj.plots.ascent import ascent_plot
    from ovtraj.plots.entry import entry_histories_plot

    directory = location(directory)
    try:
        ascent = ascent_plot(
            ascent_trajectory(plan, scenario), scenario, directory / f"{name}_ascent.png"
        )
    except ReplayFailed:  # a plan whose scenario no longer poses its launch: no figure
        ascent = None
    table = trajectories.get("reentry")
    entry = None
    if table is not None and len(table):
        entry = entry_histories_plot(table, scenario, directory / f"{name}_entry_histories.png")
    return ascent, entry


def stored_stage_rows(run: Run, sample_id: int) -> dict[str, dict[str, Any]]:
    """The stage rows the run stored for a sample (stage -> row; a stage it did not reach
    or store is left out)."""
    from ovtraj.mission import STAGES

    rows: dict[str, dict[str, Any]] = {}
    for stage in STAGES:
        table = run.stage(stage)
        if len(table) and "sample_id" in table:
            match = table[table["sample_id"] == sample_id]
            if len(match):
                rows[stage] = match.iloc[0].to_dict()
    return rows


def last_surrogates(store: RunStore, result: PipelineResult) -> Any:
    """The pipeline's last surrogate fit; None when it is no longer stored (pruned as
    stale)."""
    from ovtraj.pipeline.features import load_surrogates
    from ovtraj.surrogate import SurrogateError

    rounds = result.summary.get("iterations") or []
    if not rounds:
        return None
    last = rounds[-1]
    try:
        return load_surrogates(store.root / last["run_id"] / "surrogates" / last["fit_id"])
    except (SurrogateError, StoreError, OSError):
        return None
