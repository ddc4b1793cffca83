"""Run directories of a Monte Carlo stored in batches: ``<root>/<run_id>/``.

Shared by the deorbit-burn Monte Carlo (:mod:`ovtraj.studies.deorbit_burn.store`) and the mission
plan's (:mod:`ovtraj.mission.montecarlo_store`). Layout::

    config.json                 what the runs fly (resolved), written once
    run.json                    run id, kind, created, code version, the kind's figures,
                                status, the size and SHA-256 of config.json
    runs/part-<k>.parquet       the batch starting at run k: its rows, exactly of the kind's
                                declared schema (NaN stored as null; wall times in the marker)
    batches/<k>.json            written last: that batch is complete; its run numbers, the
                                size and SHA-256 of its part (``"files"``) and the rows' wall
                                times (``"timing"``)
    summary.json                the report, replaced by every run of the Monte Carlo; derived
                                from the batches, so a subclass can build it again
    plots/<name>.png            pictures drawn from the batches, replaced with the summary;
                                their size and SHA-256 in run.json beside config.json's

The run id hashes what changes results (a subclass gives that content; the kind is added).
Files are written with :mod:`ovtraj.store.files` (temporary name, then linked into place; a stored
file is never overwritten), a batch counts only once its marker exists, and an interrupted
run resumes at the first missing batch. Every read is checked: a part's size, SHA-256 and
schema against its marker, ``config.json`` against ``run.json``; a missing or changed file
raises :class:`StoreError` naming it (the DoE store's conventions). With a store key
configured (``OVTRAJ_STORE_KEY``), ``run.json``, the batch markers and ``summary.json`` carry
an HMAC seal, checked on every read (:mod:`ovtraj.store.seals`).
"""

from __future__ import annotations

import datetime
import hashlib
import json
from pathlib import Path
from typing import Any, ClassVar

import pandas as pd
import pyarrow as pa

from ovtraj.store.environment_block import stamped
from ovtraj.store.files import (
    Digest,
    StoreError,
    marker_files,
    read_json,
    read_table,
    remove_file,
    write_bytes,
    write_json,
    write_parquet,
)
from ovtraj.store.products import directory_lock
from ovtraj.store.records import plain, table_from_frame
from ovtraj.store.seals import read_authenticated, write_sealed
from ovtraj.store.verification import VerifyReport

__all__ = [
    "PLOTS",
    "STORE_FORMAT",
    "SUMMARY",
    "BatchedRun",
    "StoreError",
    "consecutive_batches",
    "content_id",
    "part_name",
]

STORE_FORMAT = 2  # 2: file digests in run.json and the batch markers, checked on read
SUMMARY = "summary.json"
PLOTS = "plots"


def content_id(content: dict[str, Any]) -> str:
    """Content hash (16 hex digits) of a JSON-able mapping (keys sorted)."""
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def part_name(batch: int) -> str:
    return f"runs/part-{batch:05d}.parquet"


def consecutive_batches(todo: list[int], size: int) -> list[list[int]]:
    """Consecutive run numbers still to do, grouped ``size`` at a time (a gap starts a new
    group, so a batch's first run number names it whatever the batch size was)."""
    groups: list[list[int]] = []
    for run in todo:
        if groups and len(groups[-1]) < size and groups[-1][-1] == run - 1:
            groups[-1].append(run)
        else:
            groups.append([run])
    return groups


class BatchedRun:
    """One stored Monte Carlo run; a subclass names its kind, schema and row keys."""

    INFO = "run.json"
    KIND: ClassVar[str]
    SCHEMA: ClassVar[pa.Schema]  # the stored rows (no timing)
    KEYS: ClassVar[tuple[str, ...]]  # what identifies a row: ("run", ...)
    TIMING: ClassVar[tuple[str, ...]] = ("wall_time_s",)  # kept in the markers, not the parts

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.id = self.directory.name

    @classmethod
    def open_or_create(
        cls, root: str | Path, rid: str, config: dict[str, Any], info: dict[str, Any]
    ) -> BatchedRun:
        """The run ``rid`` under ``root``: reopened, or created with ``config`` stored and
        ``info`` (the kind's figures) in ``run.json``."""
        run = cls(Path(root) / rid)
        if (run.directory / cls.INFO).is_file():
            run.info  # noqa: B018 - refuses another store format, naming the file
            return run
        with directory_lock(run.directory):
            if (run.directory / cls.INFO).is_file():  # created meanwhile by another process
                return run
            path = run.directory / "config.json"
            remove_file(path)  # left by an interrupted creation
            digest = write_json(path, config)
            content = {
                "run_id": rid,
                "kind": cls.KIND,
                "format": STORE_FORMAT,
                "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                **info,
                "status": "created",
                "files": {"config.json": digest.to_json()},
            }
            write_sealed(run.directory / cls.INFO, stamped(content), replace=True)
        return run

    @property
    def info(self) -> dict[str, Any]:
        path = self.directory / self.INFO
        info = read_authenticated(path)
        if not isinstance(info, dict) or info.get("format") != STORE_FORMAT:
            found = info.get("format", 1) if isinstance(info, dict) else None
            raise StoreError(
                f"{path}: store format {found}; this version of ovtraj reads format "
                f"{STORE_FORMAT} (checksummed): run the Monte Carlo again"
            )
        if info.get("kind") != self.KIND:
            raise StoreError(f"{path}: a {info.get('kind')} run, not a {self.KIND} run")
        return info

    @property
    def config(self) -> dict[str, Any]:
        """What the runs fly (checked against ``run.json``)."""
        try:
            digest = Digest.from_json(self.info["files"]["config.json"])
        except (KeyError, TypeError, ValueError):
            raise StoreError(f"{self.directory / self.INFO}: no digest of config.json") from None
        return read_json(self.directory / "config.json", digest)

    def update_info(self, **changes: Any) -> None:
        """Merge ``changes`` into ``run.json`` (the run's mutable index, replaced atomically)."""
        write_sealed(self.directory / self.INFO, self.info | changes, replace=True)

    def _markers(self) -> dict[int, dict[str, Any]]:
        """Every complete batch's marker, by its first run number."""
        folder = self.directory / "batches"
        found = {}
        for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
            if not path.stem.isdigit():
                continue
            marker = read_authenticated(path)
            if not isinstance(marker, dict) or not isinstance(marker.get("files"), dict):
                raise StoreError(
                    f"{path}: not a batch marker of store format {STORE_FORMAT} (no file digests)"
                )
            marker_files(path, marker)  # names inside the run and usable digests, or refused
            found[int(path.stem)] = marker
        return found

    def done_runs(self) -> set[int]:
        """Run numbers stored by complete batches."""
        return {int(r) for marker in self._markers().values() for r in marker["runs"]}

    def write_batch(self, batch: int, frame: pd.DataFrame) -> bool:
        """Store a batch's rows (the schema's columns plus the timing ones); False (nothing
        written) if already stored.

        ``batch`` is the batch's first run number, so that batches of another size never
        collide with stored ones (only runs without a complete batch are submitted again).
        The part is written first, then its marker with the part's digest and the rows'
        wall times. A part without a marker (an interrupted write) is replaced.
        """
        marker = self.directory / "batches" / f"{batch:05d}.json"
        if marker.exists():
            return False
        frame = frame.reset_index(drop=True)
        keys = [frame[k] for k in self.KEYS]
        timing = {
            column: [
                [*(plain(v) for v in row[:-1]), float(row[-1])]
                for row in zip(*keys, frame[column], strict=True)
            ]
            for column in self.TIMING
            if column in frame
        }
        stored = frame.drop(columns=[c for c in self.TIMING if c in frame])
        table = table_from_frame(stored, self.SCHEMA, f"{self.KIND} runs")
        runs = sorted({int(r) for r in frame["run"]})
        # The batches folder is the lock of batch writes: a part and its marker are
        # written together, one writer at a time (a part takes milliseconds to write).
        with directory_lock(marker.parent):
            if marker.exists():  # stored meanwhile by another process
                return False
            part = self.directory / part_name(batch)
            remove_file(part)  # left by an interrupted write
            digest = write_parquet(part, table, self.SCHEMA)
            content = {
                "batch": batch,
                "runs": runs,
                "files": {part_name(batch): digest.to_json()},
                "timing": timing,  # [*keys, seconds] per row
            }
            write_sealed(marker, stamped(content))
        return True

    def results(self) -> pd.DataFrame:
        """Every row of the complete batches, sorted by the keys (every part checked)."""
        tables = []
        for marker in self._markers().values():
            for relative, digest in marker["files"].items():
                tables.append(
                    read_table(self.directory / relative, Digest.from_json(digest), self.SCHEMA)
                )
        if not tables:
            return self.SCHEMA.empty_table().to_pandas()
        frame = pa.concat_tables(tables).to_pandas()
        return frame.sort_values(list(self.KEYS), kind="stable").reset_index(drop=True)

    def timing(self) -> pd.DataFrame:
        """The stored rows' wall times (the keys, ``wall_time_s``) from the batch markers."""
        rows = [
            tuple(entry)
            for marker in self._markers().values()
            for entry in marker.get("timing", {}).get("wall_time_s", [])
        ]
        frame = pd.DataFrame(rows, columns=[*self.KEYS, "wall_time_s"])
        return frame.sort_values(list(self.KEYS), kind="stable").reset_index(drop=True)

    def write_summary(self, summary: dict[str, Any]) -> Path:
        """``summary.json``: the flow's report (plain JSON, NaN as null; sealed with a store
        key), replaced each run."""
        path = self.directory / SUMMARY
        write_sealed(path, summary, replace=True)
        return path

    def write_plots(self, pictures: dict[str, bytes]) -> list[Path]:
        """Store pictures drawn from the batches as ``plots/<name>`` (replaced, as the
        summary is, when drawn again) and list their digests in ``run.json``'s ``files``,
        which :meth:`verify` checks; returns their paths."""
        digests, paths = {}, []
        for name, payload in pictures.items():
            if "/" in name or "\\" in name or name in ("", ".", "..") or not name.isprintable():
                raise ValueError(f"{name!r}: not a plain file name")
            path = self.directory / PLOTS / name
            digests[f"{PLOTS}/{name}"] = write_bytes(path, payload, replace=True).to_json()
            paths.append(path)
        info = self.info
        self.update_info(files={**info.get("files", {}), **digests})
        return paths

    def stored_summary(self) -> dict[str, Any] | None:
        """``summary.json`` as written (its seal checked with a store key); None when there
        is none. :class:`StoreError` naming the file when it is not a sealed summary."""
        path = self.directory / SUMMARY
        if not path.is_file():
            return None
        summary = read_authenticated(path)
        if not isinstance(summary, dict):
            raise StoreError(f"{path}: not a JSON object")
        return summary

    def verify(self) -> VerifyReport:
        """Check every file of the run (like fsck): ``run.json``'s and each marker's seal
        (with a store key) and environment block, ``config.json`` and every part against
        their recorded size, SHA-256 and schema, ``summary.json``'s seal; files nothing lists
        are reported as uncovered."""
        report = VerifyReport(self.id)
        info_path = self.directory / self.INFO
        covered = {info_path}
        info = report.read_document(info_path)
        if info is None:
            return report
        if not isinstance(info, dict) or info.get("kind") != self.KIND:
            report.problems.append(f"{info_path}: not a {self.KIND} run")
            return report
        expected: list[tuple[Path, Any, pa.Schema | None]] = []
        files = info.get("files")
        listed = files.get("config.json") if isinstance(files, dict) else None
        expected.append((self.directory / "config.json", listed, None))
        try:  # the pictures run.json lists (names inside the run, usable digests)
            listing = marker_files(info_path, info) if isinstance(files, dict) else {}
            for relative, digest in listing.items():
                if relative.startswith(f"{PLOTS}/"):
                    expected.append((self.directory / relative, digest, None))
        except StoreError as err:
            report.problems.append(str(err))
        for path in sorted((self.directory / "batches").glob("*")):
            covered.add(path)
            marker = report.read_document(path)
            if marker is None:
                continue
            try:
                for relative, digest in marker_files(path, marker).items():
                    expected.append((self.directory / relative, digest, self.SCHEMA))
            except StoreError as err:
                report.problems.append(str(err))
        summary = self.directory / SUMMARY
        if summary.is_file():
            covered.add(summary)
            report.read_document(summary)
        for path, digest, schema in expected:
            covered.add(path)
            report.check_file(path, digest, schema)
        report.find_uncovered(self.directory, covered)
        return report
