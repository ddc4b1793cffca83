"""The stored items a catalog row comes from, found in the store, stamped and read
(:mod:`ovtraj.tracking.catalog`): every item of a store in name order (:func:`scan`), or the
one a row's ``source`` names (:func:`entry_of`).

An item is (kind, its folder relative to the store, its document files): a run (its
manifest), a pipeline result (its summary, in its DoE run), a plan (its marker, in its
pipeline result), a plan Monte Carlo run (``run.json`` and ``summary.json``). A row's
``source`` is its first document relative to the store.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ovtraj.formatting import printable
from ovtraj.store.backends import S3Path, location
from ovtraj.store.files import Digest, StoreError, read_bytes
from ovtraj.store.layout import (
    MANIFEST,
    PIPELINE_DIR,
    PIPELINE_MARKER,
    PLAN_MARKER_SUFFIX,
    PLANS_DIR,
    is_id,
)
from ovtraj.tracking.catalog_rows import monte_carlo_row, pipeline_row, plan_row, run_row
from ovtraj.tracking.catalog_schema import new_row

__all__ = [
    "Item",
    "Stamp",
    "documents_unchanged",
    "entry_of",
    "holders",
    "item_row",
    "scan",
    "scan_order",
    "stamp_of",
]

# A stored item: (kind, its folder relative to the store, its document files).
Item = tuple[str, str, list[str]]
# What reading an item can raise: its row then holds the error.
_READ_ERRORS = (StoreError, OSError, ValueError, TypeError, AttributeError, RecursionError)

# A document's stamp: (size [B], modification time [ns], inode) of its files, kept in
# ``stamps.json`` beside the catalog (not in it: host data). A document whose stamp is the
# one recorded is not read again; any other is read and its SHA-256 decides.
Stamp = list[int]


def stamp_of(paths: list[str]) -> Stamp | None:
    """The stamp of the document files ``paths`` (None when one cannot be stat-ed)."""
    stamp: Stamp = []
    for path in paths:
        try:
            found = os.stat(path, follow_symlinks=False)
        except OSError:
            return None
        stamp += [found.st_size, found.st_mtime_ns, found.st_ino]
    return stamp


def local_sources(root: Path) -> Iterator[Item]:
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


def _local_results(run: str, folder: str) -> Iterator[Item]:
    """The pipeline results and plans of one run (:func:`local_sources`)."""
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


def _object_sources(root: S3Path) -> Iterator[Item]:
    """As :func:`local_sources`, on an object store (its listings)."""
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


def scan(
    root: Path | S3Path,
    previous: dict[str, dict[str, Any]],
    stamps: dict[str, Stamp],
) -> tuple[list[dict[str, Any]], dict[str, Stamp]]:
    """Every item's row (``previous``'s when its documents did not change) and the stamps
    of the documents read, in the store's name order."""
    local = not isinstance(root, S3Path)
    items = local_sources(root) if local else _object_sources(root)  # type: ignore[arg-type]
    made: dict[str, dict[str, Any]] = {}
    seen: dict[str, Stamp] = {}
    for item in items:
        source = source_of(root, item)
        context = made.get(context_source(item)) or {}
        row, stamp = item_row(root, item, previous.get(source), stamps.get(source), context)
        if row is None:
            continue  # another study's batched run (the deorbit burn's)
        if stamp is not None:
            seen[source] = stamp
        made[source] = row
    return list(made.values()), seen


def source_of(root: Path | S3Path, item: Item) -> str:
    """An item's ``source``: its first document relative to the store ``root``."""
    return item[2][0][len(str(root)) + 1 :]


def context_source(item: Item) -> str | None:
    """The ``source`` of the row an item's row takes columns from: a pipeline result's DoE
    run (the target), a plan's pipeline result (the creation time); None for the others."""
    kind, folder, _ = item
    if kind == "pipeline":
        return f"{folder.split('/')[0]}/{MANIFEST}"
    if kind == "plan":
        return f"{folder}/{PIPELINE_MARKER}"
    return None


def item_row(
    root: Path | S3Path,
    item: Item,
    old: dict[str, Any] | None,
    recorded: Stamp | None,
    context: dict[str, Any],
) -> tuple[dict[str, Any] | None, Stamp | None]:
    """The row of one stored item and the stamp to record for it (None: read it again next
    time). ``old`` (its previous row) is kept when its documents' stamp is ``recorded`` or
    their SHA-256 its ``source_sha256``; otherwise the row is read from them (``context``:
    the row of :func:`context_source`). An unreadable item's row holds the error; None for
    a batched run of another study."""
    kind, folder, documents = item
    source = source_of(root, item)
    stamp = stamp_of(documents) if not isinstance(root, S3Path) else None
    try:
        if old is not None and stamp is not None and recorded == stamp:
            row = dict(old)  # unchanged since it was read (its stamp)
        else:
            row = _read_row(root, item, source, old, context)
            if row is None:
                return None, None
        return row, stamp if stamp is not None and row["error"] is None else None
    except _READ_ERRORS as err:
        name = folder.rsplit("/", 1)[-1] if kind != "plan" else source.rsplit("/", 1)[-1]
        return new_row(kind, name, source, "-", error=printable(str(err))[:500]), None


def _read_row(
    root: Path | S3Path,
    item: Item,
    source: str,
    old: dict[str, Any] | None,
    context: dict[str, Any],
) -> dict[str, Any] | None:
    """The row an item's documents give now (``old`` again when their SHA-256 is its
    ``source_sha256``); None for a batched run of another study."""
    kind, folder, documents = item
    directory = location(str(root) + "/" + folder)
    payload = b"".join(read_bytes(location(d)) for d in documents)
    digest = Digest.of(payload).sha256
    if old is not None and old["source_sha256"] == digest:
        return dict(old)
    if kind == "run":
        return run_row(directory, source, digest)
    if kind == "pipeline":
        return pipeline_row(location(documents[0]), source, digest, payload, context)
    if kind == "plan":
        return plan_row(location(documents[0]), source, digest, payload, context)
    return monte_carlo_row(directory, source, digest)


def entry_of(root: Path | S3Path, source: str) -> Item | None:
    """The stored item whose row's ``source`` is ``source``, as :func:`scan` finds it;
    None when a scan would not find it (gone, or no document of a catalogued item)."""
    parts = source.split("/")
    if not is_id(parts[0]) or any(p in ("", ".", "..") for p in parts):
        return None

    def found(*names: str) -> bool:
        return location("/".join([str(root), parts[0], *names])).is_file()

    def item(kind: str, depth: int, *documents: str) -> Item:
        folder = "/".join(parts[:depth])
        return kind, folder, [f"{root}/{parts[0]}/{d}" for d in documents]

    run = found(MANIFEST)
    if parts[1:] == [MANIFEST]:
        return item("run", 1, MANIFEST) if run else None
    if parts[1:] == ["run.json"]:
        if run or not found("run.json"):
            return None
        summary = ["summary.json"] if found("summary.json") else []
        return item("monte_carlo", 1, "run.json", *summary)
    if len(parts) < 4 or parts[1] != PIPELINE_DIR or not run:
        return None
    result = f"{PIPELINE_DIR}/{parts[2]}"
    if not found(result, PIPELINE_MARKER):
        return None
    if parts[3:] == [PIPELINE_MARKER]:
        return item("pipeline", 3, f"{result}/{PIPELINE_MARKER}")
    plan = parts[3:] == [PLANS_DIR, parts[-1]] and parts[-1].endswith(PLAN_MARKER_SUFFIX)
    if plan and found(result, PLANS_DIR, parts[-1]):
        return item("plan", 3, f"{result}/{PLANS_DIR}/{parts[-1]}")
    return None


def holders(source: str) -> list[str]:
    """The ``source`` of the items that hold the item of ``source`` (a pipeline result's DoE
    run; a plan's DoE run and pipeline result): their rows give its row columns."""
    parts = source.split("/")
    if len(parts) < 4 or parts[1] != PIPELINE_DIR:
        return []
    run = f"{parts[0]}/{MANIFEST}"
    return [run] if len(parts) == 4 else [run, "/".join([*parts[:3], PIPELINE_MARKER])]


def scan_order(source: str) -> tuple[str, list[str], int, str]:
    """The place of a ``source`` in :func:`scan`'s order: by run, the run (or Monte Carlo
    run) first, then its pipeline results by name, each before its plans."""
    parts = source.split("/")
    return parts[0], parts[2:3], len(parts), parts[-1]


def documents_unchanged(root: Path, sources: set[str], stamps: dict[str, Stamp]) -> bool:
    """Whether the local store ``root`` holds the documents of ``sources`` and no other,
    each with the stamp recorded in ``stamps``."""
    prefix = len(str(root)) + 1
    now = {}
    for _, _, documents in local_sources(root):
        stamp = stamp_of(documents)
        if stamp is None:
            return False
        now[documents[0][prefix:]] = stamp
    return now == stamps and sources == now.keys()
