"""The flights of a plan of a run store, stored beside it and shown in its report.

``ovtraj fly PLAN`` (the J2 replay) and ``ovtraj fly PLAN --fidelity high`` store their result
beside a plan of a run store (``<store>/<run>/pipeline/<id>/plans/<plan>.json``, the plan
listed by its marker ``<plan>.files.json``) as ``<plan>-flight-j2.json`` and
``<plan>-flight-high.json``:

- *Content*: the result ``ovtraj fly PLAN --json`` prints, less what is not a result of the
  plan and the code that flew it: the replay's wall time, and the folder of the force-model
  file read (its name and its settings are kept). The same plan, code and settings give the
  same bytes on any machine. Sealed as a marker is (:mod:`ovtraj.store.seals`).
- *Never overwritten*: the same flight flown again is left as it is; a different one under
  the same name (flown by another code version, or under other force-model settings) is
  refused, naming the file and the code versions. One flight per plan and fidelity keeps
  the name meaning one thing and the report showing which flight it holds (names by content
  would pile up flights with no order but a clock, which the store does not keep); the plan
  itself is refused the same way (:func:`ovtraj.mission.plan_store.write_plan`).
- *Covered*: each stored flight is listed in the plan's marker, so ``ovtraj verify`` checks
  it. The report, a view of stored results, is written again with its section of flights
  (:func:`ovtraj.pipeline.report.flown_section`; the rest of it is the plan's, checked
  against the marker first and left as it is), then the marker with the new digests.
  Planning the same point again (:func:`ovtraj.pipeline.planning.write_mission_plan`) reads
  the same flights (:func:`stored_flights`) and writes the same report.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

from ovtraj.mission.high_fidelity import FIDELITIES
from ovtraj.pipeline.report import FLOWN_END, FLOWN_START, flown_section
from ovtraj.pipeline.report_tables import FlightResultError, flight_shown
from ovtraj.store.files import (
    Digest,
    StoreError,
    file_digest,
    marker_files,
    read_bytes,
    write_bytes,
)
from ovtraj.store.layout import PIPELINE_DIR, PLAN_MARKER_SUFFIX, PLANS_DIR
from ovtraj.store.products import digests_json, directory_lock
from ovtraj.store.records import json_text
from ovtraj.store.seals import canonical_json, read_authenticated, write_sealed

__all__ = [
    "REPORT_SUFFIX",
    "StoredFlight",
    "flight_document",
    "flight_name",
    "store_flight",
    "stored_flights",
    "stored_plan_folder",
]

# The plan's report beside it: ``<plan>-report.html`` (ovtraj.pipeline.planning).
REPORT_SUFFIX = "-report.html"
# Fields of ``ovtraj fly --json`` that are not a result of the plan and the code: timing.
_TIMING_FIELDS = ("wall_time_s",)


def flight_name(plan_name: str, fidelity: str) -> str:
    """The file of the plan's flight at ``fidelity`` (``j2`` or ``high``)."""
    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity: {fidelity!r} is not one of {', '.join(FIDELITIES)}")
    return f"{plan_name}-flight-{fidelity}.json"


def stored_plan_folder(plan_path: Path) -> Path | None:
    """The plans folder of a run store that holds ``plan_path`` (``<store>/<run>/pipeline/
    <id>/plans/``, the plan's marker beside it); None for a plan file anywhere else."""
    plan_path = plan_path.resolve()
    folder = plan_path.parent
    if (
        folder.name != PLANS_DIR
        or len(plan_path.parents) < 5
        or plan_path.parents[2].name != PIPELINE_DIR
    ):
        return None
    if not (folder / f"{plan_path.stem}{PLAN_MARKER_SUFFIX}").is_file():
        return None
    return folder


def flight_document(row: Mapping[str, Any]) -> dict[str, Any]:
    """The stored content of a flight result as ``ovtraj fly PLAN --json`` prints it: without
    its timing, the force-model file by its name (where it was read is the machine's)."""
    document = {k: v for k, v in row.items() if k not in _TIMING_FIELDS}
    source = document.get("force_model_file")
    if isinstance(source, str):
        document["force_model_file"] = PurePath(source).name
    return document


def _fidelity_of(flight: Mapping[str, Any]) -> str:
    return "high" if flight.get("fidelity") == "high" else "j2"


def stored_flights(folder: Any, plan_name: str, plan: Any) -> list[tuple[Any, dict[str, Any]]]:
    """The flights stored beside the plan ``plan_name`` in ``folder`` (a local or object
    store's path), J2 then high, as (file, flight): each read and sealed as a marker is,
    checked against the digest the plan's marker lists for it (when it lists it), of its
    file's fidelity and of this ``plan`` (:func:`~ovtraj.pipeline.report_tables.flight_shown`);
    StoreError naming the file otherwise."""
    marker_path = folder / f"{plan_name}{PLAN_MARKER_SUFFIX}"
    listed: dict[str, Digest] = {}
    if marker_path.is_file():
        listed = marker_files(marker_path, read_authenticated(marker_path))
    flights = []
    for fidelity in FIDELITIES:
        path = folder / flight_name(plan_name, fidelity)
        if not path.exists():
            continue
        flight = read_authenticated(path, listed.get(path.name))
        if not isinstance(flight, dict) or _fidelity_of(flight) != fidelity:
            raise StoreError(f"{path}: not a {fidelity} flight of ovtraj fly")
        try:
            flight_shown(flight, plan)
        except FlightResultError as err:
            raise StoreError(f"{path}: {err}") from None
        flights.append((path, flight))
    return flights


class OtherFlightStored(StoreError):
    """A flight of the same plan and fidelity with other content (another code version)
    is stored: kept as it is, the new one not stored. Not a fault of the flight."""


@dataclass(frozen=True)
class StoredFlight:
    """Where ``ovtraj fly`` stored a flight: ``path``; ``new``: False when the same flight
    was stored already; ``report``: the report written again with it, None when the plan's
    report has no section of flights to write (one written before flights were stored)."""

    path: Path
    new: bool
    report: Path | None


def store_flight(plan_path: Path, plan: Any, row: Mapping[str, Any]) -> StoredFlight | None:
    """Store the flight ``row`` (as ``ovtraj fly PLAN --json`` prints it) of the plan read
    from ``plan_path`` beside it, list it in the plan's marker and write the plan's report
    again with its flights; None (nothing written) for a plan outside a run store.

    Checked before anything is written: the plan file and its report are the ones its
    marker lists (StoreError naming the file otherwise), and a flight of the same name
    stored with other content is refused (StoreError naming it and both code versions)."""
    folder = stored_plan_folder(plan_path)
    if folder is None:
        return None
    name = plan_path.resolve().stem
    document = flight_document(row)
    path = folder / flight_name(name, _fidelity_of(document))
    marker_path = folder / f"{name}{PLAN_MARKER_SUFFIX}"
    report = folder / f"{name}{REPORT_SUFFIX}"
    with directory_lock(folder):
        marker = read_authenticated(marker_path)
        files = marker_files(marker_path, marker)
        plan_file = plan_path.resolve().name
        if plan_file not in files:
            raise StoreError(f"{marker_path}: does not list {plan_file}")
        read_bytes(folder / plan_file, files[plan_file])  # the stored plan, unchanged
        text = None
        if report.name in files:
            text = read_bytes(report, files[report.name]).decode("utf-8")
        new = not path.exists()
        if not new:
            _same_flight(path, document, files.get(path.name))
            if path.name in files:  # stored, listed and shown already: nothing to write
                shown = report if text is not None and FLOWN_START in text else None
                return StoredFlight(path, False, shown)
        if new:
            write_sealed(path, document)
        files[path.name] = file_digest(path)
        written = None
        if text is not None:
            flights = [flight for _, flight in stored_flights(folder, name, plan)]
            section = flown_section(flights, plan)
            spliced = _with_section(text, section)
            if spliced is not None:
                files[report.name] = write_bytes(report, spliced.encode("utf-8"), replace=True)
                written = report
        write_sealed(marker_path, {**marker, "files": digests_json(files)}, replace=True)
    from ovtraj.tracking.catalog import refresh_entries

    # the plan's catalog row (and those of what it references) for its marker's new files;
    # the store's other rows are not read
    root = folder.parents[3]
    refresh_entries(root, [marker_path.relative_to(root).as_posix()])
    return StoredFlight(path, new, written)


def _same_flight(path: Path, document: Mapping[str, Any], expected: Digest | None) -> None:
    """Refuse a flight stored at ``path`` with content other than ``document``."""
    from ovtraj.config.io_limits import echoed

    stored = read_authenticated(path, expected)
    if isinstance(stored, Mapping) and canonical_json(stored) == canonical_json(document):
        return
    versions = ""
    if isinstance(stored, Mapping) and "replay_code_version" in document:
        before = echoed(json_text(stored.get("replay_code_version"), indent=None))
        versions = f" (stored by code {before}, flown now by {document['replay_code_version']})"
    raise OtherFlightStored(
        f"{path}: another flight of this plan is stored there{versions}; not overwritten "
        "(the flight above is printed only)"
    )


def _with_section(text: str, section: str) -> str | None:
    """``text`` (a report) with its one section of flights replaced by ``section``; None
    when it has no such section."""
    start = text.find(FLOWN_START)
    if start < 0 or text.find(FLOWN_START, start + 1) >= 0:
        return None
    end = text.find(FLOWN_END, start)
    if end < 0:
        return None
    return text[:start] + section + text[end + len(FLOWN_END) :]
