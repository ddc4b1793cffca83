"""A stored run checked like fsck (:meth:`ovtraj.runs.store.Run.verify`): every file
against its recorded digest and schema, the documents' seals with a store key."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow as pa

from ovtraj.runs.schemas import DATASETS
from ovtraj.store.files import StoreError, marker_files, read_json
from ovtraj.store.layout import MANIFEST
from ovtraj.store.verification import VerifyReport

if TYPE_CHECKING:
    from ovtraj.runs.store import Run

__all__ = ["PRODUCT_MARKERS", "RUN_FILES", "verify_run"]

# The files the manifest lists (by digest).
RUN_FILES = ("config.json", "samples.parquet")
# Markers of a run's pipeline products (glob patterns under the run); each lists its
# files, relative to its own folder, with their digests.
PRODUCT_MARKERS = (
    "surrogates/*/meta.json",
    "fronts/*/meta.json",
    "pipeline/*/pipeline.json",
    "pipeline/*/plans/*.files.json",
)

# A file to check: its path, the digest recorded for it, its schema (None: not Parquet).
Expected = tuple[Path, Any, pa.Schema | None]


def verify_run(run: Run) -> VerifyReport:
    """Check every file of the run against its recorded digest and schema (like fsck).

    Covered files: the manifest's (config, samples), each batch marker's, and those
    listed by the markers of the run's surrogate fits, fronts and pipeline results.
    Files that nothing lists are reported as uncovered (readers never use them). With
    a store key configured, the manifest and every marker whose seal is missing or wrong
    are reported as tampered (:mod:`ovtraj.store.seals`); the files such a marker lists are
    still checked against its digests, for accidents.
    """
    report = VerifyReport(run.id)
    covered = {run.directory / MANIFEST}
    try:
        manifest = run.manifest_document()
    except StoreError as err:
        report.problems.append(str(err))
        return report
    report.check_document(run.directory / MANIFEST, manifest)
    recorded = manifest.get("files")
    recorded = recorded if isinstance(recorded, dict) else {}
    expected: list[Expected] = []
    for name in RUN_FILES:
        schema = DATASETS["samples"] if name == "samples.parquet" else None
        expected.append((run.directory / name, recorded.get(name), schema))
    expected += _batch_files(run.directory, report, covered)
    expected += _product_files(run.directory, report, covered)
    for path, digest, schema in expected:
        covered.add(path)
        report.check_file(path, digest, schema)
    report.find_uncovered(run.directory, covered)
    return report


def _batch_files(directory: Path, report: VerifyReport, covered: set[Path]) -> list[Expected]:
    """The files the run's batch markers list; each marker is checked (seal, names inside
    the run, usable digests) and added to ``covered``, its problems to ``report``."""
    expected: list[Expected] = []
    for path in sorted((directory / "batches").glob("*")):
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
            expected.append((directory / relative, digest, DATASETS.get(dataset)))
    return expected


def _product_files(directory: Path, report: VerifyReport, covered: set[Path]) -> list[Expected]:
    """The files the markers of the run's products list (:data:`PRODUCT_MARKERS`); each
    marker is checked and added to ``covered``, its problems to ``report``."""
    expected: list[Expected] = []
    for pattern in PRODUCT_MARKERS:
        for marker_path in sorted(directory.glob(pattern)):
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
    return expected
