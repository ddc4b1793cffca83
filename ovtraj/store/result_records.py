"""Prefect's task result records, read as plain JSON data.

A persisted task result is one JSON document (Prefect 3.9, ``ResultRecord.serialize``)::

    {"metadata": {"storage_key": ..., "expiration": ..., "serializer": {"type": ...},
                  "prefect_version": ..., "storage_block_id": ...},
     "result": <the serializer's output, as text>}

Prefect deserialises ``result`` with the serializer the *record* names, whatever the
store was configured with: a record naming ``pickle`` runs code when Prefect reads it.
The flows write theirs with the plain JSON serializer of ``tasks/results.py``
(:data:`SERIALIZER`); this module reads a record's envelope without Prefect and without
decoding its result, so that the flows can refuse any other record before Prefect sees it,
and ``ovtraj prune`` counts as task results only the files that are records.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

from ovtraj.store.files import StoreError, read_bytes

__all__ = ["SERIALIZER", "RecordError", "check_record", "is_result_record", "record_serializer"]

SERIALIZER = "ovtraj-json"
"""The ``type`` of the one serializer whose records the flows read (``tasks/results.py``)."""


class RecordError(ValueError):
    """Bytes that are not a Prefect result record, or one this project does not read."""


def record_serializer(payload: bytes, source: str) -> str:
    """The serializer ``type`` a result record names; RecordError naming ``source`` if
    ``payload`` is not a result record (JSON with ``metadata.serializer.type`` and
    ``result``). The result itself is not decoded."""
    try:
        document: Any = json.loads(payload)
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise RecordError(f"{source}: not a Prefect result record (not JSON)") from None
    metadata = document.get("metadata") if isinstance(document, dict) else None
    serializer = metadata.get("serializer") if isinstance(metadata, dict) else None
    kind = serializer.get("type") if isinstance(serializer, dict) else None
    if not isinstance(kind, str) or "result" not in document:
        raise RecordError(f"{source}: not a Prefect result record")
    return kind


def check_record(payload: bytes, source: str) -> bytes:
    """``payload`` if it is a result record of :data:`SERIALIZER`; RecordError naming
    ``source`` and the serializer it names otherwise."""
    kind = record_serializer(payload, source)
    if kind != SERIALIZER:
        raise RecordError(
            f"{source}: a Prefect result record of serializer {kind[:40]!r}, refused: only "
            f"{SERIALIZER!r} records are read (others can run code when read)"
        )
    return payload


def is_result_record(path: Path) -> bool:
    """Whether ``path`` is a Prefect task result record (:func:`record_serializer`): a
    regular file, not a link, within ``reads.unrecorded_file_max_mib``
    (:func:`ovtraj.store.files.read_bytes`), whose JSON is a record's envelope. Its result,
    pickled or not, is never decoded."""
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return False
        record_serializer(read_bytes(path), str(path))
    except (OSError, StoreError, RecordError):
        return False
    return True
