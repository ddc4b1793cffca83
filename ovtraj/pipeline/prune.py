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
* **Prefect task results**: the files of the local result storage
  (``configs/orchestration.yaml`` ``results``), a cache: a later flow run recomputes a
  task whose result is gone; every result of a run is in the run store. Remove them
  when no flow is running.

A removal renames the directory to a hidden ``.pruned-*`` name first (atomic: readers
either see the whole product or none of it), then deletes it; one left by a stopped prune
is listed and removed by the next. Local stores only.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from ovtraj.files import read_json
from ovtraj.pipeline.catalog import pipeline_summaries, stored_runs, tree_bytes
from ovtraj.pipeline.steps import MARKER
from ovtraj.runs import Run, RunStore, StoreError
from ovtraj.storage import S3Path

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
                run.directory.resolve(),
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


def _stale_products(runs: list[Run], code: str) -> list[PruneItem]:
    items = []
    for run in runs:
        for folder, what in (("surrogates", "surrogate fit"), ("fronts", "surrogate front")):
            base = run.directory / folder
            items += [replace(item, kind="fits") for item in _leftovers(base)]
            for directory in sorted(base.iterdir()) if base.is_dir() else []:
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
                        directory.resolve(),
                        tree_bytes(directory) or 0,
                        f"{what} of run {run.id} by code {stored_code}, not this code ({code})",
                    )
                )
    return items


def _leftovers(folder: Path) -> list[PruneItem]:
    """Directories a prune renamed and was stopped before deleting (``.pruned-*``)."""
    found = sorted(folder.glob(f"{HIDDEN}*")) if folder.is_dir() else []
    return [
        PruneItem("children", path.resolve(), tree_bytes(path) or 0, "left by a stopped prune")
        for path in found
        if path.is_dir()
    ]


def _prefect_results(folder: Path | None) -> list[PruneItem]:
    if folder is None or not folder.is_dir():
        return []
    return [
        PruneItem("prefect-results", path.resolve(), path.stat().st_size, "Prefect task result")
        for path in sorted(folder.iterdir())
        if path.is_file()
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
    Raises :class:`StoreError` for a store on object storage."""
    if isinstance(store.root, S3Path):
        raise StoreError(
            f"{store.root}: prune works on a local store; on object storage use the "
            "bucket's lifecycle rules"
        )
    runs = stored_runs(store)
    items: list[PruneItem] = []
    if "children" in kinds:
        items += _leftovers(store.root)
        items += _superseded_children(runs)
    if "fits" in kinds:
        items += _stale_products(runs, code)
    if "prefect-results" in kinds:
        items += _prefect_results(prefect_results)
    return items


def remove(item: PruneItem) -> bool:
    """Delete one item; False when it is gone already or (a run) now in use."""
    path = item.path
    if not path.exists():
        return False
    if item.kind == "children" and Run(path).in_use():
        return False
    if path.is_file():
        path.unlink(missing_ok=True)
        return True
    if path.name.startswith(HIDDEN):
        shutil.rmtree(path)
        return True
    hidden = path.with_name(f"{HIDDEN}{path.name}")
    os.replace(path, hidden)
    shutil.rmtree(hidden)
    return True
