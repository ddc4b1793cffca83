"""Run directories of the deorbit-burn Monte Carlo: ``<root>/<run_id>/`` (``data/runs`` by default).

Layout::

    config.json                 resolved problem (every default and Earth constant filled in)
    run.json                    run id, kind, created, code version, runs, strategies, seed,
                                status, batches (not ``manifest.json``: the DoE run catalog
                                lists only its own runs)
    runs/part-<k>.parquet       the batch starting at run k: one row per run and strategy
                                (``RUN_SCHEMA``)
    batches/<k>.json            written last: that batch is complete (its run numbers)
    summary.json                dispersion statistics per strategy and the published figures
    plots/*.png                 scatter and histograms of the entry errors per strategy

The run id hashes what changes results: the resolved config (without the execution settings
and the published figures, :func:`results_config`), the number of runs, the strategies, the
seed and the code version. Every file is written to a temporary name and
renamed (atomic on POSIX), a batch counts only once its marker exists, and a stored batch is
never overwritten, so an interrupted run resumes at the first missing batch. A file that
cannot be read raises :class:`StoreError` naming it. (The DoE store's conventions; both use
:mod:`ovtraj.files`.)
"""

from __future__ import annotations

import datetime
import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa

from ovtraj.deorbit.burn.montecarlo import RUN_SCHEMA
from ovtraj.files import StoreError, atomic_bytes, atomic_parquet, read_json, read_parquet

__all__ = [
    "DEFAULT_ROOT",
    "MonteCarloRun",
    "StoreError",
    "atomic_bytes",
    "atomic_parquet",
    "monte_carlo_run_id",
    "read_parquet",
    "results_config",
]

DEFAULT_ROOT = Path("data") / "runs"
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
    content = {
        "kind": RUN_KIND,
        "config": results_config(resolved),
        "runs": int(runs),
        "strategies": [int(s) for s in strategies],
        "seed": int(seed),
        "code": code,
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


class MonteCarloRun:
    """One stored Monte Carlo run."""

    INFO = "run.json"

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.id = self.directory.name

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
        run = cls(Path(root) / rid)
        if (run.directory / cls.INFO).is_file():
            return run
        run.directory.mkdir(parents=True, exist_ok=True)
        atomic_bytes(run.directory / "config.json", json.dumps(resolved, indent=2).encode())
        info = {
            "run_id": rid,
            "kind": RUN_KIND,
            "name": resolved.get("name"),
            "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "code_version": code,
            "runs": int(runs),
            "strategies": [int(s) for s in strategies],
            "seed": int(seed),
            "status": "created",
        }
        atomic_bytes(run.directory / cls.INFO, json.dumps(info, indent=2).encode())
        return run

    @property
    def info(self) -> dict[str, Any]:
        return read_json(self.directory / self.INFO)

    def update_info(self, **changes: Any) -> None:
        info = self.info | changes
        atomic_bytes(self.directory / self.INFO, json.dumps(info, indent=2).encode())

    def _markers(self) -> list[Path]:
        folder = self.directory / "batches"
        return sorted(folder.glob("*.json")) if folder.is_dir() else []

    def done_runs(self) -> set[int]:
        """Run numbers stored by complete batches."""
        return {int(r) for marker in self._markers() for r in read_json(marker)["runs"]}

    def write_batch(self, batch: int, frame: pd.DataFrame) -> bool:
        """Store a batch's rows (``RUN_SCHEMA``); False (nothing written) if already stored.

        ``batch`` is the batch's first run number, so that batches of another size never
        collide with stored ones (only runs without a complete batch are submitted again).
        """
        marker = self.directory / "batches" / f"{batch:05d}.json"
        if marker.exists():
            return False
        table = pa.Table.from_pandas(frame, schema=RUN_SCHEMA, preserve_index=False)
        atomic_parquet(self.directory / "runs" / f"part-{batch:05d}.parquet", table)
        runs = sorted({int(r) for r in frame["run"]})
        atomic_bytes(marker, json.dumps({"batch": batch, "runs": runs}).encode())
        return True

    def results(self) -> pd.DataFrame:
        """Every row of the complete batches, sorted by run and strategy."""
        parts = [
            self.directory / "runs" / f"part-{marker.stem}.parquet" for marker in self._markers()
        ]
        if not parts:
            return RUN_SCHEMA.empty_table().to_pandas()
        frame = pd.concat([read_parquet(p) for p in parts], ignore_index=True)
        return frame.sort_values(["run", "strategy"], kind="stable").reset_index(drop=True)

    def write_summary(self, summary: dict[str, Any]) -> Path:
        path = self.directory / "summary.json"
        atomic_bytes(path, json.dumps(summary, indent=2, default=_json_default).encode())
        return path


def _json_default(value: Any) -> Any:
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
