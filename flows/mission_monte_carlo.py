"""Flow: dispersed Monte Carlo of a mission plan, closed and open loop.

A thin adapter of the library's driver (:mod:`ovtraj.runs.plan_monte_carlo`, which
``ovtraj fly PLAN --monte-carlo N`` runs too, so both store the same run for the same
inputs):

1. read the plan and the dispersions (``configs/dispersions.yaml`` by default);
2. the driver creates (or reopens) the run directory ``<store>/<run_id>/``: the id hashes
   the plan, the dispersions that count for results, the number of runs, the seed and the
   code version;
3. it flies the runs the store does not hold yet, closed and open loop, here in batches of
   several runs per Prefect task on the configured task runner; each task is cached on its
   inputs and writes its own batch to Parquet;
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
    store_missing_batches,
)
from flows.runners import check_runner
from ovtraj.config.base import load_model
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.mission.high_fidelity import high_fidelity_settings
from ovtraj.mission.montecarlo_store import PlanMonteCarloRun
from ovtraj.mission.plan_store import read_plan
from ovtraj.paths import config_path
from ovtraj.runs.plan_monte_carlo import (
    PlanMonteCarloRequest,
    drive_plan_monte_carlo,
    store_of,
)
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
    logger = get_run_logger()
    prune_expired_results()
    mission_plan = read_plan(Path(plan))
    config_file = Path(dispersions) if dispersions else config_path("dispersions.yaml")
    config = load_model(DispersionsConfig, config_file)
    execution = config.execution
    chosen_runner = runner or execution.task_runner
    check_runner(chosen_runner, dask_address)
    n = runs or execution.runs
    seed = execution.seed if seed is None else int(seed)
    size = batch_size or execution.batch_size
    sky = high_fidelity_settings(mission_plan, fidelity, force_model)
    request = PlanMonteCarloRequest(
        plan=mission_plan,
        dispersions=config,
        runs=n,
        seed=seed,
        root=store_of(config, config_file, store),
        code=code_version(),
        batch_size=size,
        force_model=sky,
    )

    def opened(run: PlanMonteCarloRun, todo: int) -> None:
        labels = run_tags("plan-monte-carlo", mission_plan.scenario.get("name"), run.id)
        label_flow_run(f"plan-monte-carlo {run.id}", labels)
        logger.info("run %s: %d runs, %d to fly", run.id, n, todo)

    def fly(run: PlanMonteCarloRun, batches: list[list[int]]) -> dict[int, str]:
        """Each batch a cached Prefect task (store_missing_batches groups the runs into
        the same batches again)."""
        inputs = {
            "plan": mission_plan.to_dict(),
            "dispersions": config.model_dump(mode="json"),
            "run_url": str(run.directory.resolve()),
            "seed": seed,
            "force_model": None if sky is None else sky.model_dump(mode="json"),
        }
        return store_missing_batches(
            run,
            [k for runs in batches for k in runs],
            size,
            plan_mc_batch_task,
            lambda group: inputs,
            runner=chosen_runner,
            workers=workers or execution.workers,
            dask_address=dask_address,
            retries=execution.task_retries,
            timeout_per_run_s=TIMEOUTS.mission_mc_batch_per_run_s,
            deadline=deadline,
            limit=LIMIT,
        )

    report = drive_plan_monte_carlo(request, fly, opened=opened)
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
        description=f"Plan Monte Carlo {run_id} ({n} runs, seed {seed}, {fidelity} sky)",
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
    failed = report["failed_batches"]
    if failed:
        raise RuntimeError(f"run {run_id}: {len(failed)} batch(es) failed: {'; '.join(failed)}")
    return report


def _km(value: float | None) -> float | None:
    return None if value is None else round(value / 1e3, 3)


if __name__ == "__main__":
    import sys

    print(plan_monte_carlo_flow(sys.argv[1]))
