"""What the run store can lose without losing a result, and removing it (``ovtraj prune``).

Three kinds, each safe by construction:

* **superseded child runs**: a run with a parent, every sample of which a later complete
  run of its family holds (a child adopts its parent's batches), that is no stored
  pipeline result's final run and that no process is working on. The family's root,
  which holds the pipeline results, is never removed; the pipeline results keep the
  removed run ids, so ``ovtraj plan <removed id>`` still finds them. Running the same
  pipeline again computes a removed round again (same ids, same results).
* **stale surrogate fits and fronts**: ``surrogates/<fit id>`` and ``fronts/<front id>``
  of another code version than this one: their ids include the code version, so this
  code never loads them again (a stored pipeline result does not need them).
* **Prefect task results**: the result records of the local result storage
  (``configs/orchestration.yaml`` ``results``), a cache: a later flow run recomputes a
  task whose result is gone; every result of a run is in the run store. Only files that
  parse as Prefect result records count (:func:`ovtraj.store.result_records.is_result_record`;
  parsed as JSON, never deserialized); anything else there is left alone. Remove them
  when no flow is running.

Nothing outside the store root and the results folder is touched: a symbolic link is
never followed and never listed (a ``.pruned-*`` link, a run directory, a product folder
or a result that is a link stays, and so does its target); every item is a directory
entry of the resolved root (or of a run's ``surrogates``/``fronts`` folder, or of the
results folder), and :func:`remove` deletes it only if its folder still resolves to
itself and the entry itself (``lstat``) is still a directory (a regular file for a
result). A run that a process works on (its run lock) and a product being written (its
directory lock) are kept.

A removal renames the directory to a hidden ``.pruned-*`` name first (atomic: readers
either see the whole product or none of it), then deletes it (:func:`shutil.rmtree`,
which never follows a link inside it); one left by a stopped prune is listed and removed
by the next. Local stores only.
"""

from __future__ import annotations

import os
import shutil
import stat
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from ovtraj.pipeline.catalog import pipeline_summaries
from ovtraj.pipeline.steps import MARKER
from ovtraj.runs import Run, RunStore, StoreError
from ovtraj.store import locks
from ovtraj.store.backends import S3Path
from ovtraj.store.files import read_json, tree_bytes
from ovtraj.store.result_records import is_result_record

__all__ = ["PruneItem", "prunable", "remove"]

KINDS = ("children", "fits", "prefect-results")
HIDDEN = ".pruned-"  # a directory being removed; a stopped prune leaves it, the next removes it


@dataclass
class PruneItem:
    kind: str  # one of KINDS
    path: Path
    size_bytes: int
    reason: str

    def to_json(self) -> dict[str, Any]:
        return asdict(self) | {"path": str(self.path)}


def _superseded_children(runs: list[Run]) -> list[PruneItem]:
    manifests, lineages = {}, {}
    for run in runs:
        try:
            manifests[run.id] = run.manifest
            lineages[run.id] = run.lineage()
        except StoreError:
            continue  # unreadable: never judged, never removed
    final_runs = {
        summary.get("final_run") for run in runs for _, summary in pipeline_summaries(run)
    }
    items = []
    for run in runs:
        manifest = manifests.get(run.id)
        if manifest is None or not manifest.get("parent") or run.id in final_runs:
            continue
        later = [
            rid
            for rid, lineage in lineages.items()
            if run.id in lineage and manifests[rid].get("status") == "complete"
        ]
        if not later or run.in_use():
            continue
        items.append(
            PruneItem(
                "children",
                run.directory,
                tree_bytes(run.directory, _shared_elsewhere(run)) or 0,
                f"child run ({manifest.get('origin')}) of {lineages[run.id][0]}: its samples "
                f"are all in the complete run {sorted(later)[0]}",
            )
        )
    return items


def _shared_elsewhere(run: Run) -> set[tuple[int, int]]:
    """Inodes of files ``run`` shares with other runs (hard links): removing it frees
    none of them."""
    stats: dict[tuple[int, int], list[int]] = {}
    for folder, _, names in os.walk(run.directory):
        for name in names:
            stat = os.lstat(os.path.join(folder, name))
            seen = stats.setdefault((stat.st_dev, stat.st_ino), [stat.st_nlink, 0])
            seen[1] += 1
    return {key for key, (links, inside) in stats.items() if links > inside}


def _is_directory(path: Path) -> bool:
    """Whether ``path`` is a directory itself: a symbolic link to one is not (``lstat``)."""
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def _stale_products(runs: list[Run], code: str) -> list[PruneItem]:
    items = []
    for run in runs:
        for folder, what in (("surrogates", "surrogate fit"), ("fronts", "surrogate front")):
            base = run.directory / folder
            if not _is_directory(base):
                continue
            items += [replace(item, kind="fits") for item in _leftovers(base)]
            for directory in sorted(base.iterdir()):
                if not _is_directory(directory):
                    continue
                marker = directory / MARKER
                try:
                    stored_code = read_json(marker).get("code") if marker.is_file() else None
                except (StoreError, OSError, AttributeError):
                    continue
                if stored_code is None or stored_code == code:
                    continue
                items.append(
                    PruneItem(
                        "fits",
                        directory,
                        tree_bytes(directory) or 0,
                        f"{what} of run {run.id} by code {stored_code}, not this code ({code})",
                    )
                )
    return items


def _leftovers(folder: Path) -> list[PruneItem]:
    """Directories a prune renamed and was stopped before deleting (``.pruned-*``)."""
    found = sorted(folder.glob(f"{HIDDEN}*")) if folder.is_dir() else []
    return [
        PruneItem("children", path, tree_bytes(path) or 0, "left by a stopped prune")
        for path in found
        if _is_directory(path)
    ]


def _prefect_results(folder: Path | None) -> list[PruneItem]:
    if folder is None or not _is_directory(folder):
        return []
    return [
        PruneItem("prefect-results", path, os.lstat(path).st_size, "Prefect task result")
        for path in sorted(folder.iterdir())
        if is_result_record(path)
    ]


def prunable(
    store: RunStore,
    code: str,
    *,
    kinds: tuple[str, ...] = KINDS,
    prefect_results: Path | None = None,
) -> list[PruneItem]:
    """What :func:`remove` may delete, by kind; deletes nothing.

    ``prefect_results``: the local folder of Prefect's task results (None: left alone).
    Every item's path is the resolved root's (or results folder's) and plain names below
    it; a run directory that is a symbolic link is not a run here.
    Raises :class:`StoreError` for a store on object storage."""
    if isinstance(store.root, S3Path):
        raise StoreError(
            f"{store.root}: prune works on a local store; on object storage use the "
            "bucket's lifecycle rules"
        )
    root = store.root.resolve()
    runs = [Run(root / d.name) for d in store.run_directories() if _is_directory(root / d.name)]
    items: list[PruneItem] = []
    if "children" in kinds:
        items += _leftovers(root)
        items += _superseded_children(runs)
    if "fits" in kinds:
        items += _stale_products(runs, code)
    if "prefect-results" in kinds:
        items += _prefect_results(None if prefect_results is None else prefect_results.resolve())
    return items


def _in_use(item: PruneItem) -> bool:
    """A run a process works on (its run lock), a product being written (its directory)."""
    if item.kind == "children":
        return Run(item.path).in_use()
    return locks.held(item.path)


def remove(item: PruneItem) -> bool:
    """Delete one item (:func:`prunable`); False when it is gone already, now in use, or no
    longer what was listed: a symbolic link now, or in a folder reached through one (only
    ever the entry itself is removed, never a link's target)."""
    path = item.path
    try:
        # Listed as the resolved root plus plain names: its folder resolves to itself
        # unless a folder on the way was replaced by a symbolic link since.
        if path.parent.resolve(strict=True) != path.parent:
            return False
        mode = os.lstat(path).st_mode
    except (OSError, RuntimeError):  # gone, or a loop of links (RuntimeError before 3.13)
        return False
    if item.kind == "prefect-results":
        if not is_result_record(path):
            return False
        path.unlink(missing_ok=True)  # unlink removes the entry, never a link's target
        return True
    if not stat.S_ISDIR(mode) or _in_use(item):
        return False
    if not path.name.startswith(HIDDEN):
        hidden = path.with_name(f"{HIDDEN}{path.name}")
        os.replace(path, hidden)  # renames the entry itself: a directory, checked above
        path = hidden
    shutil.rmtree(path)  # refuses a symbolic link as its argument, never follows one inside
    return True
