"""The run store: one directory per DoE run under ``data/runs/<run_id>/``.

Layout::

    manifest.json                    run id, parent, created, code and dependency
                                     versions, seed, samples, status, counts, store
                                     format, the digests of config and samples, and
                                     the environment that created the run
    config.json                      resolved scenario (every default filled in)
    samples.parquet                  sample_id and the design variables
    stages/<stage>/part-<k>.parquet  each stage's own rows, keyed by sample_id
    totals/part-<k>.parquet          the mission totals, keyed by sample_id
    trajectories/<stage>/part-<k>.parquet   the batch's trajectory tables as stored
    batches/<k>.json                 written last: batch k is complete; its sample ids,
                                     the size and SHA-256 of every file of the batch,
                                     the batch's timing record, and the environment of
                                     the process that computed it
    locks/                           advisory locks of the processes working on the run

Every Parquet file has its dataset's declared schema (:mod:`ovtraj.runs.schemas`). The
environment blocks (:mod:`ovtraj.store.environment_block`: CPU, BLAS and its kernel,
library versions) are declared too, and are never in a data file nor in the run id: the
same inputs store the same data files on every machine (:mod:`ovtraj.environment`).

Guarantees:

- *Nothing stored is changed.* Files are written to a temporary name and linked into
  place; a stored file is never overwritten (only the manifest, the run's index, is
  replaced atomically, and never when nothing changed).
- *Every read is checked.* Readers take the files a batch marker lists, check their
  size, SHA-256 and schema, and refuse a changed file naming it (:class:`StoreError`);
  files without a marker (an interrupted batch) are never read. :meth:`Run.verify`
  checks a whole run.
- *Tamper evidence, with a key.* The checksums detect accidents only. With a store key
  configured (``OVTRAJ_STORE_KEY``), the manifest and every marker carry an HMAC seal,
  checked on every read: a marker rewritten without the key is refused as tampered
  (:mod:`ovtraj.store.seals`), and through its digests so is every data file it lists.
- *Concurrent writers.* A process working on a run holds the run lock (shared) and
  claims each batch (exclusive lock) before computing it, so two processes never
  compute a batch twice; a killed process's locks are released by the kernel. The
  first writer of a run with no other writer removes the temporary files that
  interrupted writes left. A run whose manifest says ``running`` while no process
  holds its lock was interrupted (:meth:`Run.status`).

The run id is a content hash of what changes results: the resolved config (which
holds the design bounds) without the settings that only say how the run executes
or what is done with it afterwards (``mission.doe``, ``mission.surrogate``,
``mission.optimize``, ``mission.verify``, ``mission.plan``), the seed, the samples
themselves, the parent run and the code version.

A child run (``parent``) starts with its parent's samples: the parent's stored
batches are adopted as the child's first batches (hard links where the file system
allows, their digests carried over), so only the new samples are evaluated. Its
manifest says how many batches were adopted (``inherited_batches``).
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.config import Scenario
from ovtraj.config.mission import DoeSettings
from ovtraj.environment import dependency_versions
from ovtraj.interrupts import interrupt_of
from ovtraj.mission import STAGES, MissionRecord
from ovtraj.runs.schemas import (
    DATASETS,
    SCHEMA_VERSION,
    TIMING_COLUMNS,
    stored_columns,
    stored_rows,
)
from ovtraj.store import locks, paths
from ovtraj.store.backends import S3Path, location
from ovtraj.store.environment_block import stamped
from ovtraj.store.files import (
    TEMPORARY_SUFFIX,
    Digest,
    StoreError,
    make_folders,
    marker_files,
    read_bytes,
    read_json,
    read_table,
    remove_file,
    remove_orphans,
    write_bytes,
    write_json,
    write_parquet,
)
from ovtraj.store.layout import ID_HEX_DIGITS, MANIFEST, is_id
from ovtraj.store.records import table_from_frame, table_from_rows
from ovtraj.store.seals import authenticated, read_authenticated, write_sealed
from ovtraj.store.verification import VerifyReport

__all__ = ["ID_HEX_DIGITS", "Run", "RunStore", "StoreError", "VerifyReport", "checked_id", "run_id"]

RUN_FILES = ("config.json", "samples.parquet")
# Waits on the manifest lock: a holder only reads and rewrites one small file.
MANIFEST_LOCK_WAIT_S = 60.0
# The layout's names and ids: ovtraj.store.layout (ids: :func:`checked_id` where they enter).
# Markers of a run's pipeline products (glob patterns under the run); each lists its
# files, relative to its own folder, with their digests.
PRODUCT_MARKERS = (
    "surrogates/*/meta.json",
    "fronts/*/meta.json",
    "pipeline/*/pipeline.json",
    "pipeline/*/plans/*.files.json",
)


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


def results_hash(resolved: dict[str, Any]) -> str:
    """Hash of :func:`results_config` (the runs of one scenario share it)."""
    text = json.dumps(results_config(resolved), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


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
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:ID_HEX_DIGITS]


def checked_id(value: Any, what: str = "run id") -> str:
    """``value`` if it is an id of the store (see :data:`ID_HEX_DIGITS`), else
    :class:`StoreError` naming it, escaped (a newline shows as ``\\n``) and cut
    (:func:`ovtraj.config.io_limits.echoed`)."""
    if not isinstance(value, str) or not is_id(value):
        from ovtraj.config.io_limits import echoed

        raise StoreError(
            f"{what} {echoed(repr(value))} is not an id of this store ({ID_HEX_DIGITS} "
            "lowercase hexadecimal digits, as `ovtraj runs` lists them)"
        )
    return value


def within_store(root: Path | S3Path, path: Path | S3Path, what: str) -> Path | S3Path:
    """``path`` if, its links followed, it lies inside the store ``root``, else
    :class:`StoreError` naming ``what`` (a file and its field): a path built from ids
    (:func:`checked_id`) cannot climb out of the store by its name, this refuses a folder
    of the store that is a link to elsewhere. An object store has no links."""
    if isinstance(root, S3Path) or isinstance(path, S3Path):
        return path
    if not path.resolve().is_relative_to(root.resolve()):
        from ovtraj.formatting import printable

        raise StoreError(f"{what}: {printable(str(path))} leads outside the store {root}")
    return path


def part_name(batch: int) -> str:
    return f"part-{batch:05d}.parquet"


def result_rows(
    pairs: list[tuple[int, MissionRecord]],
) -> tuple[dict[str, list[dict[str, Any]]], dict[str, dict[str, Any]]]:
    """The rows a batch of (sample id, record) pairs stores, by dataset (``stages/<stage>``,
    for the stages some sample reached, and ``totals``), and the timing columns taken out of
    the stage rows (stage -> sample id -> value; kept in the batch marker, never in a table)."""
    rows: dict[str, list[dict[str, Any]]] = {}
    timing: dict[str, dict[str, Any]] = {}
    for stage in STAGES:
        found = []
        for sid, rec in pairs:
            if stage not in rec.stages:
                continue
            row = dict(rec.stages[stage])
            for column in TIMING_COLUMNS:
                if column in row:
                    timing.setdefault(stage, {})[str(sid)] = row.pop(column)
            found.append({"sample_id": sid, **row})
        if found:
            rows[f"stages/{stage}"] = found
    rows["totals"] = [{"sample_id": sid, **rec.totals()} for sid, rec in pairs]
    return rows, timing


def _utc_now() -> str:
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


class Run:
    """One stored run."""

    def __init__(self, directory: Path | S3Path | str) -> None:
        self.directory = location(directory)
        self.id = self.directory.name

    @property
    def url(self) -> str:
        """The run's absolute location (a path, or an object-store URL): what a worker
        on another machine opens with :meth:`open`."""
        return str(self.directory.resolve())

    @classmethod
    def open(cls, url: str) -> Run:
        """The stored run at ``url`` (from :attr:`url`), checked like :meth:`RunStore.run`."""
        where = location(url)
        return RunStore(where.parent).run(where.name)

    # -- metadata -------------------------------------------------------------------------
    @property
    def manifest(self) -> dict[str, Any]:
        """The manifest, its format checked, and its seal when a store key is configured."""
        return authenticated(self.directory / MANIFEST, self._manifest_document())

    def _manifest_document(self) -> dict[str, Any]:
        """The manifest as stored (seal included, not checked), of this store format."""
        manifest = read_json(self.directory / MANIFEST)
        if not isinstance(manifest, dict):
            raise StoreError(f"{self.directory / MANIFEST}: not a run manifest")
        version = manifest.get("schema_version", 1)
        if version != SCHEMA_VERSION:
            raise StoreError(
                f"{self.directory / MANIFEST}: store format {version}; this version of ovtraj "
                f"reads format {SCHEMA_VERSION} (checksummed, declared schemas): run the DoE again"
            )
        return manifest

    def _file_digest(self, name: str) -> Digest:
        try:
            return Digest.from_json(self.manifest["files"][name])
        except (KeyError, TypeError, ValueError):
            raise StoreError(f"{self.directory / MANIFEST}: no digest of {name}") from None

    @property
    def config(self) -> dict[str, Any]:
        return read_json(self.directory / "config.json", self._file_digest("config.json"))

    def samples(self) -> pd.DataFrame:
        path = self.directory / "samples.parquet"
        return read_table(
            path, self._file_digest("samples.parquet"), DATASETS["samples"]
        ).to_pandas()

    def lineage(self) -> list[str]:
        """The run's ancestors, the root (a DoE run) first: recorded in the manifest when
        the run was created, else found by following the stored parents."""
        manifest = self.manifest
        recorded_in = f"{self.directory / MANIFEST}: lineage"
        if "lineage" in manifest:
            lineage = manifest["lineage"]
            if not isinstance(lineage, list):
                raise StoreError(f"{recorded_in} is not a list of run ids")
            return [checked_id(rid, recorded_in) for rid in lineage]
        chain: list[str] = []
        parent = manifest.get("parent")
        while parent and parent not in chain:
            chain.insert(0, checked_id(parent, f"{recorded_in}: parent"))
            try:
                parent = Run(self.directory.parent / parent).manifest.get("parent")
            except (StoreError, OSError):
                break  # a removed ancestor ends what can be followed
        return chain

    def update_manifest(self, **changes: Any) -> bool:
        """Merge ``changes`` into the manifest; returns False (writes nothing) if none differ."""
        if all(self.manifest.get(k) == v for k, v in changes.items()):
            return False  # checked without the lock too: a read-only store is never locked
        with locks.hold(self._lock("manifest"), wait_s=MANIFEST_LOCK_WAIT_S):
            manifest = self.manifest
            if all(manifest.get(k) == v for k, v in changes.items()):
                return False
            write_sealed(self.directory / MANIFEST, manifest | changes, replace=True)
        return True

    def _lock(self, name: str) -> Path:
        return self.directory / "locks" / f"{name}.lock"

    def in_use(self) -> bool:
        """Whether a process is working on the run (holds its run lock)."""
        return locks.held(self._lock("run"))

    def status(self) -> str:
        """The manifest's status; ``interrupted`` when it says running and nobody is."""
        status = self.manifest.get("status")
        if status == "running" and not self.in_use():
            return "interrupted"
        return status

    # -- batches --------------------------------------------------------------------------
    def markers(self) -> dict[int, dict[str, Any]]:
        """Every complete batch's marker, by batch index."""
        folder = self.directory / "batches"
        if not folder.is_dir():
            return {}
        found = {}
        for path in folder.glob("*.json"):
            if not path.stem.isdigit():
                continue
            marker = read_authenticated(path)
            if not isinstance(marker, dict) or not isinstance(marker.get("files"), dict):
                raise StoreError(f"{path}: not a batch marker of store format {SCHEMA_VERSION}")
            marker_files(path, marker)  # names inside the run and usable digests, or refused
            found[int(path.stem)] = marker
        return dict(sorted(found.items()))

    def done_batches(self) -> set[int]:
        folder = self.directory / "batches"
        if not folder.is_dir():
            return set()
        return {int(p.stem) for p in folder.glob("*.json") if p.stem.isdigit()}

    def is_stored(self, batch: int) -> bool:
        return (self.directory / "batches" / f"{batch}.json").is_file()

    def batch_size(self, doe: DoeSettings) -> int:
        """Samples a batch of this run: the size its batches were stored with (the
        manifest's ``batch_size``, or the largest stored batch of a run made before it was
        recorded), else ``doe``'s for its sample count (:meth:`DoeSettings.batch_size_for`).

        A batch's index names its samples only under one size: a run resumed under
        other settings keeps the size it started with."""
        manifest = self.manifest
        recorded = manifest.get("batch_size")
        if isinstance(recorded, int) and not isinstance(recorded, bool) and recorded >= 1:
            return recorded
        inherited = int(manifest.get("inherited_batches", 0))
        own = [len(m["sample_ids"]) for k, m in self.markers().items() if k >= inherited]
        return max(own) if own else doe.batch_size_for(len(self.samples()))

    def batches(self, batch_size: int) -> list[tuple[int, pd.DataFrame]]:
        """Every batch of the run as (index, samples), stored or not.

        The batches adopted from the parent come first, as stored; the other samples
        follow in order, ``batch_size`` at a time.
        """
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        samples = self.samples()
        inherited = int(self.manifest.get("inherited_batches", 0))
        markers = self.markers()
        out: list[tuple[int, pd.DataFrame]] = []
        adopted: set[int] = set()
        for k in range(inherited):
            if k not in markers:
                raise StoreError(f"{self.directory / 'batches' / f'{k}.json'}: missing")
            ids = markers[k]["sample_ids"]
            adopted.update(ids)
            out.append((k, samples[samples["sample_id"].isin(ids)]))
        rest = samples[~samples["sample_id"].isin(adopted)]
        for j, start in enumerate(range(0, len(rest), batch_size)):
            out.append((inherited + j, rest.iloc[start : start + batch_size]))
        return out

    def pending_batches(self, batch_size: int) -> list[tuple[int, pd.DataFrame]]:
        done = self.done_batches()
        return [(k, batch) for k, batch in self.batches(batch_size) if k not in done]

    @contextmanager
    def working(self) -> Iterator[list[Path]]:
        """Hold the run lock (shared) while this process writes batches.

        When no other process works on the run, the temporary files of interrupted
        writes are removed first (yielded). The manifest says ``running`` meanwhile;
        an exception (including an interrupt) marks it ``interrupted`` with the cause.
        """
        path = self._lock("run")
        removed: list[Path] = []
        with locks.hold(path) as alone:
            if alone:
                removed = remove_orphans(self.directory)
        with locks.hold(path, shared=True, wait_s=MANIFEST_LOCK_WAIT_S):
            previous = self.manifest.get("status")
            changes: dict[str, Any] = {"status": "running"}
            if previous in ("running", "interrupted") and alone:
                changes["resumed_after_interruption"] = (
                    int(self.manifest.get("resumed_after_interruption", 0)) + 1
                )
            self.update_manifest(**changes)
            try:
                yield removed
            except BaseException as err:
                # An interrupt wrapped by compiled code is the interrupt (ovtraj.interrupts).
                cause = interrupt_of(err) or err
                try:
                    self.update_manifest(
                        status="interrupted",
                        interrupted=f"{type(cause).__name__}: {cause}"[:500],
                        interrupted_utc=_utc_now(),
                    )
                except StoreError:
                    pass  # the cause is reported; the lock tells readers the run stopped
                if cause is not err:
                    raise cause from err
                raise

    @contextmanager
    def claim(self, batch: int, *, wait_s: float = 0.0) -> Iterator[bool]:
        """Claim batch ``batch`` for this process (see :func:`ovtraj.store.locks.hold`).

        Whoever holds the claim may compute and write the batch; it first clears what
        an interrupted attempt left of it (files that no marker covers).
        """
        with locks.hold(self._lock(f"batch-{batch}"), wait_s=wait_s) as claimed:
            if claimed and not self.is_stored(batch):
                self._clear_unmarked(batch)
            yield claimed

    def _batch_paths(self, batch: int) -> list[Path]:
        name = part_name(batch)
        paths = [self.directory / "totals" / name]
        for folder in ("stages", "trajectories"):
            paths += [self.directory / folder / stage / name for stage in STAGES]
        return paths

    def _clear_unmarked(self, batch: int) -> None:
        for path in self._batch_paths(batch):
            remove_file(path)

    def _clear_interrupted(self, batch: int) -> list[Path]:
        """Remove the temporary files an earlier holder of the batch's claim left (a
        worker killed mid-write); the caller holds the claim, so no live writer owns them."""
        removed = []
        for path in self._batch_paths(batch):
            if isinstance(path, S3Path) or not path.parent.is_dir():
                continue  # an object store's writes leave no temporary object
            for temporary in path.parent.glob(f".{path.name}.*{TEMPORARY_SUFFIX}"):
                if remove_file(temporary):
                    removed.append(temporary)
        return removed

    def adopt(self, parent: Run) -> int:
        """Take the parent's stored batches as this run's first ones; returns their count.

        Done once, when the child is created: files are hard-linked (copied where links
        are not possible) under renumbered names with their digests, the batch markers
        last, then the manifest records the count. Re-running it after an interruption
        is harmless.
        """
        if "inherited_batches" in self.manifest:
            return int(self.manifest["inherited_batches"])
        stored = parent.markers()
        for new, (old, marker) in enumerate(stored.items()):
            files = {}
            for relative, digest in marker["files"].items():
                target = relative.replace(part_name(old), part_name(new))
                _link(
                    parent.directory / relative, self.directory / target, Digest.from_json(digest)
                )
                files[target] = digest
            adopted = {**marker, "batch": new, "files": files, "adopted_from": [parent.id, old]}
            write_sealed(self.directory / "batches" / f"{new}.json", adopted)
        self.update_manifest(inherited_batches=len(stored))
        return len(stored)

    def write_batch(
        self,
        batch: int,
        records: Iterable[MissionRecord],
        sample_ids: list[int],
        *,
        trajectory_steps: dict[str, float],
    ) -> bool:
        """Store a batch's records; returns False (and writes nothing) if already stored.

        The caller holds the batch's claim (:meth:`claim`). ``trajectory_steps`` gives
        the stored sampling of each stage's trajectory (:func:`.schemas.stored_rows`).
        """
        marker = self.directory / "batches" / f"{batch}.json"
        if marker.exists():
            return False
        self._clear_interrupted(batch)
        try:
            self._write_batch(marker, batch, list(records), sample_ids, trajectory_steps)
        except BaseException:
            self._clear_unmarked(batch)  # frees the space a full disk needs for the manifest
            raise
        return True

    def _write_batch(
        self,
        marker: Path,
        batch: int,
        records: list[MissionRecord],
        sample_ids: list[int],
        trajectory_steps: dict[str, float],
    ) -> None:
        pairs = list(zip(sample_ids, records, strict=True))
        part = part_name(batch)
        files: dict[str, Digest] = {}
        rows, stage_timing = result_rows(pairs)
        timing: dict[str, Any] = {
            "sample_wall_time_s": {str(sid): rec.wall_time_s for sid, rec in pairs},
            "stage_wall_time_s": stage_timing,
        }

        def store(relative: str, table: pa.Table, dataset: str) -> None:
            files[relative] = write_parquet(self.directory / relative, table, DATASETS[dataset])

        for stage in STAGES:
            dataset = f"stages/{stage}"
            if dataset in rows:
                store(
                    f"{dataset}/{part}",
                    table_from_rows(rows[dataset], DATASETS[dataset], dataset),
                    dataset,
                )
            dataset = f"trajectories/{stage}"
            if dataset not in DATASETS:
                continue
            tables = [
                (sid, rec.trajectories[stage])
                for sid, rec in pairs
                if len(rec.trajectories.get(stage, ()))
            ]
            if tables:
                # One concatenation and one selection for the batch: per sample they cost
                # ~6 ms, two thirds of a sample's storing (docs/mission.md).
                columns = stored_columns(stage)
                frame = pd.concat([table for _, table in tables], ignore_index=True)[columns]
                ids = np.repeat([sid for sid, _ in tables], [len(t) for _, t in tables])
                keep = np.concatenate(
                    [stored_rows(t, stage, trajectory_steps[stage]) for _, t in tables]
                )
                frame = frame.loc[keep].reset_index(drop=True)
                frame.insert(0, "sample_id", ids[keep])
                store(
                    f"{dataset}/{part}",
                    table_from_frame(frame, DATASETS[dataset], dataset),
                    dataset,
                )
        store(
            f"totals/{part}",
            table_from_rows(rows["totals"], DATASETS["totals"], "totals"),
            "totals",
        )
        content = {
            "batch": batch,
            "sample_ids": [int(s) for s in sample_ids],
            "files": {name: digest.to_json() for name, digest in sorted(files.items())},
            "timing": timing,
        }
        write_sealed(marker, stamped(content))

    # -- reading ----------------------------------------------------------------------------
    def _dataset(self, name: str) -> pd.DataFrame:
        """Every marked part of a dataset, checked, in sample order."""
        schema = DATASETS[name]
        tables = []
        for k, marker in self.markers().items():
            relative = f"{name}/{part_name(k)}"
            digest = marker["files"].get(relative)
            if digest is None:
                continue  # no sample of the batch reached this stage
            tables.append(read_table(self.directory / relative, Digest.from_json(digest), schema))
        table = pa.concat_tables(tables) if tables else schema.empty_table()
        frame = table.to_pandas()
        return frame.sort_values("sample_id", kind="stable").reset_index(drop=True)

    def batch_totals(self, batch: int) -> pd.DataFrame:
        """The totals of one stored batch (checked)."""
        marker = self.markers().get(batch)
        if marker is None:
            raise StoreError(f"{self.directory / 'batches' / f'{batch}.json'}: missing")
        relative = f"totals/{part_name(batch)}"
        digest = Digest.from_json(marker["files"][relative])
        return read_table(self.directory / relative, digest, DATASETS["totals"]).to_pandas()

    def stage(self, name: str) -> pd.DataFrame:
        if name not in STAGES:
            raise ValueError(f"stage must be one of {', '.join(STAGES)}; got {name!r}")
        return self._dataset(f"stages/{name}")

    def totals(self) -> pd.DataFrame:
        return self._dataset("totals")

    def trajectory(self, stage: str, sample_id: int) -> pd.DataFrame:
        """One sample's trajectory table of a stage as stored (empty if the stage has none)."""
        dataset = f"trajectories/{stage}"
        for k, marker in self.markers().items():
            if sample_id not in marker["sample_ids"]:
                continue
            relative = f"{dataset}/{part_name(k)}"
            digest = marker["files"].get(relative)
            if dataset not in DATASETS or digest is None:
                return pd.DataFrame()
            frame = read_table(
                self.directory / relative, Digest.from_json(digest), DATASETS[dataset]
            ).to_pandas()
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
            "origin": manifest.get("origin"),
            "created_utc": manifest.get("created_utc"),
            "status": self.status(),
            "scenario": manifest.get("scenario"),
            "samples": manifest.get("samples"),
            "stored_batches": len(self.done_batches()),
            "evaluated": len(totals),
            "feasible": len(feasible),
        }
        for column in ("t_total_s", "dv_total_mps", "m_load_kg"):
            summary[f"min_{column}"] = float(feasible[column].min()) if len(feasible) else None
            summary[f"max_{column}"] = float(feasible[column].max()) if len(feasible) else None
        return summary

    # -- checking -----------------------------------------------------------------------------
    def verify(self) -> VerifyReport:
        """Check every file of the run against its recorded digest and schema (like fsck).

        Covered files: the manifest's (config, samples), each batch marker's, and those
        listed by the markers of the run's surrogate fits, fronts and pipeline results.
        Files that nothing lists are reported as uncovered (readers never use them). With
        a store key configured, the manifest and every marker whose seal is missing or wrong
        are reported as tampered (:mod:`ovtraj.store.seals`); the files such a marker lists are
        still checked against its digests, for accidents.
        """
        report = VerifyReport(self.id)
        covered = {self.directory / MANIFEST}
        expected: list[tuple[Path, Any, pa.Schema | None]] = []

        try:
            manifest = self._manifest_document()
        except StoreError as err:
            report.problems.append(str(err))
            return report
        report.check_document(self.directory / MANIFEST, manifest)
        recorded = manifest.get("files")
        recorded = recorded if isinstance(recorded, dict) else {}
        for name in RUN_FILES:
            schema = DATASETS["samples"] if name == "samples.parquet" else None
            expected.append((self.directory / name, recorded.get(name), schema))
        for path in sorted((self.directory / "batches").glob("*")):
            covered.add(path)
            try:
                marker = read_json(path)
                listed = marker["files"]
                if not isinstance(listed, dict):
                    raise TypeError
                report.check_document(path, marker)
                marker_files(path, marker)  # names inside the run and usable digests
            except StoreError as err:
                report.problems.append(str(err))
                continue
            except (KeyError, TypeError):
                report.problems.append(f"{path}: not a batch marker")
                continue
            for relative, digest in listed.items():
                dataset = relative.rsplit("/", 1)[0]
                expected.append((self.directory / relative, digest, DATASETS.get(dataset)))
        for pattern in PRODUCT_MARKERS:
            for marker_path in sorted(self.directory.glob(pattern)):
                covered.add(marker_path)
                try:
                    marker = read_json(marker_path)
                    listed = marker.get("files")
                except StoreError as err:
                    report.problems.append(str(err))
                    continue
                except AttributeError:
                    report.problems.append(f"{marker_path}: not a marker")
                    continue
                if not isinstance(listed, dict):
                    report.problems.append(f"{marker_path}: lists no file digests")
                    continue
                report.check_document(marker_path, marker)
                try:
                    marker_files(marker_path, marker)  # names inside its folder, usable digests
                except StoreError as err:
                    report.problems.append(str(err))
                    continue
                for relative, digest in listed.items():
                    expected.append((marker_path.parent / relative, digest, None))
        for path, digest, schema in expected:
            covered.add(path)
            report.check_file(path, digest, schema)
        report.find_uncovered(self.directory, covered)
        return report


def _link(source: Path | S3Path, target: Path | S3Path, digest: Digest) -> None:
    """``target`` becomes ``source``'s content (checked): a hard link, or a copy."""
    payload = read_bytes(source, digest)
    if isinstance(source, S3Path) or isinstance(target, S3Path):
        write_bytes(target, payload)  # an object store has no links
        return
    try:
        make_folders(target.parent)
        os.link(source, target)
        return
    except FileExistsError:
        read_bytes(target, digest)  # adopted by an earlier, interrupted attempt
        return
    except OSError:
        pass
    write_bytes(target, payload)


class RunStore:
    """All runs under a root directory (default: the workspace's ``runs/``, ovtraj.store.paths)."""

    def __init__(self, root: str | Path | None = None) -> None:
        self.root = paths.store_root(None, None, root)

    @classmethod
    def for_scenario(
        cls, scenario: Scenario, config: str | Path | None, override: str | Path | None = None
    ) -> RunStore:
        """The scenario's store: ``override`` (``--store``), else ``mission.doe.store``
        relative to the folder of the scenario file ``config``, else the workspace's
        ``runs/``."""
        configured = scenario.mission.doe.store if scenario.mission is not None else None
        base = paths.resolve(config, None).parent if config is not None else None
        return cls(paths.store_root(configured, base, override))

    def run_directories(self) -> list[Path | S3Path]:
        """Every run's directory (one with a manifest), in name order; a hidden one (a
        prune's ``.pruned-*`` being deleted) is not a run."""
        if not self.root.is_dir():
            return []
        return [
            d
            for d in sorted(self.root.iterdir())
            if not d.name.startswith(".") and (d / MANIFEST).is_file()
        ]

    def run(self, run_id: str) -> Run:
        """The stored run ``run_id`` (checked: :func:`checked_id`, then its manifest's format)."""
        directory = self.root / checked_id(run_id)
        if not (directory / MANIFEST).is_file():
            raise StoreError(f"{directory}: no such run (no {MANIFEST})")
        run = Run(directory)
        # Refuses another store format, naming the file; the seal is checked by every read of
        # the manifest, so that `verify` can open a tampered run to report it.
        run._manifest_document()
        return run

    def create(
        self,
        *,
        resolved: dict[str, Any],
        samples: pd.DataFrame,
        seed: int,
        code: str,
        parent: str | None = None,
        origin: str = "latin hypercube",
        lineage: list[str] | None = None,
    ) -> Run:
        """The run of these inputs: created, or the stored one if it exists (same id).

        ``lineage``: the parent's ancestors and the parent, root first (kept in the
        manifest so that a family is known when intermediate runs are pruned)."""
        rid = run_id(resolved, seed, samples, code, parent)
        directory = self.root / rid
        samples = samples.reset_index(drop=True)
        if (directory / MANIFEST).is_file():
            return self._reopen(rid, samples)
        run = Run(directory)
        with locks.hold(run._lock("manifest"), wait_s=MANIFEST_LOCK_WAIT_S):
            if (directory / MANIFEST).is_file():  # created meanwhile by another process
                return self._reopen(rid, samples)
            files = {
                "config.json": write_json(directory / "config.json", resolved),
                "samples.parquet": write_parquet(
                    directory / "samples.parquet",
                    table_from_frame(samples, DATASETS["samples"], "samples"),
                    DATASETS["samples"],
                ),
            }
            manifest = {
                "run_id": rid,
                "schema_version": SCHEMA_VERSION,
                "parent": parent,
                "lineage": list(lineage or ([parent] if parent else [])),
                "created_utc": _utc_now(),
                "scenario": resolved.get("name"),
                "results_hash": results_hash(resolved),
                "code_version": code,
                "dependencies": dependency_versions(),
                "seed": seed,
                "samples": len(samples),
                "origin": origin,
                "status": "created",
                "evaluated": 0,
                "feasible": 0,
                "files": {name: digest.to_json() for name, digest in files.items()},
            }
            write_sealed(directory / MANIFEST, stamped(manifest), replace=True)
        return run

    def latin_hypercube_run(
        self, resolved: dict[str, Any], seed: int, code: str, *, at_most: int
    ) -> Run | None:
        """The stored run with the most Latin-hypercube samples (at most ``at_most``) of this
        scenario, seed and code: a hypercube run or one extended by further hypercubes."""
        wanted = {"results_hash": results_hash(resolved), "seed": seed, "code_version": code}
        best: tuple[int, str, Run] | None = None
        for directory in self.run_directories():
            try:
                manifest = Run(directory).manifest
            except StoreError:
                continue  # not a run of this format: never extended
            if any(manifest.get(k) != v for k, v in wanted.items()):
                continue
            if manifest.get("origin") != "latin hypercube" or manifest["samples"] > at_most:
                continue
            key = (int(manifest["samples"]), manifest.get("created_utc") or "")
            if best is None or key > best[:2]:
                best = (*key, Run(directory))
        return best[2] if best is not None else None

    def _reopen(self, rid: str, samples: pd.DataFrame) -> Run:
        run = self.run(rid)
        if not run.samples().equals(samples):
            raise StoreError(
                f"{run.directory / 'samples.parquet'}: differs from this run's samples"
            )
        return run

    def catalog(self) -> list[dict[str, Any]]:
        """Every run's summary, newest first; an unreadable run is listed with its error."""
        if not self.root.is_dir():
            return []
        rows = []
        for directory in self.run_directories():
            try:
                rows.append(Run(directory).summary())
            except StoreError as err:
                rows.append({"run_id": directory.name, "status": f"error: {err}"})
        return sorted(rows, key=lambda r: r.get("created_utc") or "", reverse=True)
