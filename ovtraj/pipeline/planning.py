"""From a verified front to a mission plan on disk (SPEC step 6)."""

from __future__ import annotations

from dataclasses import dataclass
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
from ovtraj.store.layout import (
    MANIFEST,
    PIPELINE_DIR,
    PIPELINE_MARKER,
    PLAN_MARKER_SUFFIX,
    PLANS_DIR,
)
from ovtraj.store.products import digests_json
from ovtraj.store.seals import write_sealed
from ovtraj.tracking.catalog import refresh_entries
from ovtraj.tracking.catalog_rows import plan_file


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
    changed since (:func:`ovtraj.tracking.diff.changes`), or None for the first plan.

    The catalog is read as stored (every writer of a plan keeps its own rows up to date),
    only the row of the plan found refreshed (a plan pruned or changed since is not taken);
    the catalog is rebuilt only when there is no usable one."""
    from ovtraj.mission.plan_store import read_plan
    from ovtraj.tracking.diff import changes
    from ovtraj.tracking.figures import plan_figures
    from ovtraj.tracking.history import previous_plan

    catalog = refresh_entries(store.root, [])
    row, checked = previous_plan(catalog, plan), set()
    while row is not None and row["source"] not in checked:
        checked.add(row["source"])
        catalog = refresh_entries(store.root, [row["source"]])
        row = previous_plan(catalog, plan)
    if row is None:
        return None
    # the catalog is a file like any other: the path its row gives stays inside the store
    path = within_store(store.root, plan_file(store.root, row["source"]), f"{catalog.path}: source")
    previous = read_plan(path).to_dict()
    return row, changes(plan_figures(previous), plan_figures(plan))


@dataclass(frozen=True)
class _PlanPoint:
    """The front point being planned: its scenario, store and pipeline result, the
    objectives' normalisation, its row of the verified front, and the folder its plan goes
    to (the result's ``plans/``)."""

    scenario: Scenario
    store: RunStore
    result: PipelineResult
    normalisation: Normalisation
    row: Any
    directory: Any

    @property
    def sample_id(self) -> int:
        return int(self.row["sample_id"])

    @property
    def name(self) -> str:
        """The plan's name: the stem of its files."""
        return f"plan-sample-{self.sample_id}"


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
    too (``ovtraj verify``). The store's catalog then lists the plan: its rows and those of
    what it references are brought up to date (:func:`catalog_sources`), no other.
    """
    from ovtraj.mission.plan_store import write_plan

    normalisation = Normalisation.mission(scenario.mission.optimize)
    row = pick_front_point(result.front, normalisation, pick)
    point = _PlanPoint(scenario, store, result, normalisation, row, result.directory / "plans")
    plan, record, run = _plan_of_point(point, launch_fit)
    json_path, yaml_path = write_plan(plan, point.directory, point.name)
    plots, ascent, entry = _plan_plots(point, plan, record, run)
    report, flights = _plan_report(point, pick, plan, plots, ascent, entry)
    plots += [p for p in (ascent, entry) if p is not None]
    paths = [json_path, yaml_path, *(location(p) for p in plots), report]
    paths += [path for path, _ in flights]
    _seal_plan(point, paths)
    return {
        "plan": plan,
        "json": json_path,
        "yaml": yaml_path,
        "plots": [location(p) for p in plots],
        "report": report,
        "pick": pick_explanation(result.front, normalisation, pick, row),
    }


def _plan_of_point(point: _PlanPoint, launch_fit: LaunchFit) -> tuple[Any, Any, Run]:
    """The plan of the point and the chain's record of it, evaluated again on the pinned
    kernel, checked against the front's values when ``mission.plan.front_tolerance`` is
    set; and the pipeline's final run (which stored the point)."""
    from ovtraj.mission.plan_build import plan_and_record
    from ovtraj.mission.plan_check import check_front_point

    row, result, sample_id = point.row, point.result, point.sample_id
    design = MissionDesign(**{name: float(row[name]) for name in DESIGN_NAMES})
    source = {
        "doe_run": result.doe_run,
        "run_id": result.final_run,
        "pipeline_id": result.pipeline_id,
        "front_index": int(row["front_index"]),
        "sample_id": sample_id,
        "front_objectives": {n: float(row[n]) for n in point.normalisation.names},
    }
    context = MissionContext(point.scenario, launch_fit)
    require_pinned_kernel()  # the plan is stored: computed on the pinned OpenBLAS kernel only
    plan, record = plan_and_record(context, design, source=source)
    run = point.store.run(result.final_run)
    tolerance = point.scenario.mission.plan.front_tolerance
    if tolerance is not None:
        check_front_point(
            record,
            source["front_objectives"],
            stored_stage_rows(run, sample_id),
            tolerance,
            f"front point {source['front_index']} (sample {sample_id})",
        )
    return plan, record, run


def _plan_plots(
    point: _PlanPoint, plan: Any, record: Any, run: Run
) -> tuple[list[Any], Path | None, Path | None]:
    """The plan's figures: the mission plots and the front with the point (a list), the
    ascent and the entry's histories (:func:`plan_detail_plots`, None without data)."""
    from ovtraj.plots.mission import mission_plots

    scenario, result, directory, name = point.scenario, point.result, point.directory, point.name
    plots = mission_plots(record.trajectories, scenario, directory, prefix=name)
    ascent, entry = plan_detail_plots(plan, record.trajectories, scenario, directory, name)
    from ovtraj.plots.front import front_plot

    totals = run.totals()
    chosen = result.front[result.front["sample_id"] == point.sample_id]
    plots.append(
        front_plot(
            directory / f"{name}-front.png",
            point.normalisation,
            samples=totals[totals["feasible"].astype(bool)],
            verified=result.front,
            chosen=chosen,
            title=f"front point {int(point.row['front_index'])} (sample {point.sample_id}), "
            f"pipeline {result.pipeline_id}",
            scenario=scenario.name,
            date=f"epoch {scenario.epoch_utc}",
        )
    )
    return plots, ascent, entry


def _plan_report(
    point: _PlanPoint,
    pick: Pick,
    plan: Any,
    plots: list[Any],
    ascent: Path | None,
    entry: Path | None,
) -> tuple[Any, list[Any]]:
    """The plan's HTML report (what changed since the previous plan of the target, the
    flights stored beside the plan) and those flights, (path, flight) each."""
    result, normalisation = point.result, point.normalisation
    since = _since_previous_plan(point.store, plan.to_dict())
    flights = stored_flights(location(point.directory), point.name, plan)  # ovtraj fly's
    report = write_report(
        point.directory / f"{point.name}{REPORT_SUFFIX}",
        scenario_name=point.scenario.name,
        normalisation=normalisation,
        summary=result.summary,
        verify=point.scenario.mission.verify,
        front=result.front,
        plan=plan,
        pick_text=pick_explanation(result.front, normalisation, pick, point.row),
        surrogates=last_surrogates(point.store, result),
        plots=[result.directory / "front.png", *(location(p) for p in plots)],
        since_previous=since,
        ascent_plot=ascent,
        entry_plot=entry,
        flights=[flight for _, flight in flights],
    )
    return report, flights


def _seal_plan(point: _PlanPoint, paths: list[Any]) -> None:
    """Write the plan's marker ``<name>.files.json`` (the size and SHA-256 of every file of
    the plan), then bring the catalog's rows of the plan and of what it references up to
    date (:func:`ovtraj.tracking.catalog.refresh_entries`)."""
    files = {path.name: file_digest(path) for path in paths}
    write_sealed(
        point.directory / f"{point.name}{PLAN_MARKER_SUFFIX}",
        {"plan": point.name, "files": digests_json(files)},
        replace=True,  # the plots are views, drawn again with the plan
    )
    refresh_entries(point.store.root, catalog_sources(point.result, point.name))


def catalog_sources(result: PipelineResult, name: str) -> list[str]:
    """The catalog rows (their ``source``, relative to the store) that writing the plan
    ``name`` of a pipeline result changes: the plan's and those of what it references, its
    pipeline result and the runs that result was made from (its DoE run, the runs of its
    rounds, its final run)."""
    folder = f"{result.directory.parent.parent.name}/{PIPELINE_DIR}/{result.directory.name}"
    runs = {result.doe_run, result.final_run}
    for step in result.summary.get("iterations") or []:
        if isinstance(step, dict):
            runs |= {step.get("run_id"), step.get("infill_run")}
    return [
        *(f"{run}/{MANIFEST}" for run in sorted(r for r in runs if isinstance(r, str))),
        f"{folder}/{PIPELINE_MARKER}",
        f"{folder}/{PLANS_DIR}/{name}{PLAN_MARKER_SUFFIX}",
    ]


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
