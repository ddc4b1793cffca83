"""The run store seen by families: a DoE run, the runs that extend it, its pipeline results
(the listing itself is the catalog's, ovtraj.tracking.catalog).

A pipeline's infill rounds each create a child run (``extend_run``) that holds every
sample of its parent plus the new ones; the pipeline result itself is stored in the DoE
run (``<doe run>/pipeline/<pipeline id>/``). A family is a root run (no parent) and every
run whose lineage starts with it. Any run id of a family leads to its pipeline results
(:func:`family_root`), also once its intermediate runs are pruned.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ovtraj.pipeline.loop import MARKER as PIPELINE_MARKER
from ovtraj.runs import Run, RunStore, StoreError
from ovtraj.runs.ids import checked_id
from ovtraj.store.backends import S3Path
from ovtraj.store.files import read_json
from ovtraj.store.layout import MANIFEST

__all__ = ["family_root", "pipeline_summaries"]


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
    for run in (Run(d) for d in store.run_directories()):
        for _, summary in pipeline_summaries(run):
            members = {summary.get("doe_run"), summary.get("final_run")}
            members |= {i.get("run_id") for i in summary.get("iterations", [])}
            members |= {i.get("infill_run") for i in summary.get("iterations", [])}
            if run_id in members:
                return run
    raise StoreError(f"{directory}: no such run (no manifest.json) in any pipeline family")
