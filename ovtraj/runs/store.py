"""The run store: one directory per DoE run under ``data/runs/<run_id>/``.

Layout::

    config.json                      resolved scenario (every default filled in)
    manifest.json                    run id, parent, created, code and dependency
                                     versions, seed, samples, status, counts
    samples.parquet                  sample_id and the design variables
    stages/<stage>/part-<k>.parquet  each stage's own rows, keyed by sample_id
    totals/part-<k>.parquet          the mission totals, keyed by sample_id
    trajectories/<stage>/part-<k>.parquet   the batch's trajectory tables, with sample_id
    batches/<k>.json                 written last: batch k is complete

The run id is a content hash of what changes results: the resolved config (which
holds the design bounds) without the settings that only say how the run executes
or what is done with it afterwards (``mission.doe``, ``mission.surrogate``,
``mission.optimize``, ``mission.verify``, ``mission.plan``), the seed, the samples
themselves, the parent run and the code version.

A child run (``parent``) starts with its parent's samples: the parent's stored
batches are adopted as the child's first batches (hard links where the file system
allows), so only the new samples are evaluated. Its manifest says how many batches
were adopted (``inherited_batches``); the rest of its samples are split after them.

Every file is written to a temporary name and renamed, and a batch
counts only once its marker exists, so an interrupted run resumes at the first
incomplete batch and a complete run is never recomputed. Stored files are never
overwritten; a file that cannot be read raises :class:`StoreError` naming it.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import platform
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.files import StoreError, atomic_bytes, atomic_parquet, read_json, read_parquet
from ovtraj.mission import STAGES, MissionRecord

__all__ = ["DEFAULT_ROOT", "Run", "RunStore", "StoreError", "run_id"]

DEFAULT_ROOT = Path("data") / "runs"
DEPENDENCIES = ("numpy", "scipy", "pandas", "pyarrow", "heyoka", "numba", "pydantic", "prefect")


# Settings that do not change a sample's results: how the DoE executes, and what
# the pipeline does with the results afterwards.
NON_RESULT_SETTINGS = ("doe", "surrogate", "optimize", "verify", "plan")


def results_config(resolved: dict[str, Any]) -> dict[str, Any]:
    """The resolved config without :data:`NON_RESULT_SETTINGS` (a copy)."""
    content = dict(resolved)
    mission = content.get("mission")
    if isinstance(mission, dict):
        content["mission"] = {k: v for k, v in mission.items() if k not in NON_RESULT_SETTINGS}
    return content


def samples_hash(samples: pd.DataFrame) -> str:
    """Hash of the design table (ids and values, bit for bit)."""
    table = samples.reset_index(drop=True)
    digest = hashlib.sha256()
    for column in sorted(table.columns):
        digest.update(column.encode("utf-8"))
        digest.update(np.ascontiguousarray(table[column].to_numpy(dtype=float)).tobytes())
    return digest.hexdigest()[:16]


def run_id(
    resolved: dict[str, Any], seed: int, samples: pd.DataFrame, code: str, parent: str | None
) -> str:
    content = {
        "config": results_config(resolved),
        "seed": seed,
        "samples": len(samples),
        "samples_hash": samples_hash(samples),
        "code": code,
        "parent": parent,
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def dependency_versions() -> dict[str, str]:
    versions = {"python": platform.python_version()}
    for name in DEPENDENCIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


class Run:
    """One stored run."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.id = directory.name

    # -- metadata -------------------------------------------------------------------------
    @property
    def manifest(self) -> dict[str, Any]:
        return read_json(self.directory / "manifest.json")

    def update_manifest(self, **changes: Any) -> None:
        manifest = self.manifest | changes
        atomic_bytes(self.directory / "manifest.json", json.dumps(manifest, indent=2).encode())

    @property
    def config(self) -> dict[str, Any]:
        return read_json(self.directory / "config.json")

    def samples(self) -> pd.DataFrame:
        return read_parquet(self.directory / "samples.parquet")

    # -- batches --------------------------------------------------------------------------
    def done_batches(self) -> set[int]:
        folder = self.directory / "batches"
        if not folder.is_dir():
            return set()
        return {int(p.stem) for p in folder.glob("*.json")}

    def batches(self, batch_size: int) -> list[tuple[int, pd.DataFrame]]:
        """Every batch of the run as (index, samples), stored or not.

        The batches adopted from the parent come first, as stored; the other samples
        follow in order, ``batch_size`` at a time.
        """
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        samples = self.samples()
        inherited = int(self.manifest.get("inherited_batches", 0))
        out: list[tuple[int, pd.DataFrame]] = []
        adopted: set[int] = set()
        for k in range(inherited):
            ids = read_json(self.directory / "batches" / f"{k}.json")["sample_ids"]
            adopted.update(ids)
            out.append((k, samples[samples["sample_id"].isin(ids)]))
        rest = samples[~samples["sample_id"].isin(adopted)]
        for j, start in enumerate(range(0, len(rest), batch_size)):
            out.append((inherited + j, rest.iloc[start : start + batch_size]))
        return out

    def pending_batches(self, batch_size: int) -> list[tuple[int, pd.DataFrame]]:
        done = self.done_batches()
        return [(k, batch) for k, batch in self.batches(batch_size) if k not in done]

    def adopt(self, parent: Run) -> int:
        """Take the parent's stored batches as this run's first ones; returns their count.

        Done once, when the child is created: files are hard-linked (copied where links
        are not possible) under renumbered names, the batch markers last, then the
        manifest records the count. Re-running it after an interruption is harmless.
        """
        if "inherited_batches" in self.manifest:
            return int(self.manifest["inherited_batches"])
        stored = sorted(parent.done_batches())
        for new, old in enumerate(stored):
            for folder in ("stages", "trajectories"):
                for stage in STAGES:
                    _link(
                        parent.directory / folder / stage / f"part-{old:05d}.parquet",
                        self.directory / folder / stage / f"part-{new:05d}.parquet",
                    )
            _link(
                parent.directory / "totals" / f"part-{old:05d}.parquet",
                self.directory / "totals" / f"part-{new:05d}.parquet",
            )
        for new, old in enumerate(stored):
            marker = read_json(parent.directory / "batches" / f"{old}.json")
            marker["batch"] = new
            atomic_bytes(self.directory / "batches" / f"{new}.json", json.dumps(marker).encode())
        self.update_manifest(inherited_batches=len(stored))
        return len(stored)

    def write_batch(
        self, batch: int, records: Iterable[MissionRecord], sample_ids: list[int]
    ) -> bool:
        """Store a batch's records; returns False (and writes nothing) if already stored."""
        marker = self.directory / "batches" / f"{batch}.json"
        if marker.exists():
            return False
        records = list(records)
        part = f"part-{batch:05d}.parquet"
        for stage in STAGES:
            rows = [
                {"sample_id": sid, **rec.stages[stage]}
                for sid, rec in zip(sample_ids, records, strict=True)
                if stage in rec.stages
            ]
            if rows:
                # Rows straight to Arrow: pandas' object-column conversion costs more
                # than the write itself on a batch of a few samples.
                path = self.directory / "stages" / stage / part
                atomic_parquet(path, pa.Table.from_pylist(rows))
            tables = [
                (sid, rec.trajectories[stage])
                for sid, rec in zip(sample_ids, records, strict=True)
                if len(rec.trajectories.get(stage, ()))
            ]
            if tables:
                # One concatenation, then the key column (a per-table assign copies each).
                frame = pd.concat([table for _, table in tables], ignore_index=True)
                frame["sample_id"] = np.repeat(
                    [sid for sid, _ in tables], [len(table) for _, table in tables]
                )
                atomic_parquet(self.directory / "trajectories" / stage / part, frame)
        totals = [
            {"sample_id": sid, **rec.totals()} for sid, rec in zip(sample_ids, records, strict=True)
        ]
        atomic_parquet(self.directory / "totals" / part, pa.Table.from_pylist(totals))
        atomic_bytes(marker, json.dumps({"batch": batch, "sample_ids": sample_ids}).encode())
        return True

    # -- reading ----------------------------------------------------------------------------
    def _dataset(self, folder: Path) -> pd.DataFrame:
        parts = sorted(folder.glob("part-*.parquet")) if folder.is_dir() else []
        if not parts:
            return pd.DataFrame()
        frame = pd.concat([read_parquet(p) for p in parts], ignore_index=True)
        return frame.sort_values("sample_id", kind="stable").reset_index(drop=True)

    def stage(self, name: str) -> pd.DataFrame:
        if name not in STAGES:
            raise ValueError(f"stage must be one of {', '.join(STAGES)}; got {name!r}")
        return self._dataset(self.directory / "stages" / name)

    def totals(self) -> pd.DataFrame:
        return self._dataset(self.directory / "totals")

    def trajectory(self, stage: str, sample_id: int) -> pd.DataFrame:
        """One sample's trajectory table of a stage (empty if the stage has none)."""
        for marker in sorted((self.directory / "batches").glob("*.json")):
            if sample_id in read_json(marker)["sample_ids"]:
                path = (
                    self.directory / "trajectories" / stage / f"part-{int(marker.stem):05d}.parquet"
                )
                if not path.is_file():
                    return pd.DataFrame()
                frame = read_parquet(path)
                rows = frame[frame["sample_id"] == sample_id]
                return rows.drop(columns="sample_id").reset_index(drop=True)
        raise StoreError(f"{self.directory}: sample {sample_id} is not stored")

    def summary(self) -> dict[str, Any]:
        manifest = self.manifest
        totals = self.totals()
        feasible = totals[totals["feasible"]] if len(totals) else totals
        summary = {
            "run_id": self.id,
            "parent": manifest.get("parent"),
            "created_utc": manifest.get("created_utc"),
            "status": manifest.get("status"),
            "scenario": manifest.get("scenario"),
            "samples": manifest.get("samples"),
            "evaluated": len(totals),
            "feasible": len(feasible),
        }
        for column in ("t_total_s", "dv_total_mps", "m_load_kg"):
            summary[f"min_{column}"] = float(feasible[column].min()) if len(feasible) else None
            summary[f"max_{column}"] = float(feasible[column].max()) if len(feasible) else None
        return summary


def _link(source: Path, target: Path) -> None:
    """``target`` becomes ``source``'s content: a hard link, or a copy across devices."""
    if not source.is_file() or target.exists():
        return
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, target)
    except OSError:
        atomic_bytes(target, source.read_bytes())


class RunStore:
    """All runs under a root directory (``data/runs`` by default)."""

    def __init__(self, root: str | Path = DEFAULT_ROOT) -> None:
        self.root = Path(root)

    def run(self, run_id: str) -> Run:
        directory = self.root / run_id
        if not (directory / "manifest.json").is_file():
            raise StoreError(f"{directory}: no such run (no manifest.json)")
        return Run(directory)

    def create(
        self,
        *,
        resolved: dict[str, Any],
        samples: pd.DataFrame,
        seed: int,
        code: str,
        parent: str | None = None,
        origin: str = "latin hypercube",
    ) -> Run:
        """The run of these inputs: created, or the stored one if it exists (same id)."""
        rid = run_id(resolved, seed, samples, code, parent)
        directory = self.root / rid
        if (directory / "manifest.json").is_file():
            run = Run(directory)
            stored = run.samples()
            if not stored.equals(samples.reset_index(drop=True)):
                raise StoreError(
                    f"{directory / 'samples.parquet'}: differs from this run's samples"
                )
            return run
        directory.mkdir(parents=True, exist_ok=True)
        atomic_bytes(directory / "config.json", json.dumps(resolved, indent=2).encode())
        atomic_parquet(directory / "samples.parquet", samples.reset_index(drop=True))
        manifest = {
            "run_id": rid,
            "parent": parent,
            "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "scenario": resolved.get("name"),
            "code_version": code,
            "dependencies": dependency_versions(),
            "seed": seed,
            "samples": len(samples),
            "origin": origin,
            "status": "created",
            "evaluated": 0,
            "feasible": 0,
        }
        atomic_bytes(directory / "manifest.json", json.dumps(manifest, indent=2).encode())
        return Run(directory)

    def catalog(self) -> list[dict[str, Any]]:
        """Every run's summary, newest first; an unreadable run is listed with its error."""
        if not self.root.is_dir():
            return []
        rows = []
        for directory in sorted(self.root.iterdir()):
            if not (directory / "manifest.json").is_file():
                continue
            try:
                rows.append(Run(directory).summary())
            except StoreError as err:
                rows.append({"run_id": directory.name, "status": f"error: {err}"})
        return sorted(rows, key=lambda r: r.get("created_utc") or "", reverse=True)
