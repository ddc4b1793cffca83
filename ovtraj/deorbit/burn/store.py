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
seed and the code version. Files are written with :mod:`ovtraj.files` (temporary name, then
linked into place; a stored file is never overwritten), a batch counts only once its marker
exists, and an interrupted run resumes at the first missing batch. Every read is checked: a
part's size, SHA-256 and schema against its marker, ``config.json`` against ``run.json``; a
missing or changed file raises :class:`StoreError` naming it. (The DoE store's conventions.)
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

from ovtraj.deorbit.burn.montecarlo import STORED_RUN_SCHEMA, TIMING_COLUMNS
from ovtraj.files import (
    Digest,
    StoreError,
    read_json,
    read_table,
    remove_file,
    write_json,
    write_parquet,
)
from ovtraj.products import directory_lock
from ovtraj.records import table_from_frame

__all__ = [
    "MonteCarloRun",
    "StoreError",
    "monte_carlo_run_id",
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


STORE_FORMAT = 2  # 2: file digests in run.json and the batch markers, checked on read


def part_name(batch: int) -> str:
    return f"runs/part-{batch:05d}.parquet"


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
            run.info  # noqa: B018 - refuses another store format, naming the file
            return run
        with directory_lock(run.directory):
            if (run.directory / cls.INFO).is_file():  # created meanwhile by another process
                return run
            run._create(rid, resolved, runs, strategies, seed, code)
        return run

    def _create(
        self,
        rid: str,
        resolved: dict[str, Any],
        runs: int,
        strategies: Sequence[int],
        seed: int,
        code: str,
    ) -> None:
        path = self.directory / "config.json"
        remove_file(path)  # left by an interrupted creation
        config = write_json(path, resolved)
        info = {
            "run_id": rid,
            "kind": RUN_KIND,
            "format": STORE_FORMAT,
            "name": resolved.get("name"),
            "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "code_version": code,
            "runs": int(runs),
            "strategies": [int(s) for s in strategies],
            "seed": int(seed),
            "status": "created",
            "files": {"config.json": config.to_json()},
        }
        write_json(self.directory / self.INFO, info, replace=True)

    @property
    def info(self) -> dict[str, Any]:
        path = self.directory / self.INFO
        info = read_json(path)
        if not isinstance(info, dict) or info.get("format") != STORE_FORMAT:
            found = info.get("format", 1) if isinstance(info, dict) else None
            raise StoreError(
                f"{path}: store format {found}; this version of ovtraj reads format "
                f"{STORE_FORMAT} (checksummed): run the Monte Carlo again"
            )
        return info

    @property
    def config(self) -> dict[str, Any]:
        """The resolved problem (checked against ``run.json``)."""
        try:
            digest = Digest.from_json(self.info["files"]["config.json"])
        except (KeyError, TypeError, ValueError):
            raise StoreError(f"{self.directory / self.INFO}: no digest of config.json") from None
        return read_json(self.directory / "config.json", digest)

    def update_info(self, **changes: Any) -> None:
        """Merge ``changes`` into ``run.json`` (the run's mutable index, replaced atomically)."""
        write_json(self.directory / self.INFO, self.info | changes, replace=True)

    def _markers(self) -> dict[int, dict[str, Any]]:
        """Every complete batch's marker, by its first run number."""
        folder = self.directory / "batches"
        found = {}
        for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
            if not path.stem.isdigit():
                continue
            marker = read_json(path)
            if not isinstance(marker, dict) or not isinstance(marker.get("files"), dict):
                raise StoreError(
                    f"{path}: not a batch marker of store format {STORE_FORMAT} (no file digests)"
                )
            found[int(path.stem)] = marker
        return found

    def done_runs(self) -> set[int]:
        """Run numbers stored by complete batches."""
        return {int(r) for marker in self._markers().values() for r in marker["runs"]}

    def write_batch(self, batch: int, frame: pd.DataFrame) -> bool:
        """Store a batch's rows (``RUN_SCHEMA``); False (nothing written) if already stored.

        The results go to the part (``STORED_RUN_SCHEMA``), the timing columns to the
        marker (:meth:`timing`).

        ``batch`` is the batch's first run number, so that batches of another size never
        collide with stored ones (only runs without a complete batch are submitted again).
        The part is written first, then its marker with the part's digest. A part without
        a marker (an interrupted write) is replaced.
        """
        marker = self.directory / "batches" / f"{batch:05d}.json"
        if marker.exists():
            return False
        frame = frame.reset_index(drop=True)
        timing = {
            column: [
                [int(r), int(s), float(t)]
                for r, s, t in zip(frame["run"], frame["strategy"], frame[column], strict=True)
            ]
            for column in TIMING_COLUMNS
            if column in frame
        }
        stored = frame.drop(columns=[c for c in TIMING_COLUMNS if c in frame])
        table = table_from_frame(stored, STORED_RUN_SCHEMA, "monte carlo runs")
        runs = sorted({int(r) for r in frame["run"]})
        # The batches folder is the lock of batch writes: a part and its marker are
        # written together, one writer at a time (a part takes milliseconds to write).
        with directory_lock(marker.parent):
            if marker.exists():  # stored meanwhile by another process
                return False
            part = self.directory / part_name(batch)
            remove_file(part)  # left by an interrupted write
            digest = write_parquet(part, table, STORED_RUN_SCHEMA)
            content = {
                "batch": batch,
                "runs": runs,
                "files": {part_name(batch): digest.to_json()},
                "timing": timing,  # [run, strategy, seconds] per row
            }
            write_json(marker, content)
        return True

    def results(self) -> pd.DataFrame:
        """Every row of the complete batches, sorted by run and strategy (every part checked)."""
        tables = []
        for marker in self._markers().values():
            for relative, digest in marker["files"].items():
                tables.append(
                    read_table(
                        self.directory / relative, Digest.from_json(digest), STORED_RUN_SCHEMA
                    )
                )
        if not tables:
            return STORED_RUN_SCHEMA.empty_table().to_pandas()
        frame = pa.concat_tables(tables).to_pandas()
        return frame.sort_values(["run", "strategy"], kind="stable").reset_index(drop=True)

    def timing(self) -> pd.DataFrame:
        """The stored rows' wall times (run, strategy, ``wall_time_s``) from the batch markers."""
        rows = [
            (run, strategy, seconds)
            for marker in self._markers().values()
            for run, strategy, seconds in marker.get("timing", {}).get("wall_time_s", [])
        ]
        frame = pd.DataFrame(rows, columns=["run", "strategy", "wall_time_s"])
        return frame.sort_values(["run", "strategy"], kind="stable").reset_index(drop=True)

    def write_summary(self, summary: dict[str, Any]) -> Path:
        """``summary.json``: the flow's report (plain JSON, NaN as null), replaced each run."""
        path = self.directory / "summary.json"
        write_json(path, summary, replace=True)
        return path
