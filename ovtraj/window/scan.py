"""The launch-window driver: one whole-mission pipeline per launch day, then the best day
(``ovtraj window`` and ``flows/window.py`` call :func:`scan_window`).

For a scenario and N days:

1. a scenario per day (:func:`ovtraj.window.days.day_scenario`: the launch day moves, the
   target stays the same object);
2. the launch fit of each day: its stored fit, else the grid the days share, flown on the
   day and fitted (:func:`ovtraj.launch.launch_fit.day_launch_fit`, ~2-5 s); a grid none of
   the stores holds is solved first, once (~4 min; the shipped scenario's is shipped);
3. each day's pipeline, :func:`ovtraj.pipeline.drive.drive_pipeline` as ``ovtraj pipeline``
   runs it: its own DoE run, infill runs, front, plan and report in the run store, each
   reused by content on a second scan. The days run on a :class:`DayRunner`: the library's
   pool (:class:`PoolDays`, the command) or the flow's task runner, each day whole in one
   process with its batches in series: a pipeline's fits, NSGA-II and plan run in one
   process anyway, so two days side by side keep two cores busy where one day's batches
   on two processes would leave one idle most of the time (docs/window.md, measured);
4. each day's record (its picked plan: the front point's design, objectives and score by
   the pick's weights on the normalised objectives, :func:`ovtraj.pipeline.pick.
   weighted_scores`; the plan swept along the porkchop's variable, :mod:`.porkchop`),
   written as the day ends, so a stopped scan resumes where it was;
5. the window, in ``<run store>/windows/<window id>/``: the tables (``window.parquet``,
   :data:`ovtraj.window.report.WINDOW_SCHEMA`; ``porkchop.parquet``), the plots (PNG,
   SVG), the HTML page linking each day's report, and ``window.json`` written last with
   their digests.

The best day is the day whose picked plan scores lowest, under the same weights and the
same normalisation as each day's pick (the scenario's ``mission.optimize`` ideal and
reference points, which no launch day moves); a tie goes to the earlier day. A window
whose ``window.json`` is stored, checks, and whose days' plans are unchanged is returned
as stored: nothing simulated, nothing written.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import as_completed
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.orchestration import DaskSettings, load_orchestration
from ovtraj.launch.launch_fit import (
    Progress,
    day_launch_fit,
    find_launch_fit,
    find_launch_grid,
    grid_data,
    grid_from_data,
    solve_launch_grid,
)
from ovtraj.mission import DESIGN_NAMES
from ovtraj.optimize import Normalisation
from ovtraj.pipeline.pick import Pick, pick_weights, weighted_scores
from ovtraj.pipeline.steps import content_id
from ovtraj.runs import RunStore
from ovtraj.runs.ids import checked_id
from ovtraj.runs.runners import RunnerChoice, batch_pool
from ovtraj.store.backends import location
from ovtraj.store.files import StoreError, file_digest
from ovtraj.units import S_PER_HOUR
from ovtraj.window.days import day_scenario, launch_date
from ovtraj.window.porkchop import Sweep, sweep_day, window_sweep
from ovtraj.window.records import (
    FORMAT,
    PLANNED,
    WindowOutcome,
    best_day,
    new_record,
    record_problem,
    relative_path,
    stored_day,
    write_day,
)
from ovtraj.window.settings import WindowSettings, load_window_settings

__all__ = [
    "DayJob",
    "DayRunner",
    "PoolDays",
    "WindowError",
    "WindowRequest",
    "run_day",
    "scan_window",
    "window_directory",
    "window_id",
]

logger = logging.getLogger(__name__)

WINDOWS_DIR = "windows"  # in the run store's root: a window lives beside its days' runs


class WindowError(ValueError):
    """Bad input to a window scan (the days, a scenario without a mission), named."""


@dataclass(frozen=True)
class WindowRequest:
    """What the caller asks beyond the scenario: the days, each day's DoE size and seed
    (``None``: ``mission.doe``'s) and the pick of each day's verified front."""

    days: int
    samples: int | None = None
    seed: int | None = None
    pick: Pick = field(default_factory=Pick)


@dataclass(frozen=True)
class DayJob:
    """One day's pipeline as plain data (what a pool's process or a Dask worker gets):
    the day's resolved scenario, the run store's root (a folder or ``s3://`` URL), the
    code version, the DoE's size and seed, the pick (``Pick`` as a mapping), the
    porkchop's sweep (``Sweep`` as a mapping) and the launch grid the days share
    (:func:`ovtraj.launch.launch_fit.grid_data`; None when every day's fit is stored),
    so that a worker with no grid on its disk retimes it."""

    window_id: str
    day: int
    date: str
    resolved: dict[str, Any]
    store: str
    code: str
    samples: int
    seed: int
    pick: dict[str, Any]
    sweep: dict[str, Any]
    grid: dict[str, Any] | None = None


def _pick_of(data: dict[str, Any]) -> Pick:
    weights = data.get("weights")
    return Pick(**{**data, "weights": None if weights is None else tuple(weights)})


def run_day(job: DayJob) -> dict[str, Any]:
    """The day's pipeline (``ovtraj pipeline``'s driver, its batches in this process),
    its plan swept (:func:`~ovtraj.window.porkchop.sweep_day`) and its record; a day the
    pipeline cannot plan (no front, a pick no point meets, the
    optimiser stopped, a plan off its front point, a launch the shared grid cannot fly)
    is a record ``no plan`` with the reason. Other faults raise."""
    from ovtraj.mission.plan_check import PlanMismatch
    from ovtraj.pipeline import OptimiserStopped, PipelineError
    from ovtraj.pipeline.drive import PipelineRequest, drive_pipeline
    from ovtraj.runs.execute import PoolBatches

    scenario = scenario_from_dict(job.resolved, f"day {job.day} of window {job.window_id}")
    record = new_record(job.window_id, job.day, job.date)
    grid = None if job.grid is None else grid_from_data(job.grid)
    try:
        fit = day_launch_fit(scenario, grid=grid)
    except ValueError as err:  # a grid point the day cannot fly
        return record | {"reason": str(err)}
    if fit is None:
        raise WindowError(f"{job.date}: no launch fit and no launch grid stored for the day")
    orchestration = load_orchestration()
    batches = PoolBatches(
        scenario,
        fit,
        RunnerChoice("serial", 1),
        dask=orchestration.dask,
        time_limit_s=orchestration.flows.doe_s,
        progress=logger.debug,
    )
    pick = _pick_of(job.pick)
    request = PipelineRequest(samples=job.samples, seed=job.seed, pick=pick)
    store = RunStore(job.store)
    try:
        outcome = drive_pipeline(
            scenario, fit, store, job.code, batches, request, progress=logger.debug
        )
    except (PipelineError, OptimiserStopped, PlanMismatch) as err:
        return record | {"reason": str(err)}
    result, planned = outcome.result, outcome.planned
    source = planned["plan"].source
    front = result.front
    chosen = front[front["front_index"] == int(source["front_index"])]
    normalisation = Normalisation.mission(scenario.mission.optimize)
    score = weighted_scores(chosen, normalisation, pick_weights(pick))
    plan_path = location(planned["json"])
    design = {name: float(chosen.iloc[0][name]) for name in DESIGN_NAMES}
    return record | {
        "status": PLANNED,
        "doe_run": result.doe_run,
        "pipeline_id": result.pipeline_id,
        "final_run": result.final_run,
        "converged": outcome.converged,
        "stop_reason": str(result.summary["stop_reason"]),
        "verdict": outcome.verdict,
        "front_index": int(source["front_index"]),
        "sample_id": int(source["sample_id"]),
        **{name: float(chosen.iloc[0][name]) for name in normalisation.names},
        "score": float(score[0]),
        **design,
        "plan": relative_path(plan_path, store.root),
        "plan_sha256": file_digest(plan_path).sha256,
        "report": relative_path(location(planned["report"]), store.root),
        "sweep": sweep_day(scenario, fit, design, Sweep.from_data(job.sweep)),
    }


class DayRunner(Protocol):
    """Where the days' pipelines run: ``run`` yields each job's record as it ends (any
    order), or raises the first fault."""

    def run(self, jobs: Sequence[DayJob]) -> Iterator[dict[str, Any]]: ...


@dataclass(frozen=True)
class PoolDays:
    """The library's :class:`DayRunner`: the days on the pool of ``choice``
    (:func:`ovtraj.runs.runners.batch_pool`): ``processes`` and ``dask`` run
    ``choice.workers`` days at once, one per process; ``serial`` and ``threads`` one
    after another here (threads would share one core's GIL between whole pipelines)."""

    choice: RunnerChoice
    dask: DaskSettings | None = None

    def run(self, jobs: Sequence[DayJob]) -> Iterator[dict[str, Any]]:
        if not jobs:
            return
        choice = self.choice
        if choice.runner in ("serial", "threads"):
            for job in jobs:
                yield run_day(job)
            return
        dask = self.dask or load_orchestration().dask
        workers = min(choice.workers, len(jobs))
        with batch_pool(choice.runner, workers, choice.dask_address, dask) as pool:
            futures = [pool.executor.submit(run_day, job) for job in jobs]
            for future in as_completed(futures):
                yield future.result()


def window_id(
    base: Scenario, request: WindowRequest, code: str, settings: WindowSettings | None = None
) -> str:
    """Content id of a scan: the scenario (its first day), the days, the DoE's size and
    seed as each day's pipeline takes them, the pick, the porkchop's sweep
    (``settings``, default ``configs/window.yaml``) and the code version. The runner is
    not part of it (no result depends on where the days run)."""
    doe = base.mission.doe
    sweep = window_sweep(base, (settings or load_window_settings()).porkchop)
    return content_id(
        {
            "kind": "launch-window",
            "format": FORMAT,
            "scenario": base.resolved(),
            "days": request.days,
            "samples": doe.samples if request.samples is None else request.samples,
            "seed": doe.seed if request.seed is None else request.seed,
            "pick": asdict(request.pick),
            "sweep": sweep.as_data(),
            "code": code,
        }
    )


def window_directory(store: RunStore, identity: str) -> Any:
    """``<run store>/windows/<window id>``."""
    return store.root / WINDOWS_DIR / checked_id(identity, "window id")


def scan_window(
    base: Scenario,
    request: WindowRequest,
    store: RunStore,
    code: str,
    runner: DayRunner,
    *,
    progress: Callable[[str], None] | None = None,
    grid_progress: Progress | None = None,
    settings: WindowSettings | None = None,
) -> WindowOutcome:
    """Scan ``request.days`` launch days from the scenario's own (module notes).

    Raises :class:`WindowError` (the days outside ``configs/window.yaml`` ``max_days``, no
    mission section), ``ConfigError`` (a day's scenario invalid), and what the runner
    raises for a day (the store, the cluster, a batch).
    """
    from ovtraj.window.report import load_window, write_window

    settings = settings or load_window_settings()
    say = progress or logger.info
    if base.mission is None or base.launch is None:
        raise WindowError("the scenario has no mission section (a window plans missions)")
    if not 1 <= request.days <= settings.max_days:
        raise WindowError(
            f"days = {request.days}: must lie in 1..{settings.max_days} "
            "(configs/window.yaml max_days)"
        )
    scenarios = [day_scenario(base, d) for d in range(request.days)]
    dates = [launch_date(base, d) for d in range(request.days)]
    identity = window_id(base, request, code, settings)
    sweep = window_sweep(base, settings.porkchop)
    directory = window_directory(store, identity)
    stored = load_window(directory, identity, dates, store, sweep)
    if stored is not None:
        say(f"window {identity}: stored, every day's plan unchanged (nothing to run)")
        return stored
    records = {}
    for d, date in enumerate(dates):
        record = stored_day(directory, identity, d, date, store, sweep)
        if record is not None:
            records[d] = record
    todo = [d for d in range(request.days) if d not in records]
    if records:
        say(f"window {identity}: {len(records)} of {request.days} days stored")
    grid = find_launch_grid(base) if todo else None
    if grid is None and any(find_launch_fit(scenarios[d]) is None for d in todo):
        say("no launch grid stored for these days: solving it once (~4 min here)")
        grid = solve_launch_grid(base, grid_progress)
    carried = None if grid is None else grid_data(grid)
    doe = base.mission.doe
    jobs = {
        d: DayJob(
            window_id=identity,
            day=d,
            date=dates[d],
            resolved=scenarios[d].resolved(),
            store=str(store.root),
            code=code,
            samples=doe.samples if request.samples is None else request.samples,
            seed=doe.seed if request.seed is None else request.seed,
            pick=asdict(request.pick),
            sweep=sweep.as_data(),
            grid=carried,
        )
        for d in todo
    }
    for record in runner.run(list(jobs.values())):
        day = record.get("day") if isinstance(record, dict) else None
        job = jobs.get(day) if type(day) is int else None
        problem = "no day of this scan" if job is None else None
        problem = problem or record_problem(record, identity, job.day, job.date, sweep)
        if problem:
            raise StoreError(f"window {identity}: a day's record came back malformed ({problem})")
        write_day(directory, record)
        records[day] = record
        say(day_line(record))
    ordered = [records[d] for d in range(request.days)]
    best = best_day(ordered)
    return write_window(directory, identity, base, request, code, ordered, best, store, sweep)


def day_line(record: dict[str, Any]) -> str:
    """One progress line of a finished day."""
    if record["status"] != PLANNED:
        return f"day {record['day']} {record['date']}: no plan ({record['reason']})"
    return (
        f"day {record['day']} {record['date']}: T_total {record['t_total_s'] / S_PER_HOUR:.2f} h, "
        f"dV_total {record['dv_total_mps']:.2f} m/s, M_load {record['m_load_kg']:.2f} kg, "
        f"score {record['score']:.4f}"
    )
