"""The run store's layout: the names of its folders and documents, and what an id looks like.

A run is ``<store>/<run id>/`` with its ``manifest.json``; a pipeline result lives in its DoE
run, ``pipeline/<pipeline id>/pipeline.json`` (its summary, written last), with its plans,
``plans/<name>.json`` and ``<name>.files.json`` (the digests of the plan's files, written
last). Ids are :data:`ID_HEX_DIGITS` hexadecimal digits of a SHA-256. Kept apart from the
run store's code (``ovtraj.runs.store``) so that a reader of the layout (the catalog,
``ovtraj runs``) does not import the mission chain.
"""

from __future__ import annotations

import re

__all__ = [
    "ID_HEX_DIGITS",
    "MANIFEST",
    "PIPELINE_DIR",
    "PIPELINE_MARKER",
    "PLANS_DIR",
    "PLAN_MARKER_SUFFIX",
    "is_id",
]

# Run ids (ovtraj.runs.ids.run_id) and the ids of a run's products (surrogate fits,
# fronts, pipeline results: ovtraj.pipeline.steps.content_id) are this many hexadecimal
# digits of a SHA-256. An id is a folder name of the store: one that is not such a string
# (``..``, a ``/``, a newline that would forge a log line) is refused where it enters
# (ovtraj.runs.ids.checked_id).
ID_HEX_DIGITS = 16
ID_PATTERN = re.compile(f"[0-9a-f]{{{ID_HEX_DIGITS}}}")
MANIFEST = "manifest.json"
PIPELINE_DIR = "pipeline"
PIPELINE_MARKER = "pipeline.json"
PLANS_DIR = "plans"
PLAN_MARKER_SUFFIX = ".files.json"


def is_id(name: str) -> bool:
    """Whether ``name`` is an id of the store (a run's folder name, a product's id)."""
    return ID_PATTERN.fullmatch(name) is not None
