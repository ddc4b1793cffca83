"""Stored Monte Carlo runs of a mission plan (:mod:`ovtraj.mission.montecarlo`), and one
batch of them flown and stored, by whatever process runs it (:func:`store_plan_batch`).

A run directory of :class:`ovtraj.store.batched.BatchedRun`: ``config.json`` holds the plan
and the dispersions that count for results, each batch's part holds a row per run and loop
(``closed``, ``open``) of :data:`~ovtraj.mission.montecarlo_outcome.STORED_RUN_SCHEMA`. The run id
hashes the plan, the dispersions (not their ``execution`` settings), the number of runs, the
seed and the code version (and the force model of a high-fidelity closed loop).

``summary.json`` is derived from the stored batches (:meth:`PlanMonteCarloRun.report`):
a reader takes it only when it authenticates (with a store key), and otherwise builds the
report again from the sealed batches, so an edited summary is never shown.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ovtraj.config.base import model_from_dict
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.mission.montecarlo import simulate_batch
from ovtraj.mission.montecarlo_outcome import STORED_RUN_SCHEMA
from ovtraj.mission.montecarlo_statistics import loop_summaries, monte_carlo_report
from ovtraj.mission.plan import MissionPlan
from ovtraj.store.batched import BatchedRun, StoreError, content_id

__all__ = ["PlanMonteCarloRun", "plan_monte_carlo_id", "store_plan_batch"]

RUN_KIND = "mission_monte_carlo"

logger = logging.getLogger(__name__)


def plan_monte_carlo_id(
    plan: dict[str, Any],
    dispersions: dict[str, Any],
    runs: int,
    seed: int,
    code: str,
    force_model: dict[str, Any] | None = None,
) -> str:
    """Content hash of what a plan Monte Carlo's rows depend on; ``force_model`` (the
    high-fidelity sky of the closed loop) only when given, so that a J2 Monte Carlo's id
    does not depend on the high-fidelity settings."""
    content = {
        "kind": RUN_KIND,
        "plan": plan,
        "dispersions": dispersions,
        "runs": int(runs),
        "seed": int(seed),
        "code": code,
    }
    if force_model is not None:
        content["force_model"] = force_model
    return content_id(content)


class PlanMonteCarloRun(BatchedRun):
    """One stored plan Monte Carlo: a row per run and loop."""

    KIND = RUN_KIND
    SCHEMA = STORED_RUN_SCHEMA
    KEYS = ("run", "loop")

    @classmethod
    def create(
        cls,
        root: str | Path,
        *,
        plan: dict[str, Any],
        dispersions: dict[str, Any],
        runs: int,
        seed: int,
        code: str,
        force_model: dict[str, Any] | None = None,
    ) -> PlanMonteCarloRun:
        """The run of these inputs: created, or the stored one (same id) reopened; with
        ``force_model`` the closed loop flies under the high-fidelity sky."""
        rid = plan_monte_carlo_id(plan, dispersions, runs, seed, code, force_model)
        info = {"code_version": code, "runs": int(runs), "seed": int(seed)}
        config = {"plan": plan, "dispersions": dispersions}
        if force_model is not None:
            config["force_model"] = force_model
            info["fidelity"] = "high"
        return cls.open_or_create(root, rid, config, info)

    def report(self) -> dict[str, Any]:
        """The Monte Carlo's report from what is stored (the sealed ``run.json``, config and
        batches): both loops' statistics, ``runs`` asked and ``stored_runs``, ``status``
        complete when every run is stored: what ``summary.json`` holds. What one pass
        adds (``simulated_runs``, the run's ``directory``) is the driver's
        (:mod:`ovtraj.runs.plan_monte_carlo`)."""
        info = self.info
        config = self.config
        plan = MissionPlan.model_validate(config["plan"])
        loops = loop_summaries(plan, self.results())
        runs, stored = int(info["runs"]), len(self.done_runs())
        return {
            "run_id": self.id,
            "runs": runs,
            "stored_runs": stored,
            "seed": int(info["seed"]),
            "status": "complete" if stored >= runs else "incomplete",
            **monte_carlo_report(
                loops["closed"], loops["open"], int(info["seed"]), plan.terminal.stated_miss_m
            ),
            "fidelity": info.get("fidelity", "j2"),
        }

    def summary(self) -> dict[str, Any]:
        """``summary.json`` when it authenticates, else :meth:`report` built again from the
        stored batches (a warning names the refused file): the figures a reader shows."""
        try:
            stored = self.stored_summary()
        except StoreError as err:
            logger.warning("%s; the report is built again from the stored batches", err)
            stored = None
        return self.report() if stored is None else stored


def store_plan_batch(
    plan: dict[str, Any],
    dispersions: dict[str, Any],
    run_url: str,
    batch: int,
    runs: list[int],
    seed: int,
    force_model: dict[str, Any] | None = None,
    on_run: Callable[[], None] | None = None,
) -> dict[str, Any]:
    """Fly ``runs`` closed and open loop (:func:`~ovtraj.mission.montecarlo.simulate_batch`)
    and store them as the batch ``batch`` (its first run number) of the run at ``run_url``
    (absolute); a small summary back (``batch``, ``runs``, ``rows``, ``failed``,
    ``wall_time_s``); ``on_run()`` after each run.

    The inputs are plain: the plan (``MissionPlan.to_dict()``), the dispersions and the
    force model of a high-fidelity closed loop (their JSON dumps). The job of every batch
    of a plan's Monte Carlo (:class:`~ovtraj.store.monte_carlo.BatchJob`), wherever it
    runs: the command's process, a pool's process, a Dask worker, a Prefect task."""
    start = time.perf_counter()
    frame = simulate_batch(
        MissionPlan.model_validate(plan),
        model_from_dict(DispersionsConfig, dispersions, "the run's dispersions"),
        runs,
        seed,
        None
        if force_model is None
        else model_from_dict(ForceModelSettings, force_model, "the run's force model"),
        on_run,
    )
    PlanMonteCarloRun(Path(run_url)).write_batch(batch, frame)
    return {
        "batch": batch,
        "runs": len(runs),
        "rows": len(frame),
        "failed": int((~frame["landed"].astype(bool)).sum()),
        "wall_time_s": time.perf_counter() - start,
    }
