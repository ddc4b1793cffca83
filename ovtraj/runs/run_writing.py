"""The writer's side of a stored run (:class:`ovtraj.runs.store.Run`): its locks, the
manifest's updates, the claim of a batch, the batch written and the parent's batches
adopted.

A process working on a run holds the run lock (shared) and claims each batch (exclusive
lock) before computing it, so two processes never compute a batch twice; a killed
process's locks are released by the kernel. The first writer of a run with no other
writer removes the temporary files that interrupted writes left. Files are written to a
temporary name and linked into place; the batch marker, written last, says the batch is
complete.
"""

from __future__ import annotations

import datetime
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ovtraj.interrupts import interrupt_of
from ovtraj.mission import STAGES, MissionRecord
from ovtraj.runs.batch_tables import batch_tables, part_name, result_rows
from ovtraj.runs.schemas import DATASETS
from ovtraj.store import locks
from ovtraj.store.backends import S3Path
from ovtraj.store.environment_block import stamped
from ovtraj.store.files import (
    TEMPORARY_SUFFIX,
    Digest,
    StoreError,
    make_folders,
    read_bytes,
    remove_file,
    remove_orphans,
    write_bytes,
    write_parquet,
)
from ovtraj.store.layout import MANIFEST
from ovtraj.store.seals import write_sealed

if TYPE_CHECKING:
    from ovtraj.runs.store import Run

__all__ = ["MANIFEST_LOCK_WAIT_S", "RunWriting", "utc_now"]

# Waits on the manifest lock: a holder only reads and rewrites one small file.
MANIFEST_LOCK_WAIT_S = 60.0


def utc_now() -> str:
    """The time now, UTC, to the second (ISO 8601): what a manifest records."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


class RunWriting:
    """The writing methods of :class:`~ovtraj.runs.store.Run`, which gives them the run's
    ``directory``, ``manifest``, ``markers()`` and ``is_stored(batch)``."""

    directory: Path | S3Path
    manifest: dict[str, Any]

    def lock_file(self, name: str) -> Path:
        """The run's lock ``name`` (``run``, ``manifest``, ``batch-<k>``)."""
        return self.directory / "locks" / f"{name}.lock"

    def in_use(self) -> bool:
        """Whether a process is working on the run (holds its run lock)."""
        return locks.held(self.lock_file("run"))

    def update_manifest(self, **changes: Any) -> bool:
        """Merge ``changes`` into the manifest; returns False (writes nothing) if none differ."""
        if all(self.manifest.get(k) == v for k, v in changes.items()):
            return False  # checked without the lock too: a read-only store is never locked
        with locks.hold(self.lock_file("manifest"), wait_s=MANIFEST_LOCK_WAIT_S):
            manifest = self.manifest
            if all(manifest.get(k) == v for k, v in changes.items()):
                return False
            write_sealed(self.directory / MANIFEST, manifest | changes, replace=True)
        return True

    @contextmanager
    def working(self) -> Iterator[list[Path]]:
        """Hold the run lock (shared) while this process writes batches.

        When no other process works on the run, the temporary files of interrupted
        writes are removed first (yielded). The manifest says ``running`` meanwhile;
        an exception (including an interrupt) marks it ``interrupted`` with the cause.
        """
        path = self.lock_file("run")
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
                        interrupted_utc=utc_now(),
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
        with locks.hold(self.lock_file(f"batch-{batch}"), wait_s=wait_s) as claimed:
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
        """Write the batch's Parquet files (:func:`.batch_tables.batch_tables`), then its
        marker: the files' digests and the batch's timing."""
        pairs = list(zip(sample_ids, records, strict=True))
        rows, stage_timing = result_rows(pairs)
        timing: dict[str, Any] = {
            "sample_wall_time_s": {str(sid): rec.wall_time_s for sid, rec in pairs},
            "stage_wall_time_s": stage_timing,
        }
        files: dict[str, Digest] = {
            relative: write_parquet(self.directory / relative, table, DATASETS[dataset])
            for relative, table, dataset in batch_tables(rows, pairs, batch, trajectory_steps)
        }
        content = {
            "batch": batch,
            "sample_ids": [int(s) for s in sample_ids],
            "files": {name: digest.to_json() for name, digest in sorted(files.items())},
            "timing": timing,
        }
        write_sealed(marker, stamped(content))


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
