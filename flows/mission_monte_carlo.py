"""Flow: dispersed Monte Carlo of a mission plan, closed and open loop.

A thin adapter of the library's one Monte Carlo driver
(:func:`ovtraj.store.monte_carlo.drive_monte_carlo` with the study
:class:`ovtraj.runs.plan_monte_carlo.PlanMonteCarlo`, which ``ovtraj fly PLAN
--monte-carlo N`` runs too, so both store the same run for the same inputs):

1. read the plan and the dispersions (``configs/dispersions.yaml`` by default);
2. the driver creates (or reopens) the run directory ``<store>/<run_id>/``: the id hashes
   the plan, the dispersions that count for results, the number of runs, the seed and the
   code version;
3. it flies the runs the store does not hold yet, closed and open loop, here in batches of
   several runs per Prefect task on the configured task runner
   (:class:`flows.monte_carlo_tasks.MonteCarloTasks`); each task is cached on its inputs
   and writes its own batch to Parquet;
4. it writes the landing-miss statistics of each loop, the landed fractions, the smallest
   margin of each path limit and the dV spent (``dv_mps``: p50 / p95 / max of the total
   and of each manoeuvre against the plan's) into ``summary.json``, and the pictures (the
   landing footprint, the dV per manoeuvre) into ``plots/``;
5. two table artifacts (the landing miss, the dV) and a markdown artifact showing the
   pictures; the report is returned.
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
    prune_expired_results,
    run_name,
    run_tags,
)
from flows.monte_carlo_tasks import MonteCarloTasks, raise_failed_batches
from ovtraj.config.base import load_model
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.mission.high_fidelity import high_fidelity_settings
from ovtraj.mission.montecarlo_store import PlanMonteCarloRun
from ovtraj.mission.plan_store import read_plan
from ovtraj.paths import config_path
from ovtraj.runs.plan_monte_carlo import PlanMonteCarlo, store_of
from ovtraj.store.monte_carlo import drive_monte_carlo
from tasks.common import TIMEOUTS, code_version
from tasks.mission_monte_carlo import plan_mc_batch_task

LIMIT = "flows.mission_monte_carlo_s of configs/orchestration.yaml"


@flow(
    name="plan-monte-carlo",
    flow_run_name=run_name("plan-monte-carlo", "plan"),
    timeout_seconds=FLOW_TIMEOUTS.mission_monte_carlo_s,
    log_prints=True,
)
def plan_monte_carlo_flow(
    plan: str,
    dispersions: str | None = None,
    runs: int | None = None,
    seed: int | None = None,
    store: str | None = None,
    batch_size: int | None = None,
    workers: int | None = None,
    runner: str | None = None,
    dask_address: str | None = None,
    fidelity: str = "j2",
    force_model: str | None = None,
) -> dict[str, Any]:
    """Monte Carlo of a plan file; returns the run's summary (id, both loops' statistics).

    The parameters are ``ovtraj fly PLAN --monte-carlo RUNS``'s by the same names
    (``--dispersions`` is ``dispersions``, ``--force-model`` ``force_model``; what the
    command does not take is listed with why in tests/test_flows.py). Arguments left
    ``None`` take the dispersions file's ``execution`` values (``store``: the run store,
    else its ``execution.store``, else the workspace's). ``fidelity``
    ``high`` flies the closed loop under the high-fidelity force model (``force_model``,
    by default the shipped ``configs/force_model.yaml``; ``ovtraj fly --monte-carlo N
    --fidelity high`` in the CLI); the open loop stays the J2 replay. Raises
    ``RuntimeError`` naming the failed batches if a task fails (after its retries); the
    stored batches are kept and a re-run flies only the missing runs.
    """
    deadline = time.monotonic() + FLOW_TIMEOUTS.mission_monte_carlo_s
    prune_expired_results()
    study, tasks = _prepared(
        plan,
        dispersions,
        runs,
        seed,
        store,
        batch_size,
        workers,
        runner,
        dask_address,
        fidelity,
        force_model,
        deadline,
    )

    def opened(run: PlanMonteCarloRun, todo: int) -> None:
        labels = run_tags("plan-monte-carlo", study.plan.scenario.get("name"), run.id)
        label_flow_run(f"plan-monte-carlo {run.id}", labels)
        get_run_logger().info("run %s: %d runs, %d to fly", run.id, study.runs, todo)

    report = drive_monte_carlo(study, tasks, opened=opened)
    _publish(report, fidelity)
    raise_failed_batches(report, report["failed_batches"])
    return report


def _prepared(
    plan: str,
    dispersions: str | None,
    runs: int | None,
    seed: int | None,
    store: str | None,
    batch_size: int | None,
    workers: int | None,
    runner: str | None,
    dask_address: str | None,
    fidelity: str,
    force_model: str | None,
    deadline: float,
) -> tuple[PlanMonteCarlo, MonteCarloTasks]:
    """The flow's parameters as the driver's study and flier: the plan, the dispersions
    file (the shipped one by default) and its ``execution`` values for those left None."""
    mission_plan = read_plan(Path(plan))
    config_file = Path(dispersions) if dispersions else config_path("dispersions.yaml")
    config = load_model(DispersionsConfig, config_file)
    execution = config.execution
    tasks = MonteCarloTasks.configured(
        plan_mc_batch_task,
        execution,
        TIMEOUTS.mission_mc_batch_per_run_s,
        runner=runner,
        workers=workers,
        dask_address=dask_address,
        batch_size=batch_size or execution.batch_size,
        deadline=deadline,
        limit=LIMIT,
    )
    study = PlanMonteCarlo(
        plan=mission_plan,
        dispersions=config,
        runs=runs or execution.runs,
        seed=execution.seed if seed is None else int(seed),
        root=store_of(config, config_file, store),
        code=code_version(),
        batch_size=tasks.batch_size,
        force_model=high_fidelity_settings(mission_plan, fidelity, force_model),
    )
    return study, tasks


def _publish(report: dict[str, Any], fidelity: str) -> None:
    """Two table artifacts (each loop's landing miss; the dV spent per manoeuvre) and a
    markdown artifact showing the pictures."""
    run_id = report["run_id"]
    loops = {"closed": report, "open": report["open_loop"]}  # the closed loop's at the top
    create_table_artifact(
        key="plan-monte-carlo",
        table=[
            {
                "loop": loop,
                "runs": s["runs"],
                "landed": s["landed"],
                "within_stated_miss": s["within_stated_miss_fraction"],
                "p50_km": _km((s["landing_miss_m"] or {}).get("p50")),
                "p95_km": _km((s["landing_miss_m"] or {}).get("p95")),
                "max_km": _km((s["landing_miss_m"] or {}).get("max")),
            }
            for loop, s in loops.items()
        ],
        description=(
            f"Plan Monte Carlo {run_id} ({report['runs']} runs, seed {report['seed']}, "
            f"{fidelity} sky)"
        ),
    )
    create_table_artifact(
        key="plan-monte-carlo-dv",
        table=[
            {"loop": loop, "manoeuvre": name, **figures}
            for loop, s in loops.items()
            for name, figures in s["dv_mps"].items()
        ],
        description=(
            f"Plan Monte Carlo {run_id}: dV spent [m/s], p50 / p95 / max over the runs that "
            "flew each manoeuvre, against the plan"
        ),
    )
    create_markdown_artifact(
        key="plan-monte-carlo-plots",
        markdown="\n\n".join(embedded_plots(report["plots"])),
        description=f"Plan Monte Carlo {run_id}: the landing footprint and the dV per manoeuvre",
    )


def _km(value: float | None) -> float | None:
    return None if value is None else round(value / 1e3, 3)


if __name__ == "__main__":
    import sys

    print(plan_monte_carlo_flow(sys.argv[1]))
