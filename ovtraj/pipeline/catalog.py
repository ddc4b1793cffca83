"""The run store seen by families: a DoE run, the runs that extend it, its pipeline results.

A pipeline's infill rounds each create a child run (``extend_run``) that holds every
sample of its parent plus the new ones; the pipeline result itself is stored in the DoE
run (``<doe run>/pipeline/<pipeline id>/``). A family is a root run (no parent) and every
run whose lineage starts with it. Any run id of a family leads to its pipeline results
(:func:`family_root`), also once its intermediate runs are pruned.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ovtraj.pipeline.loop import MARKER as PIPELINE_MARKER
from ovtraj.runs import Run, RunStore, StoreError
from ovtraj.runs.store import MANIFEST, checked_id
from ovtraj.store.backends import S3Path
from ovtraj.store.files import read_json

__all__ = [
    "CatalogEntry",
    "family_root",
    "pipeline_summaries",
    "store_catalog",
    "stored_runs",
    "tree_bytes",
]


@dataclass
class CatalogEntry:
    """One run as the catalog lists it; ``depth`` 0 for a family's root."""

    run_id: str
    family: str
    depth: int
    parent: str | None = None
    origin: str | None = None
    created_utc: str | None = None
    scenario: str | None = None
    status: str | None = None
    samples: int | None = None
    evaluated: int | None = None
    feasible: int | None = None
    pipelines: list[str] = field(default_factory=list)
    size_bytes: int | None = None
    error: str | None = None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def pipeline_summaries(run: Run) -> list[tuple[Path | S3Path, dict[str, Any]]]:
    """(directory, ``pipeline.json``) of every complete pipeline result stored in ``run``,
    oldest first (the summaries as written; :func:`ovtraj.pipeline.loop.load_pipeline`
    checks the files)."""
    folder = run.directory / "pipeline"
    found = []
    for directory in sorted(folder.iterdir()) if folder.is_dir() else []:
        marker = directory / PIPELINE_MARKER
        if marker.is_file():
            summary = read_json(marker)
            if isinstance(summary, dict):
                found.append((directory, summary))
    return sorted(found, key=lambda item: item[1].get("created_utc") or "")


def tree_bytes(directory: Path | S3Path, seen: set[tuple[int, int]] | None = None) -> int | None:
    """Bytes of the files under a local ``directory``; a file hard-linked from another run
    (adopted batches) counts once per ``seen`` set. None on an object store."""
    if isinstance(directory, S3Path):
        return None
    total = 0
    for folder, _, names in os.walk(directory):
        for name in names:
            try:
                stat = os.lstat(os.path.join(folder, name))
            except OSError:
                continue  # removed meanwhile
            if seen is not None:
                if (stat.st_dev, stat.st_ino) in seen:
                    continue
                seen.add((stat.st_dev, stat.st_ino))
            total += stat.st_size
    return total


def stored_runs(store: RunStore) -> list[Run]:
    """Every run of ``store`` (:meth:`RunStore.run_directories`), in name order."""
    return [Run(d) for d in store.run_directories()]


def store_catalog(store: RunStore, *, sizes: bool = True) -> list[CatalogEntry]:
    """Every run of ``store``, families newest first, each root followed by its runs in
    lineage order. ``size_bytes`` counts a file shared with an earlier-listed run of the
    store (hard-linked batches) once; an unreadable run is listed with its error."""
    entries: dict[str, CatalogEntry] = {}
    for run in stored_runs(store):
        try:
            summary = run.summary()
            lineage = run.lineage()
            entry = CatalogEntry(
                run_id=run.id,
                family=lineage[0] if lineage else run.id,
                depth=len(lineage),
                parent=summary.get("parent"),
                origin=summary.get("origin"),
                created_utc=summary.get("created_utc"),
                scenario=summary.get("scenario"),
                status=summary.get("status"),
                samples=summary.get("samples"),
                evaluated=summary.get("evaluated"),
                feasible=summary.get("feasible"),
                pipelines=[str(s.get("pipeline_id")) for _, s in pipeline_summaries(run)],
            )
        except (StoreError, OSError, ValueError) as err:
            entry = CatalogEntry(run_id=run.id, family=run.id, depth=0, error=str(err))
        entries[run.id] = entry
    families: dict[str, list[CatalogEntry]] = {}
    for entry in entries.values():
        families.setdefault(entry.family, []).append(entry)
    ordered: list[CatalogEntry] = []

    def newest(members: list[CatalogEntry]) -> str:
        return max(m.created_utc or "" for m in members)

    for _, members in sorted(families.items(), key=lambda kv: newest(kv[1]), reverse=True):
        ordered += sorted(members, key=lambda m: (m.depth, m.created_utc or "", m.run_id))
    if sizes:
        seen: set[tuple[int, int]] = set()
        for entry in ordered:
            entry.size_bytes = tree_bytes(store.root / entry.run_id, seen)
    return ordered


def family_root(store: RunStore, run_id: str) -> Run:
    """The run that holds the pipeline results of ``run_id``'s family: ``run_id`` itself
    when it has some, else the first of its lineage that has, else the stored pipeline
    result whose DoE, final or infill run is ``run_id`` (a pruned run is found so).

    Raises :class:`StoreError` naming the id when it is not an id (:func:`checked_id`) or
    no run or pipeline result knows it."""
    directory = store.root / checked_id(run_id)
    if (directory / MANIFEST).is_file():
        run = store.run(run_id)
        for rid in [run_id, *reversed(run.lineage())]:
            candidate = store.root / rid
            if (candidate / MANIFEST).is_file():
                ancestor = store.run(rid)
                if pipeline_summaries(ancestor):
                    return ancestor
        lineage = run.lineage()
        return store.run(lineage[0]) if lineage and (store.root / lineage[0]).is_dir() else run
    for run in stored_runs(store):
        for _, summary in pipeline_summaries(run):
            members = {summary.get("doe_run"), summary.get("final_run")}
            members |= {i.get("run_id") for i in summary.get("iterations", [])}
            members |= {i.get("infill_run") for i in summary.get("iterations", [])}
            if run_id in members:
                return run
    raise StoreError(f"{directory}: no such run (no manifest.json) in any pipeline family")
