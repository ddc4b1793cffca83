"""Flow: a launch-window scan (``flows/window.py:window_flow``; docs/window.md).

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
from ovtraj.pipeline.pick import checked_pick
from ovtraj.runs import RunStore
from ovtraj.runs.preparation import mission_scenario, runner_choice
from ovtraj.runs.runners import RunnerChoice
from ovtraj.window.records import WindowOutcome, window_verdict
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
    scenario = mission_scenario(config, target)
    pick = checked_pick(None, weights, max_time_h, max_dv_mps, min_payload_kg)
    choice = runner_choice(scenario.mission.doe, runner, dask_address, workers)
    run_store = RunStore.for_scenario(scenario, config, store)
    request = WindowRequest(days=days, samples=samples, seed=seed, pick=pick)
    code = code_version()
    identity = window_id(scenario, request, code)
    label_flow_run(f"window {scenario.name} {identity}", run_tags("window", scenario.name))
    logger.info("window %s: %d days, runner %s", identity, days, choice.runner)
    outcome = scan_window(
        scenario, request, run_store, code, TaskDays(choice), progress=logger.info
    )
    rows = _day_rows(outcome)
    converged, verdict = window_verdict(outcome.records)
    _publish(outcome, rows, verdict, f"launch window {identity} of {scenario.name}")
    best = outcome.best_day
    summary = {
        "window_id": identity,
        "reused": outcome.reused,
        "converged": converged,
        "verdict": verdict,
        "best_day": best,
        "best_date": None if best is None else outcome.records[best]["date"],
        "planned_days": outcome.planned_days,
        "rows": rows,
        "files": {name: str(path) for name, path in outcome.files.items()},
    }
    return verdict_state(
        summary, verdict, converged=converged, require_converged=require_converged or best is None
    )


def _day_rows(outcome: WindowOutcome) -> list[dict[str, Any]]:
    """A row per launch day, with its pipeline's verdict (as ``ovtraj window --json``)."""
    return [
        row | {"verdict": record["verdict"]}
        for row, record in zip(
            window_rows(outcome.records, outcome.best_day), outcome.records, strict=True
        )
    ]


def _publish(outcome: WindowOutcome, rows: list[dict[str, Any]], verdict: str, title: str) -> None:
    """The days' table and the window's headline, page and plots as artifacts; the
    headline in the log."""
    create_table_artifact(
        key="launch-window",
        table=rows,
        description=f"{title}: a row per launch day "
        "(T_total [h], dV_total [m/s], M_load [kg] of the day's picked plan, its score, "
        "its verification loop's verdict)",
    )
    best = outcome.best_day
    headline = (
        verdict
        if best is None
        else f"best day {outcome.records[best]['date']} (day {best}), "
        f"score {outcome.records[best]['score']:.4f}; {verdict}"
    )
    page = str(outcome.files["window.html"])
    create_markdown_artifact(
        key="launch-window-plot",
        markdown="\n\n".join(
            [
                f"**{headline}**",
                f"- page: `{page}`",
                *embedded_plots([outcome.files["window.png"], outcome.files["porkchop.png"]]),
            ]
        ),
        description=title,
    )
    get_run_logger().info("%s; page %s", headline, page)


if __name__ == "__main__":
    run_from_command_line(window_flow)
