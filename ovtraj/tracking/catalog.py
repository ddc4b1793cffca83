"""The store's catalog: one Parquet table, a row per run, pipeline result, plan and plan
Monte Carlo, with their key figures and tags, queried with SQL (DuckDB,
:mod:`ovtraj.tracking.catalog_query`).

Layout, beside the runs (``<store>/catalog/``)::

    catalog.parquet    the rows, exactly :data:`~ovtraj.tracking.catalog_schema.SCHEMA`;
                       derived, so replaced (atomically)
    catalog.json       its size and SHA-256 (checked on every read), rows, schema version
    stamps.json        the stamps of the documents last read (host data, not in the rows)
    tags/<id>.json     an item's tags: metadata beside the item, never in its checksummed
                       files (``ovtraj tag``, :mod:`ovtraj.tracking.catalog_tags`)
    catalog.lock       held while the catalog is refreshed

The catalog is derived from the stored documents (the runs' manifests, the pipeline
summaries, the plans' markers, the Monte Carlo runs' ``run.json`` and ``summary.json``;
:mod:`ovtraj.tracking.catalog_sources`, the row each gives:
:mod:`ovtraj.tracking.catalog_rows`): :func:`refresh` reads each one and rebuilds the row of
a document whose SHA-256 changed (``source_sha256``), keeps the others, drops the rows of
documents gone (a pruned run), so a refresh after each write gives the same table as
:func:`refresh` with ``rebuild`` from nothing (``ovtraj catalog --rebuild``, also done when
the catalog is missing or damaged). A writer that knows what it wrote refreshes only those
rows (:func:`refresh_entries`: writing a plan), the others not read. The rows hold no
wall-clock or host data but the documents' own ``created_utc``.
"""

from __future__ import annotations

import contextlib
import json
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
from ovtraj.store.files import (
    Digest,
    StoreError,
    make_folders,
    parquet_bytes,
    read_bytes,
    read_json,
    write_bytes,
)
from ovtraj.store.seals import read_authenticated, write_sealed
from ovtraj.store.verification import VerifyReport
from ovtraj.tracking.catalog_schema import (
    CATALOG_DIR,
    COLUMNS,
    KINDS,
    SCHEMA,
    catalog_folder,
    catalog_settings,
    checked_id,
)
from ovtraj.tracking.catalog_sources import (
    Stamp,
    context_source,
    documents_unchanged,
    entry_of,
    holders,
    item_row,
    scan,
    scan_order,
)
from ovtraj.tracking.catalog_tags import (
    TAGS_DIR,
    all_tags,
    checked_tag,
    read_tags,
    tag_file,
    tags_text,
)

__all__ = ["Catalog", "refresh", "refresh_entries", "set_tags", "verify_catalog"]

CATALOG_FILE = "catalog.parquet"
CATALOG_MARKER = "catalog.json"
STAMPS_FILE = "stamps.json"
SCHEMA_VERSION = 1


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


# --- the catalog file -------------------------------------------------------------------


def _frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """The rows as a frame of Python values (None where a value is missing, whatever the
    column's type: no NaN standing for a missing id or count)."""
    # Rows to columns: every row has every column (new_row), so the transposition is whole.
    columns = list(zip(*map(itemgetter(*COLUMNS), rows), strict=True)) if rows else []
    return _columns_frame(dict(zip(COLUMNS, columns or [()] * len(COLUMNS), strict=True)))


def _columns_frame(columns: dict[str, Any]) -> pd.DataFrame:
    return pd.DataFrame({name: pd.Series(columns[name], dtype=object) for name in COLUMNS})


def _ordered(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    order = {kind: k for k, kind in enumerate(KINDS)}
    return sorted(rows, key=lambda r: (r["created_utc"] or "", order[r["kind"]], r["source"]))


def _read(root: Path | S3Path) -> tuple[dict[str, list[Any]] | None, str | None]:
    """The stored catalog by columns, or None and why it cannot be used (missing, damaged,
    another schema)."""
    folder = catalog_folder(root)
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
    return [dict(zip(COLUMNS, values, strict=True)) for values in together]


def _write(root: Path | S3Path, rows: list[dict[str, Any]]) -> None:
    folder = catalog_folder(root)
    table = pa.Table.from_pylist(rows, schema=SCHEMA) if rows else SCHEMA.empty_table()
    digest = write_bytes(folder / CATALOG_FILE, parquet_bytes(table), replace=True)
    marker = {"schema_version": SCHEMA_VERSION, "rows": len(rows), "file": digest.to_json()}
    write_sealed(folder / CATALOG_MARKER, marker, replace=True)


# --- refreshing -------------------------------------------------------------------------


def refresh(store_root: Path | S3Path | str, *, rebuild: bool = False) -> Catalog:
    """The store's catalog brought up to date with its documents (written when it changed);
    ``rebuild``: from the documents alone, the stored catalog not read."""
    root = location(store_root)
    with _locked(root):
        stored, why = (None, "rebuild asked") if rebuild else _read(root)
        return _refreshed(root, stored, why)


def refresh_entries(store_root: Path | S3Path | str, sources: Iterable[str]) -> Catalog:
    """The stored catalog with the rows of ``sources`` brought up to date and every other
    row kept as stored, its documents not read: what a writer that knows what it wrote
    asks for (writing a plan). ``sources`` are documents relative to the store, as the
    column ``source`` names them (``<run>/manifest.json``,
    ``<run>/pipeline/<id>/pipeline.json``, ``<run>/pipeline/<id>/plans/<name>.files.json``,
    ``<run>/run.json``); the rows of the items that hold them (a plan's pipeline result, a
    pipeline result's DoE run) are brought up to date too, since their rows give its
    columns. A source no longer stored loses its row. When every other row was up to date,
    the result is the table :func:`refresh` gives; without a usable stored catalog, it is
    :func:`refresh` (rebuilt)."""
    root = location(store_root)
    with _locked(root):
        stored, why = _read(root)
        if stored is None:
            return _refreshed(root, None, why)
        kept = _column_rows(stored)
        rows = {row["source"]: row for row in kept}
        stamps = _read_stamps(root)
        seen = dict(stamps)
        wanted = {held for source in sources for held in [*holders(source), source]}
        for source in sorted(wanted, key=scan_order):
            row, stamp = _entry_row(root, source, rows.pop(source, None), stamps.get(source), rows)
            seen.pop(source, None)
            if row is not None:
                rows[source] = row
            if stamp is not None:
                seen[source] = stamp
        return _kept(root, kept, _ordered(list(rows.values())), stamps, seen, None)


def _entry_row(
    root: Path | S3Path,
    source: str,
    old: dict[str, Any] | None,
    recorded: Stamp | None,
    rows: dict[str, dict[str, Any]],
) -> tuple[dict[str, Any] | None, Stamp | None]:
    """The row of ``source`` as a refresh gives it now (``old``: its stored row, kept when
    its documents did not change; ``rows``: the others, by source) and the stamp to record;
    None when the store no longer holds it."""
    item = entry_of(root, source)
    if item is None:
        return None, None
    context = rows.get(context_source(item)) or {}
    row, stamp = item_row(root, item, old, recorded, context)
    if row is not None:
        row["tags"] = tags_text(_item_tags(root, row["id"]))
    return row, stamp


def _item_tags(root: Path | S3Path, item_id: str) -> dict[str, str]:
    """The tags of one item as :func:`~ovtraj.tracking.catalog_tags.all_tags` reads them
    (none for a damaged or foreign tag file)."""
    try:
        return read_tags(root, item_id)
    except StoreError:
        return {}


@contextlib.contextmanager
def _locked(root: Path | S3Path) -> Iterator[None]:
    """Hold the catalog's lock (``catalog.lock``)."""
    folder = catalog_folder(root)
    if not isinstance(root, S3Path):
        make_folders(folder)  # no link on the way: the catalog stays in its store
    with locks.hold(folder / "catalog.lock", wait_s=catalog_settings().lock_wait_s):
        yield


def _refreshed(
    root: Path | S3Path, stored: dict[str, list[Any]] | None, why: str | None
) -> Catalog:
    """Every row brought up to date (the caller holds the lock): ``stored`` (by columns, or
    None, and ``why``) kept where its documents did not change (their stamps, else their
    SHA-256)."""
    local = not isinstance(root, S3Path)
    stamps = {} if stored is None else _read_stamps(root)
    tags = all_tags(root)
    if stored is not None and local and _unchanged(root, stored, stamps, tags):
        return Catalog(_columns_frame(stored), catalog_folder(root) / CATALOG_FILE)
    stored_rows = None if stored is None else _column_rows(stored)
    previous = {r["source"]: r for r in stored_rows or []}
    rows, seen = scan(root, previous, stamps)
    for row in rows:
        row["tags"] = tags_text(tags.get(row["id"]))
    because = why if stored is None else None
    return _kept(root, stored_rows, _ordered(rows), stamps, seen, because)


def _kept(
    root: Path | S3Path,
    stored_rows: list[dict[str, Any]] | None,
    rows: list[dict[str, Any]],
    stamps: dict[str, Stamp],
    seen: dict[str, Stamp],
    because: str | None,
) -> Catalog:
    """The catalog of ``rows``: written when they are not ``stored_rows``, and the stamps
    ``seen`` when they are not those read (``stamps``; a local store only)."""
    folder = catalog_folder(root)
    written = stored_rows != rows
    if written:
        _write(root, rows)
    if seen != stamps and not isinstance(root, S3Path):
        write_bytes(folder / STAMPS_FILE, json.dumps(seen).encode(), replace=True)
    return Catalog(_frame(rows), folder / CATALOG_FILE, written, because, rows)


def _unchanged(
    root: Path,
    stored: dict[str, list[Any]],
    stamps: dict[str, Stamp],
    tags: dict[str, dict[str, str]],
) -> bool:
    """Whether the stored catalog is the store's: the same documents, each with the stamp
    it had when read (none in error), and the same tags. The usual case, ~3x faster than a
    scan that reuses rows (benchmarks/catalog.py)."""
    if not documents_unchanged(root, set(stored["source"]), stamps):
        return False
    wanted = [tags_text(tags.get(item)) for item in stored["id"]]
    return wanted == stored["tags"]


def _read_stamps(root: Path | S3Path) -> dict[str, Stamp]:
    """The stamps of the documents the last refresh read (none when unreadable: then
    every document is read and hashed again)."""
    path = catalog_folder(root) / STAMPS_FILE
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


# --- checking ---------------------------------------------------------------------------


def verify_catalog(store_root: Path | S3Path | str) -> VerifyReport:
    """Check the stored catalog without changing it: ``catalog.json``'s seal (with a store
    key), ``catalog.parquet`` against its recorded digest and :data:`SCHEMA`, every tag
    file (seal, content), and its rows against those the stored documents give now (a
    catalog that is not its store's, e.g. one rewritten with a valid digest, is reported).
    """
    root = location(store_root)
    folder = catalog_folder(root)
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
    tags = all_tags(root)
    rows, _ = scan(root, {}, {})
    for row in rows:
        row["tags"] = tags_text(tags.get(row["id"]))
    if stored is None or _column_rows(stored) != _ordered(rows):
        report.problems.append(
            f"{folder / CATALOG_FILE}: its rows are not those of the store's documents "
            "(`ovtraj catalog --rebuild` writes them again)"
        )
    return report


# --- tags -------------------------------------------------------------------------------


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
    with locks.hold(catalog_folder(root) / "tags.lock", wait_s=settings.lock_wait_s):
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
        write_sealed(tag_file(root, item_id), document, replace=True)
    refresh(root)
    return current
