"""Flow: a launch-window scan (``flows/window.py:window_flow``; issue 48, docs/window.md).

The library's one driver (:func:`ovtraj.window.scan.scan_window`, as ``ovtraj window``),
with each launch day a task (``tasks/window.py``) on the flow's task runner
(``serial | threads | processes | dask``: the ``runner`` parameter, else
``mission.doe.task_runner``; ``serial`` and ``threads`` one day after another):

1. the scenario and its days (the launch day moves, the target stays);
2. a task per day not stored yet: the day's launch fit (the shared grid flown on the
   day), then its whole pipeline, runs, front, plan and report in the run store;
3. the window's tables, plots (the days' objectives, the porkchop) and page in
   ``<run store>/windows/<window id>/``, then artifacts: the days' table and the plots;
4. the state: Completed when every planned day's verification loop converged, else Failed
   with the line ``ovtraj window`` prints after its table (the days that did not, or "no
   day has a plan") as its message; ``require_converged=False``: a window whose days did
   not all converge ends Completed, named "Not converged" (``flows/verdict.py``).

A second flow run with nothing changed submits no task: every day's record is stored.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from prefect import flow, get_run_logger
from prefect.artifacts import create_markdown_artifact, create_table_artifact
from prefect.futures import as_completed

from flows.common import embedded_plots, label_flow_run, run_name, run_tags
from flows.runners import task_runner
from flows.verdict import run_from_command_line, verdict_state
from ovtraj.paths import scenario_file
from ovtraj.pipeline.pick import checked_pick
from ovtraj.runs import RunStore
from ovtraj.runs.runners import RunnerChoice, choose_runner
from ovtraj.target_sources import load_scenario_with_target
from ovtraj.window.records import window_verdict
from ovtraj.window.report import window_rows
from ovtraj.window.scan import DayJob, WindowRequest, scan_window, window_id
from ovtraj.window.settings import load_window_settings
from tasks.common import code_version
from tasks.window import window_day_task

WINDOW = load_window_settings()


@dataclass(frozen=True)
class TaskDays:
    """The flow's :class:`ovtraj.window.scan.DayRunner`: a task per day on the task runner
    of ``choice`` (``choice.workers`` days at once on processes or Dask)."""

    choice: RunnerChoice

    def run(self, jobs: Sequence[DayJob]) -> Iterator[dict[str, Any]]:
        if not jobs:
            return
        choice = self.choice
        workers = 1 if choice.runner in ("serial", "threads") else min(choice.workers, len(jobs))
        with task_runner(choice.runner, workers, choice.dask_address) as started:
            futures = [started.submit(window_day_task, {"job": asdict(job)}) for job in jobs]
            for future in as_completed(futures):
                yield future.result()


@flow(
    name="launch-window",
    flow_run_name=run_name("window"),
    timeout_seconds=WINDOW.flow_timeout_s,
    log_prints=True,
)
def window_flow(
    config: str | None = None,
    days: int = 1,
    samples: int | None = None,
    seed: int | None = None,
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
    """``days`` launch days from the scenario's, a pipeline each; the best plan of each
    day by ``weights`` (T, dV, M on the normalised objectives; equal by default) among
    the front points within the limits, and the best day. Returns the window's paths and
    the days' rows.

    The parameters are ``ovtraj window``'s options by the same names (``--max-dv-mps`` is
    ``max_dv_mps``, ``--store`` ``store``, ...; tests/test_flows.py). ``config``: the
    scenario file (default: the shipped scenario). ``max_time_h`` [h], ``max_dv_mps``
    [m/s], ``min_payload_kg`` [kg]: each day's plan among the front points within them.
    ``store``: the run store (else ``mission.doe.store``, else the workspace's).
    ``target``: a TLE/OMM file or URL replacing the scenario's target.
    ``runner``/``workers``/``dask_address``: where the days run (default:
    ``mission.doe``'s runner and workers; ``dask_address`` else ``OVTRAJ_DASK_ADDRESS``,
    else a local cluster). ``require_converged`` (the command's ``--allow-unconverged``
    turned around): a day whose verification loop did not converge ends the flow run
    Failed, the days named in its message (False: Completed, named "Not converged"); a
    window with no planned day ends Failed either way. The window is stored and published first.
    """
    logger = get_run_logger()
    path = scenario_file(config)
    scenario = load_scenario_with_target(path, target)
    if scenario.mission is None:
        raise ValueError(f"{path}: the scenario has no mission section")
    pick = checked_pick(None, weights, max_time_h, max_dv_mps, min_payload_kg)
    choice = choose_runner(scenario.mission.doe, runner, dask_address)
    if workers is not None:
        choice = RunnerChoice(choice.runner, workers, choice.dask_address)
    run_store = RunStore.for_scenario(scenario, config, store)
    request = WindowRequest(days=days, samples=samples, seed=seed, pick=pick)
    code = code_version()
    identity = window_id(scenario, request, code)
    label_flow_run(f"window {scenario.name} {identity}", run_tags("window", scenario.name))
    logger.info("window %s: %d days, runner %s", identity, days, choice.runner)
    outcome = scan_window(
        scenario, request, run_store, code, TaskDays(choice), progress=logger.info
    )
    rows = [
        row | {"verdict": record["verdict"]}  # the day's pipeline's, as `ovtraj window --json`
        for row, record in zip(
            window_rows(outcome.records, outcome.best_day), outcome.records, strict=True
        )
    ]
    create_table_artifact(
        key="launch-window",
        table=rows,
        description=f"launch window {identity} of {scenario.name}: a row per launch day "
        "(T_total [h], dV_total [m/s], M_load [kg] of the day's picked plan, its score, "
        "its verification loop's verdict)",
    )
    best = outcome.best_day
    converged, verdict = window_verdict(outcome.records)
    headline = (
        verdict
        if best is None
        else f"best day {outcome.records[best]['date']} (day {best}), "
        f"score {outcome.records[best]['score']:.4f}; {verdict}"
    )
    files = {name: str(path) for name, path in outcome.files.items()}
    create_markdown_artifact(
        key="launch-window-plot",
        markdown="\n\n".join(
            [
                f"**{headline}**",
                f"- page: `{files['window.html']}`",
                *embedded_plots([outcome.files["window.png"], outcome.files["porkchop.png"]]),
            ]
        ),
        description=f"launch window {identity} of {scenario.name}",
    )
    logger.info("%s; page %s", headline, files["window.html"])
    summary = {
        "window_id": identity,
        "reused": outcome.reused,
        "converged": converged,
        "verdict": verdict,
        "best_day": best,
        "best_date": None if best is None else outcome.records[best]["date"],
        "planned_days": outcome.planned_days,
        "rows": rows,
        "files": files,
    }
    return verdict_state(
        summary,
        verdict,
        converged=converged,
        require_converged=require_converged or best is None,
    )


if __name__ == "__main__":
    run_from_command_line(window_flow)
