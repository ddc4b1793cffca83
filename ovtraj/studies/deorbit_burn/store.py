"""Run directories of the deorbit-burn Monte Carlo: ``<root>/<run_id>/`` (``data/runs`` by default).

Layout::

    config.json                 resolved problem (every default and Earth constant filled in)
    run.json                    run id, kind, created, code version, runs, strategies, seed,
                                status, batches, the size and SHA-256 of config.json (not
                                ``manifest.json``: the DoE run catalog lists only its own runs)
    runs/part-<k>.parquet       the batch starting at run k: one row per run and strategy,
                                exactly of ``STORED_RUN_SCHEMA`` (NaN stored as null;
                                the rows' wall times are in the batch marker)
    batches/<k>.json            written last: that batch is complete; its run numbers and the
                                size and SHA-256 of its part (``"files"``)
    summary.json                dispersion statistics per strategy and the published figures
                                (a report, rewritten by every flow run)
    plots/*.png                 scatter and histograms of the entry errors per strategy

The run id hashes what changes results: the resolved config (without the execution settings
and the published figures, :func:`results_config`), the number of runs, the strategies, the
seed and the code version. Files are written with :mod:`ovtraj.store.files` (temporary name, then
linked into place; a stored file is never overwritten), a batch counts only once its marker
exists, and an interrupted run resumes at the first missing batch. Every read is checked: a
part's size, SHA-256 and schema against its marker, ``config.json`` against ``run.json``; a
missing or changed file raises :class:`StoreError` naming it. (The DoE store's conventions.)
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ovtraj.store.batched import STORE_FORMAT, BatchedRun, content_id, part_name
from ovtraj.store.files import StoreError
from ovtraj.studies.deorbit_burn.montecarlo import STORED_RUN_SCHEMA, TIMING_COLUMNS

__all__ = [
    "STORE_FORMAT",
    "MonteCarloRun",
    "StoreError",
    "monte_carlo_run_id",
    "part_name",
    "results_config",
]

RUN_KIND = "deorbit_monte_carlo"


# Settings that change how a Monte Carlo is executed or reported, not its rows (the number of
# runs, the strategies and the seed are hashed as the flow's own inputs).
_NOT_HASHED = ("runs", "seed", "strategies", "batch_size", "workers", "task_runner", "task_retries")


def results_config(resolved: dict[str, Any]) -> dict[str, Any]:
    """The part of a resolved problem that the rows depend on (no execution settings,
    no store path, no published figures)."""
    content = {k: v for k, v in resolved.items() if k != "published"}
    monte_carlo = dict(content.get("monte_carlo") or {})
    for key in (*_NOT_HASHED, "store"):
        monte_carlo.pop(key, None)
    content["monte_carlo"] = monte_carlo
    return content


def monte_carlo_run_id(
    resolved: dict[str, Any], runs: int, strategies: Sequence[int], seed: int, code: str
) -> str:
    """Content hash (16 hex digits) of what the run's results depend on.

    ``resolved`` is the whole resolved problem; :func:`results_config` picks what counts.
    """
    return content_id(
        {
            "kind": RUN_KIND,
            "config": results_config(resolved),
            "runs": int(runs),
            "strategies": [int(s) for s in strategies],
            "seed": int(seed),
            "code": code,
        }
    )


class MonteCarloRun(BatchedRun):
    """One stored deorbit-burn Monte Carlo run: a row per run and strategy."""

    KIND = RUN_KIND
    SCHEMA = STORED_RUN_SCHEMA
    KEYS = ("run", "strategy")
    TIMING = TIMING_COLUMNS

    @classmethod
    def create(
        cls,
        root: str | Path,
        *,
        resolved: dict[str, Any],
        runs: int,
        strategies: Sequence[int],
        seed: int,
        code: str,
    ) -> MonteCarloRun:
        """The run of these inputs: created, or the stored one (same id) reopened."""
        rid = monte_carlo_run_id(resolved, runs, strategies, seed, code)
        info = {
            "name": resolved.get("name"),
            "code_version": code,
            "runs": int(runs),
            "strategies": [int(s) for s in strategies],
            "seed": int(seed),
        }
        return cls.open_or_create(root, rid, resolved, info)
