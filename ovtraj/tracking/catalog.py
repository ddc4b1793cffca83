"""The store's catalog: one Parquet table, a row per run, pipeline result, plan and plan
Monte Carlo, with their key figures and tags, queried with SQL (DuckDB).

Layout, beside the runs (``<store>/catalog/``)::

    catalog.parquet    the rows, exactly :data:`SCHEMA`; derived, so replaced (atomically)
    catalog.json       its size and SHA-256 (checked on every read), rows, schema version
    tags/<id>.json     an item's tags: metadata beside the item, never in its checksummed
                       files (``ovtraj tag``)
    catalog.lock       held while the catalog is refreshed

The catalog is derived from the stored documents (the runs' manifests, the pipeline
summaries, the plans' markers, the Monte Carlo runs' ``run.json`` and ``summary.json``):
:func:`refresh` reads each one and rebuilds the row of a document whose SHA-256 changed
(``source_sha256``), keeps the others, drops the rows of documents gone (a pruned run), so
a refresh after each write gives the same table as :func:`refresh` with ``rebuild`` from
nothing (``ovtraj catalog --rebuild``, also done when the catalog is missing or damaged).
The rows hold no wall-clock or host data but the documents' own ``created_utc``.

Ids: a run's, a pipeline result's (``ovtraj runs``), a plan's (the first 16 hex digits of the
SHA-256 of its canonical JSON: the id the plan Monte Carlo run records), a Monte Carlo run's.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import resource
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from operator import itemgetter
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ovtraj.formatting import printable
from ovtraj.store import locks
from ovtraj.store.backends import S3Path, location
from ovtraj.store.batched import SUMMARY, content_id
from ovtraj.store.files import (
    Digest,
    StoreError,
    json_data,
    make_folders,
    parquet_bytes,
    read_bytes,
    read_json,
    write_bytes,
)
from ovtraj.store.layout import (
    MANIFEST,
    PIPELINE_DIR,
    PIPELINE_MARKER,
    PLAN_MARKER_SUFFIX,
    PLANS_DIR,
    is_id,
)
from ovtraj.store.seals import authenticated, read_authenticated, write_sealed
from ovtraj.store.verification import VerifyReport
from ovtraj.tracking.figures import element_set_epoch, target_name

__all__ = [
    "CATALOG_DIR",
    "KINDS",
    "SCHEMA",
    "Catalog",
    "catalog_settings",
    "plan_file",
    "plan_id",
    "query",
    "read_tags",
    "refresh",
    "set_tags",
    "verify_catalog",
]

CATALOG_DIR = "catalog"
CATALOG_FILE = "catalog.parquet"
CATALOG_MARKER = "catalog.json"
STAMPS_FILE = "stamps.json"
TAGS_DIR = "tags"
SCHEMA_VERSION = 1
KINDS = ("run", "pipeline", "plan", "monte_carlo")

# Every column, its type and unit (units in the names, docs/conventions.md).
SCHEMA = pa.schema(
    [
        pa.field("kind", pa.string(), nullable=False),  # run | pipeline | plan | monte_carlo
        pa.field("id", pa.string(), nullable=False),
        pa.field("source", pa.string(), nullable=False),  # the document, relative to the store
        pa.field("source_sha256", pa.string(), nullable=False),
        pa.field("created_utc", pa.string()),
        pa.field("scenario", pa.string()),
        pa.field("target", pa.string()),
        pa.field("element_set_epoch_utc", pa.string()),
        pa.field("code_version", pa.string()),
        pa.field("status", pa.string()),
        pa.field("error", pa.string()),  # why the document could not be read
        pa.field("family", pa.string()),  # a run's root run
        pa.field("depth", pa.int32()),  # 0 for a family's root
        pa.field("parent", pa.string()),
        pa.field("doe_run", pa.string()),
        pa.field("run_id", pa.string()),  # a pipeline's or plan's final run
        pa.field("pipeline_id", pa.string()),
        pa.field("plan_id", pa.string()),  # a Monte Carlo's plan
        pa.field("origin", pa.string()),
        pa.field("samples", pa.int64()),
        pa.field("evaluated", pa.int64()),
        pa.field("feasible", pa.int64()),
        pa.field("front_points", pa.int64()),
        pa.field("hypervolume", pa.float64()),
        pa.field("converged", pa.bool_()),
        pa.field("stop_reason", pa.string()),
        pa.field("launch_epoch_utc", pa.string()),  # the plan's drop
        pa.field("t_total_s", pa.float64()),
        pa.field("dv_total_mps", pa.float64()),
        pa.field("m_load_kg", pa.float64()),
        pa.field("landing_miss_m", pa.float64()),
        pa.field("mc_runs", pa.int64()),
        pa.field("mc_landing_miss_p95_m", pa.float64()),
        pa.field("mc_dv_margin_p95_mps", pa.float64()),
        pa.field("tags", pa.string(), nullable=False),  # JSON object, keys sorted
    ]
)
_COLUMNS = SCHEMA.names
_TAG_KEY = re.compile(r"[A-Za-z][A-Za-z0-9_.-]*")


def catalog_settings() -> Any:
    """``catalog`` of configs/orchestration.yaml."""
    from ovtraj.config.orchestration import load_orchestration

    return load_orchestration().catalog


def plan_id(plan: dict[str, Any]) -> str:
    """A plan's id: 16 hex digits of the SHA-256 of its canonical JSON (the content the
    plan Monte Carlo's run records, :mod:`ovtraj.mission.montecarlo_store`)."""
    return content_id(plan)


def plan_file(store_root: Path | S3Path, source: str) -> Path | S3Path:
    """The plan JSON of a plan row's ``source`` (its marker ``<name>.files.json``)."""
    marker = location(store_root) / source
    return marker.with_name(marker.name[: -len(PLAN_MARKER_SUFFIX)] + ".json")


@dataclass
class Catalog:
    """The catalog as read or refreshed: ``frame`` (columns of :data:`SCHEMA`, Python
    values, None for missing), where it is, what the refresh did; :attr:`rows` the same
    as dicts."""

    frame: pd.DataFrame
    path: Path | S3Path
    written: bool = False
    rebuilt_because: str | None = None
    _rows: list[dict[str, Any]] | None = None

    @property
    def rows(self) -> list[dict[str, Any]]:
        if self._rows is None:
            self._rows = self.frame.to_dict(orient="records")
        return self._rows

    def item(self, item_id: str) -> pd.Series:
        """The row of ``item_id`` (:class:`StoreError` naming it when the store has none)."""
        checked_id(item_id, "id")
        rows = self.frame[self.frame["id"] == item_id]
        if not len(rows):
            raise StoreError(
                f"{item_id}: no run, pipeline result, plan or Monte Carlo of this id in "
                f"{self.path.parent.parent} (`ovtraj runs` lists them)"
            )
        return rows.iloc[0]


# --- reading the stored documents -----------------------------------------------------


def _target_columns(scenario: dict[str, Any]) -> dict[str, Any]:
    """The target's name and element-set epoch of a resolved scenario (every kind's row)."""
    return {"target": target_name(scenario), "element_set_epoch_utc": element_set_epoch(scenario)}


# Columns that name another item: ids read from a stored document, so checked like an id
# typed on the command line before a reader follows them (`ovtraj runs`, `history`).
_ID_COLUMNS = ("family", "parent", "doe_run", "run_id", "pipeline_id", "plan_id")


def _row(kind: str, item_id: str, source: str, digest: str, **values: Any) -> dict[str, Any]:
    for column in _ID_COLUMNS:
        value = values.get(column)
        if value is not None and not (isinstance(value, str) and is_id(value)):
            raise ValueError(f"{column} {printable(str(value))[:40]!r} is not an id")
    row: dict[str, Any] = dict.fromkeys(_COLUMNS)
    row.update(kind=kind, id=item_id, source=source, source_sha256=digest, tags="{}")
    row.update(values)
    return row


def checked_id(value: Any, what: str = "id") -> str:
    """``value`` if it is an id of the store, else :func:`ovtraj.runs.ids.checked_id`'s
    error (loaded only then: the run store's code imports the mission chain, ~1.4 s)."""
    if isinstance(value, str) and is_id(value):
        return value
    from ovtraj.runs.ids import checked_id as checked

    return checked(value, what)


def _run_row(directory: Path | S3Path, source: str, digest: str) -> dict[str, Any]:
    from ovtraj.runs.store import Run

    run = Run(directory)
    manifest = run.manifest  # checked: format, seal (with a store key)
    config = run.config
    lineage = list(manifest.get("lineage") or [])
    return _row(
        "run",
        run.id,
        source,
        digest,
        created_utc=manifest.get("created_utc"),
        scenario=manifest.get("scenario"),
        **_target_columns(config),
        code_version=manifest.get("code_version"),
        status=manifest.get("status"),
        family=lineage[0] if lineage else run.id,
        depth=len(lineage),
        parent=manifest.get("parent"),
        run_id=run.id,
        origin=manifest.get("origin"),
        samples=manifest.get("samples"),
        evaluated=manifest.get("evaluated"),
        feasible=manifest.get("feasible"),
    )


def _pipeline_row(
    marker: Path | S3Path, source: str, digest: str, payload: bytes, run: dict[str, Any]
) -> dict[str, Any]:
    summary = authenticated(marker, json_data(payload))
    if not isinstance(summary, dict):
        raise ValueError("not a JSON object")
    return _row(
        "pipeline",
        checked_id(summary.get("pipeline_id"), "pipeline id"),
        source,
        digest,
        created_utc=summary.get("created_utc"),
        scenario=summary.get("scenario"),
        target=run.get("target"),
        element_set_epoch_utc=run.get("element_set_epoch_utc"),
        code_version=summary.get("code"),
        status="converged" if summary.get("converged") else "not converged",
        doe_run=summary.get("doe_run"),
        run_id=summary.get("final_run"),
        pipeline_id=summary.get("pipeline_id"),
        front_points=summary.get("front_points"),
        hypervolume=summary.get("hypervolume"),
        converged=summary.get("converged"),
        stop_reason=summary.get("stop_reason"),
    )


def _plan_row(
    marker: Path | S3Path, source: str, digest: str, payload: bytes, pipeline: dict[str, Any]
) -> dict[str, Any]:
    files = authenticated(marker, json_data(payload))
    name = marker.name[: -len(PLAN_MARKER_SUFFIX)]
    recorded = (files.get("files") or {}).get(f"{name}.json") if isinstance(files, dict) else None
    if recorded is None:
        raise ValueError(f"{marker.name} lists no {name}.json")
    plan = read_json(marker.parent / f"{name}.json", Digest.from_json(recorded))
    return _row("plan", plan_id(plan), source, digest, **plan_values(plan, pipeline))


def plan_values(plan: dict[str, Any], pipeline: dict[str, Any] | None = None) -> dict[str, Any]:
    """A plan's catalog columns (its pipeline's row gives the creation time)."""
    scenario = plan.get("scenario") or {}
    source = plan.get("source") or {}
    totals = plan.get("totals") or {}
    return {
        "created_utc": (pipeline or {}).get("created_utc"),
        "scenario": scenario.get("name"),
        **_target_columns(scenario),
        "code_version": plan.get("code_version"),
        "doe_run": source.get("doe_run"),
        "run_id": source.get("run_id"),
        "pipeline_id": source.get("pipeline_id"),
        "launch_epoch_utc": (plan.get("launch") or {}).get("drop_epoch_utc"),
        "t_total_s": totals.get("t_total_s"),
        "dv_total_mps": totals.get("dv_total_mps"),
        "m_load_kg": totals.get("m_load_kg"),
        "landing_miss_m": (plan.get("terminal") or {}).get("miss_distance_m"),
    }


def _monte_carlo_row(directory: Path | S3Path, source: str, digest: str) -> dict[str, Any] | None:
    """A plan Monte Carlo run's row; None for another kind of batched run."""
    from ovtraj.mission.montecarlo_store import RUN_KIND, PlanMonteCarloRun

    kind = read_json(directory / "run.json")
    if not isinstance(kind, dict) or kind.get("kind") != RUN_KIND:
        return None
    run = PlanMonteCarloRun(directory)
    info = run.info  # checked: format, kind, seal (with a store key)
    config = run.config
    plan = config.get("plan") if isinstance(config, dict) else None
    if not isinstance(plan, dict):
        raise ValueError("config.json holds no plan")
    # The summary as sealed, or built again from the sealed batches: never an edited one.
    summary = run.summary() if (directory / SUMMARY).is_file() else {}
    scenario = plan.get("scenario") or {}
    total = ((summary.get("dv_mps") or {}).get("total")) or {}
    return _row(
        "monte_carlo",
        directory.name,
        source,
        digest,
        created_utc=info.get("created_utc"),
        scenario=scenario.get("name"),
        **_target_columns(scenario),
        code_version=info.get("code_version"),
        status=summary.get("status") or info.get("status"),
        plan_id=plan_id(plan),
        pipeline_id=(plan.get("source") or {}).get("pipeline_id"),
        mc_runs=summary.get("runs"),
        mc_landing_miss_p95_m=(summary.get("landing_miss_m") or {}).get("p95"),
        mc_dv_margin_p95_mps=total.get("p95_minus_planned"),
    )


# A document's stamp: (size [B], modification time [ns], inode) of its files, kept in
# ``stamps.json`` beside the catalog (not in it: host data). A document whose stamp is the
# one recorded is not read again; any other is read and its SHA-256 decides.
Stamp = list[int]


def _stamp(paths: list[str]) -> Stamp | None:
    stamp: Stamp = []
    for path in paths:
        try:
            found = os.stat(path, follow_symlinks=False)
        except OSError:
            return None
        stamp += [found.st_size, found.st_mtime_ns, found.st_ino]
    return stamp


def _local_sources(root: Path) -> Iterator[tuple[str, str, list[str]]]:
    """(kind, item directory relative to ``root``, its document files) of every stored item
    of a local store, in name order (text paths, ``os.scandir`` and ``os.stat``: pathlib's
    objects cost more than the walk itself at 10,000 runs)."""
    base = str(root)
    try:
        with os.scandir(base) as entries:
            names = sorted(e.name for e in entries if is_id(e.name) and e.is_dir())
    except FileNotFoundError:
        return
    for name in names:
        run = f"{base}/{name}"
        # A stat or two a run, not a listing: a run's folder holds a dozen entries.
        if os.path.isfile(f"{run}/{MANIFEST}"):
            yield "run", name, [f"{run}/{MANIFEST}"]
            yield from _local_results(name, f"{run}/{PIPELINE_DIR}")
        elif os.path.isfile(f"{run}/run.json"):
            documents = [f"{run}/run.json"]
            if os.path.isfile(f"{run}/summary.json"):
                documents.append(f"{run}/summary.json")
            yield "monte_carlo", name, documents


def _local_results(run: str, folder: str) -> Iterator[tuple[str, str, list[str]]]:
    """The pipeline results and plans of one run (:func:`_local_sources`)."""
    try:
        with os.scandir(folder) as entries:
            results = sorted(e.name for e in entries if e.is_dir())
    except (FileNotFoundError, NotADirectoryError):
        return
    for result in results:
        marker = f"{folder}/{result}/{PIPELINE_MARKER}"
        if not os.path.isfile(marker):
            continue
        relative = f"{run}/{PIPELINE_DIR}/{result}"
        yield "pipeline", relative, [marker]
        plans = f"{folder}/{result}/{PLANS_DIR}"
        try:
            with os.scandir(plans) as entries:
                markers = sorted(e.name for e in entries if e.is_file())
        except (FileNotFoundError, NotADirectoryError):
            continue
        for plan in markers:
            if plan.endswith(PLAN_MARKER_SUFFIX):
                yield "plan", relative, [f"{plans}/{plan}"]


def _object_sources(root: S3Path) -> Iterator[tuple[str, str, list[str]]]:
    """As :func:`_local_sources`, on an object store (its listings)."""
    for directory in sorted(root.iterdir()) if root.is_dir() else []:
        if not is_id(directory.name):
            continue
        if (directory / MANIFEST).is_file():
            yield "run", directory.name, [str(directory / MANIFEST)]
            folder = directory / PIPELINE_DIR
            for result in sorted(folder.iterdir()) if folder.is_dir() else []:
                if (result / PIPELINE_MARKER).is_file():
                    relative = f"{directory.name}/{PIPELINE_DIR}/{result.name}"
                    yield "pipeline", relative, [str(result / PIPELINE_MARKER)]
                    plans = result / PLANS_DIR
                    for marker in sorted(plans.iterdir()) if plans.is_dir() else []:
                        if marker.name.endswith(PLAN_MARKER_SUFFIX):
                            yield "plan", relative, [str(marker)]
        elif (directory / "run.json").is_file():
            documents = [str(directory / "run.json")]
            if (directory / "summary.json").is_file():
                documents.append(str(directory / "summary.json"))
            yield "monte_carlo", directory.name, documents


def _scan(
    root: Path | S3Path,
    previous: dict[str, dict[str, Any]],
    stamps: dict[str, Stamp],
) -> tuple[list[dict[str, Any]], dict[str, Stamp]]:
    """Every item's row (``previous``'s when its documents did not change) and the stamps
    of the documents read."""
    local = not isinstance(root, S3Path)
    sources = _local_sources(root) if local else _object_sources(root)  # type: ignore[arg-type]
    prefix = len(str(root)) + 1
    rows: list[dict[str, Any]] = []
    runs: dict[str, dict[str, Any]] = {}
    pipelines: dict[str, dict[str, Any]] = {}
    seen: dict[str, Stamp] = {}
    for kind, item, documents in sources:
        source = documents[0][prefix:]
        stamp = _stamp(documents) if local else None
        old = previous.get(source)
        try:
            if old is not None and stamp is not None and stamps.get(source) == stamp:
                row = dict(old)  # unchanged since it was read (its stamp)
            else:
                directory = location(str(root) + "/" + item)
                payload = b"".join(read_bytes(location(d)) for d in documents)
                digest = Digest.of(payload).sha256
                if old is not None and old["source_sha256"] == digest:
                    row = dict(old)
                elif kind == "run":
                    row = _run_row(directory, source, digest)
                elif kind == "pipeline":
                    run = runs.get(item.split("/")[0], {})
                    row = _pipeline_row(location(documents[0]), source, digest, payload, run)
                elif kind == "plan":
                    marker = location(documents[0])
                    row = _plan_row(marker, source, digest, payload, pipelines.get(item, {}))
                else:
                    row = _monte_carlo_row(directory, source, digest)
                    if row is None:
                        continue  # another study's batched run (the deorbit burn's)
            if stamp is not None and row["error"] is None:
                seen[source] = stamp
        except (StoreError, OSError, ValueError, TypeError, AttributeError, RecursionError) as err:
            name = item.rsplit("/", 1)[-1] if kind != "plan" else source.rsplit("/", 1)[-1]
            row = _row(kind, name, source, "-", error=printable(str(err))[:500])
        if kind == "run":
            runs[item] = row
        elif kind == "pipeline":
            pipelines[item] = row
        rows.append(row)
    return rows, seen


# --- the catalog file -------------------------------------------------------------------


def _folder(root: Path | S3Path) -> Path | S3Path:
    return root / CATALOG_DIR


def _frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """The rows as a frame of Python values (None where a value is missing, whatever the
    column's type: no NaN standing for a missing id or count)."""
    # Rows to columns: every row has every column (_row), so the transposition is whole.
    columns = list(zip(*map(itemgetter(*_COLUMNS), rows), strict=True)) if rows else []
    return _columns_frame(dict(zip(_COLUMNS, columns or [()] * len(_COLUMNS), strict=True)))


def _columns_frame(columns: dict[str, Any]) -> pd.DataFrame:
    return pd.DataFrame({name: pd.Series(columns[name], dtype=object) for name in _COLUMNS})


def _ordered(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    order = {kind: k for k, kind in enumerate(KINDS)}
    return sorted(rows, key=lambda r: (r["created_utc"] or "", order[r["kind"]], r["source"]))


def _read(root: Path | S3Path) -> tuple[dict[str, list[Any]] | None, str | None]:
    """The stored catalog by columns, or None and why it cannot be used (missing, damaged,
    another schema)."""
    folder = _folder(root)
    marker = folder / CATALOG_MARKER
    if not marker.is_file():
        return None, "no catalog yet"
    try:
        recorded = read_authenticated(marker)  # with a store key: sealed, else rebuilt
        if not isinstance(recorded, dict) or recorded.get("schema_version") != SCHEMA_VERSION:
            return None, f"{marker}: another catalog format"
        payload = read_bytes(folder / CATALOG_FILE, Digest.from_json(recorded.get("file")))
        table = pq.read_table(pa.BufferReader(payload))
    except (StoreError, ValueError, OSError, pa.ArrowException) as err:
        return None, f"damaged catalog ({printable(str(err))[:300]})"
    if table.schema != SCHEMA:
        return None, f"{folder / CATALOG_FILE}: not the declared schema"
    return table.to_pydict(), None


def _column_rows(columns: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """Columns to rows (``to_pydict`` then this is ~3x faster than ``to_pylist``)."""
    together = zip(*columns.values(), strict=True)
    return [dict(zip(_COLUMNS, values, strict=True)) for values in together]


def _write(root: Path | S3Path, rows: list[dict[str, Any]]) -> None:
    folder = _folder(root)
    table = pa.Table.from_pylist(rows, schema=SCHEMA) if rows else SCHEMA.empty_table()
    digest = write_bytes(folder / CATALOG_FILE, parquet_bytes(table), replace=True)
    marker = {"schema_version": SCHEMA_VERSION, "rows": len(rows), "file": digest.to_json()}
    write_sealed(folder / CATALOG_MARKER, marker, replace=True)


def refresh(store_root: Path | S3Path | str, *, rebuild: bool = False) -> Catalog:
    """The store's catalog brought up to date with its documents (written when it changed);
    ``rebuild``: from the documents alone, the stored catalog not read."""
    root = location(store_root)
    folder = _folder(root)
    settings = catalog_settings()
    local = not isinstance(root, S3Path)
    if local:
        make_folders(folder)  # no link on the way: the catalog stays in its store
    with locks.hold(folder / "catalog.lock", wait_s=settings.lock_wait_s):
        stored, why = (None, "rebuild asked") if rebuild else _read(root)
        stamps = {} if stored is None else _read_stamps(root)
        tags = _all_tags(root)
        if stored is not None and local and _unchanged(root, stored, stamps, tags):
            return Catalog(_columns_frame(stored), folder / CATALOG_FILE)
        stored_rows = None if stored is None else _column_rows(stored)
        previous = {r["source"]: r for r in stored_rows or []}
        rows, seen = _scan(root, previous, stamps)
        for row in rows:
            row["tags"] = _tags_text(tags.get(row["id"]))
        rows = _ordered(rows)
        written = stored_rows != rows
        if written:
            _write(root, rows)
        if seen != stamps and local:
            write_bytes(folder / STAMPS_FILE, json.dumps(seen).encode(), replace=True)
    because = why if stored is None else None
    return Catalog(_frame(rows), folder / CATALOG_FILE, written, because, rows)


def verify_catalog(store_root: Path | S3Path | str) -> VerifyReport:
    """Check the stored catalog without changing it: ``catalog.json``'s seal (with a store
    key), ``catalog.parquet`` against its recorded digest and :data:`SCHEMA`, every tag
    file (seal, content), and its rows against those the stored documents give now (a
    catalog that is not its store's, e.g. one rewritten with a valid digest, is reported).
    """
    root = location(store_root)
    folder = _folder(root)
    report = VerifyReport(CATALOG_DIR)
    marker = folder / CATALOG_MARKER
    recorded = report.read_document(marker)
    if recorded is None:
        return report
    file = recorded.get("file") if isinstance(recorded, dict) else None
    report.check_file(folder / CATALOG_FILE, file, SCHEMA)
    tag_folder = folder / TAGS_DIR
    for path in sorted(tag_folder.iterdir()) if tag_folder.is_dir() else []:
        if report.read_document(path) is None:
            continue
        try:
            read_tags(root, checked_id(path.name.removesuffix(".json"), "tag file"))
        except StoreError as err:
            report.problems.append(str(err))
            continue
        report.checked_files += 1
    if not report.clean:
        return report
    stored, _ = _read(root)
    tags = _all_tags(root)
    rows, _ = _scan(root, {}, {})
    for row in rows:
        row["tags"] = _tags_text(tags.get(row["id"]))
    if stored is None or _column_rows(stored) != _ordered(rows):
        report.problems.append(
            f"{folder / CATALOG_FILE}: its rows are not those of the store's documents "
            "(`ovtraj catalog --rebuild` writes them again)"
        )
    return report


def _tags_text(tags: dict[str, str] | None) -> str:
    return json.dumps(tags, sort_keys=True) if tags else "{}"


def _unchanged(
    root: Path,
    stored: dict[str, list[Any]],
    stamps: dict[str, Stamp],
    tags: dict[str, dict[str, str]],
) -> bool:
    """Whether the stored catalog is the store's: the same documents, each with the stamp
    it had when read (none in error), and the same tags. The usual case, ~3x faster than a
    scan that reuses rows (benchmarks/catalog.py)."""
    prefix = len(str(root)) + 1
    now = {}
    for _, _, documents in _local_sources(root):
        stamp = _stamp(documents)
        if stamp is None:
            return False
        now[documents[0][prefix:]] = stamp
    if now != stamps or set(stored["source"]) != now.keys():
        return False
    wanted = [_tags_text(tags.get(item)) for item in stored["id"]]
    return wanted == stored["tags"]


def _read_stamps(root: Path | S3Path) -> dict[str, Stamp]:
    """The stamps of the documents the last refresh read (none when unreadable: then
    every document is read and hashed again)."""
    path = _folder(root) / STAMPS_FILE
    if isinstance(root, S3Path) or not path.is_file():
        return {}
    try:
        found = read_json(path)
    except StoreError:
        return {}
    if not isinstance(found, dict):
        return {}
    return {
        k: v for k, v in found.items() if isinstance(v, list) and all(type(x) is int for x in v)
    }


# --- tags -------------------------------------------------------------------------------


def _tag_file(root: Path | S3Path, item_id: str) -> Path | S3Path:
    return _folder(root) / TAGS_DIR / f"{checked_id(item_id, 'id')}.json"


def _all_tags(root: Path | S3Path) -> dict[str, dict[str, str]]:
    folder = _folder(root) / TAGS_DIR
    found: dict[str, dict[str, str]] = {}
    for path in sorted(folder.iterdir()) if folder.is_dir() else []:
        if not path.name.endswith(".json"):
            continue
        try:
            found[path.name[:-5]] = read_tags(root, path.name[:-5])
        except StoreError:
            continue  # a damaged or foreign file: no tags (`ovtraj tag` rewrites it)
    return found


def read_tags(store_root: Path | S3Path | str, item_id: str) -> dict[str, str]:
    """The tags of ``item_id`` (empty when it has none); :class:`StoreError` naming the
    file when it is not a tag file: not the item's, tags beyond what ``ovtraj tag``
    accepts (:func:`checked_tag`, ``catalog.tags_per_item``), or, with a store key, a seal
    missing or wrong."""
    path = _tag_file(location(store_root), item_id)
    if not path.is_file():
        return {}
    document = read_authenticated(path)
    tags = document.get("tags") if isinstance(document, dict) else None
    if not isinstance(tags, dict) or document.get("id") != item_id:
        raise StoreError(f"{path}: not the tags of {item_id}")
    if len(tags) > catalog_settings().tags_per_item:
        raise StoreError(f"{path}: {len(tags)} tags, more than catalog.tags_per_item")
    for key, value in tags.items():
        try:
            if not isinstance(value, str):
                raise ValueError(f"tag {printable(key)[:80]}: not text")
            checked_tag(key, value)
        except ValueError as err:
            raise StoreError(f"{path}: {err}") from None
    return dict(tags)


def checked_tag(key: str, value: str) -> None:
    """A tag's name and value within ``catalog`` of configs/orchestration.yaml
    (:class:`ValueError` naming what is wrong)."""
    settings = catalog_settings()
    shown = printable(key)[:80]
    if not _TAG_KEY.fullmatch(key) or len(key) > settings.tag_key_max_chars:
        raise ValueError(
            f"tag name {shown!r}: a letter, then letters, digits, '_', '.' or '-', at most "
            f"{settings.tag_key_max_chars} characters (catalog.tag_key_max_chars)"
        )
    if len(value) > settings.tag_value_max_chars or printable(value) != value:
        raise ValueError(
            f"tag {shown}: the value must be printable text of at most "
            f"{settings.tag_value_max_chars} characters (catalog.tag_value_max_chars)"
        )


def set_tags(
    store_root: Path | S3Path | str,
    item_id: str,
    tags: dict[str, str],
    remove: Iterable[str] = (),
) -> dict[str, str]:
    """Add or change ``tags`` and drop ``remove`` of the catalogued item ``item_id``;
    returns its tags. The item's own files are not touched."""
    root = location(store_root)
    catalog = refresh(root)
    catalog.item(item_id)
    for key, value in tags.items():
        checked_tag(key, value)
    settings = catalog_settings()
    with locks.hold(_folder(root) / "tags.lock", wait_s=settings.lock_wait_s):
        current = read_tags(root, item_id)
        current.update(tags)
        for key in remove:
            current.pop(key, None)
        if len(current) > settings.tags_per_item:
            raise ValueError(
                f"{item_id}: {len(current)} tags, at most {settings.tags_per_item} "
                "(catalog.tags_per_item)"
            )
        document = {"id": item_id, "tags": dict(sorted(current.items()))}
        write_sealed(_tag_file(root, item_id), document, replace=True)
    refresh(root)
    return current


# --- queries ----------------------------------------------------------------------------


def query(frame: pd.DataFrame, where: str | None) -> pd.DataFrame:
    """The catalog rows for which the SQL predicate ``where`` holds (DuckDB's dialect over
    the columns of :data:`SCHEMA`, e.g. ``kind = 'plan' AND dv_total_mps > 220``), in the
    catalog's order.

    ``where`` is parsed as one expression (DuckDB's relational ``filter``), never pasted
    into a statement: a ``;`` or an unbalanced ``)`` is a syntax error, so no second
    statement runs. The query sees only this table: DuckDB's access to files and the
    network is off and its settings locked; it runs on ``catalog.query_threads`` threads
    within ``catalog.query_memory_mib`` (DuckDB's limit, and the process's address space
    while it runs, :func:`_address_space_limit`), and is interrupted past
    ``catalog.query_time_limit_s``. Every failure is a :class:`ValueError` of one line
    naming ``--where``."""
    if where is None or not where.strip():
        return frame
    settings = catalog_settings()
    if len(where) > settings.where_max_chars:
        raise ValueError(
            f"--where: {len(where)} characters, at most {settings.where_max_chars} "
            "(catalog.where_max_chars)"
        )
    import duckdb

    table = pa.Table.from_pandas(frame, schema=SCHEMA, preserve_index=False)
    table = table.append_column("_row", pa.array(range(len(frame)), pa.int64()))
    connection = duckdb.connect(":memory:")
    try:
        connection.register("catalog", table)
        connection.execute(f"SET memory_limit = '{settings.query_memory_mib}MiB'")
        connection.execute(f"SET threads = {settings.query_threads}")
        connection.execute("SET enable_external_access = false")
        connection.execute("SET lock_configuration = true")
        timer = threading.Timer(settings.query_time_limit_s, connection.interrupt)
        timer.start()
        try:
            with _address_space_limit(settings.query_memory_mib * 2**20):
                relation = connection.table("catalog").filter(where)
                found = relation.project("_row").order("_row").fetchnumpy()["_row"]
        except duckdb.InterruptException:
            raise ValueError(
                f"--where: the query ran longer than {settings.query_time_limit_s:g} s "
                "(catalog.query_time_limit_s)"
            ) from None
        except (duckdb.OutOfMemoryException, MemoryError):
            raise ValueError(
                f"--where: the query needs more than {settings.query_memory_mib} MiB "
                "(catalog.query_memory_mib)"
            ) from None
        except duckdb.Error as err:
            text = printable(str(err).splitlines()[0] if str(err) else type(err).__name__)
            raise ValueError(f"--where: {text[:300]}") from None
        finally:
            timer.cancel()
    finally:
        connection.close()
    rows = [int(k) for k in found]
    if any(not 0 <= k < len(frame) for k in rows):  # the filter keeps the table's own rows
        raise ValueError("--where: the query returned rows the catalog does not hold")
    return frame.iloc[rows].reset_index(drop=True)


@contextlib.contextmanager
def _address_space_limit(extra_bytes: int) -> Iterator[None]:
    """The process's address space bounded to its current size plus ``extra_bytes`` while
    the block runs (Linux; elsewhere only DuckDB's own limit holds). DuckDB's memory_limit
    counts its buffers, not the strings a scalar function builds: ``repeat('x', 1e9)``
    grew the process by 2.1 GB under a 512 MiB memory_limit. Under this bound the
    allocation fails and DuckDB reports an out-of-memory error instead."""
    size = _address_space_bytes()
    if size is None:
        yield
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    wanted = size + extra_bytes
    if soft != resource.RLIM_INFINITY and soft <= wanted:
        yield  # already bounded tighter by whoever started us
        return
    if hard != resource.RLIM_INFINITY:
        wanted = min(wanted, hard)
    resource.setrlimit(resource.RLIMIT_AS, (wanted, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _address_space_bytes() -> int | None:
    """The process's virtual size [B] (``VmSize`` of /proc/self/status), None off Linux."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None
