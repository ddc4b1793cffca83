"""Stored Monte Carlo runs of a mission plan (:mod:`ovtraj.mission.montecarlo`).

A run directory of :class:`ovtraj.store.batched.BatchedRun`: ``config.json`` holds the plan
and the dispersions that count for results, each batch's part holds a row per run and loop
(``closed``, ``open``) of :data:`~ovtraj.mission.montecarlo.STORED_RUN_SCHEMA`. The run id
hashes the plan, the dispersions (not their ``execution`` settings), the number of runs, the
seed and the code version.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ovtraj.mission.montecarlo import STORED_RUN_SCHEMA
from ovtraj.store.batched import BatchedRun, content_id

__all__ = ["PlanMonteCarloRun", "plan_monte_carlo_id"]

RUN_KIND = "mission_monte_carlo"


def plan_monte_carlo_id(
    plan: dict[str, Any], dispersions: dict[str, Any], runs: int, seed: int, code: str
) -> str:
    """Content hash of what a plan Monte Carlo's rows depend on."""
    return content_id(
        {
            "kind": RUN_KIND,
            "plan": plan,
            "dispersions": dispersions,
            "runs": int(runs),
            "seed": int(seed),
            "code": code,
        }
    )


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
    ) -> PlanMonteCarloRun:
        """The run of these inputs: created, or the stored one (same id) reopened."""
        rid = plan_monte_carlo_id(plan, dispersions, runs, seed, code)
        info = {"code_version": code, "runs": int(runs), "seed": int(seed)}
        return cls.open_or_create(root, rid, {"plan": plan, "dispersions": dispersions}, info)
