"""What the store's catalog is made of (:mod:`ovtraj.tracking.catalog`): its folder in the
store, its columns with their types and units (:data:`SCHEMA`), its settings, and the row
every kind of item starts from, the ids it names checked."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pyarrow as pa

from ovtraj.formatting import printable
from ovtraj.store.backends import S3Path
from ovtraj.store.layout import is_id

__all__ = [
    "CATALOG_DIR",
    "COLUMNS",
    "KINDS",
    "SCHEMA",
    "catalog_folder",
    "catalog_settings",
    "checked_id",
    "new_row",
]

CATALOG_DIR = "catalog"
KINDS = ("run", "pipeline", "plan", "monte_carlo")

# Every column, its type and unit (units in the names, docs/conventions.md).
SCHEMA = pa.schema(
    [
        pa.field("kind", pa.string(), nullable=False),  # run | pipeline | plan | monte_carlo
        pa.field("id", pa.string(), nullable=False),
        pa.field("source", pa.string(), nullable=False),  # the document, relative to the store
        pa.field("source_sha256", pa.string(), nullable=False),
        pa.field("created_utc", pa.string()),
        pa.field("scenario", pa.string()),
        pa.field("target", pa.string()),
        pa.field("element_set_epoch_utc", pa.string()),
        pa.field("code_version", pa.string()),
        pa.field("status", pa.string()),
        pa.field("error", pa.string()),  # why the document could not be read
        pa.field("family", pa.string()),  # a run's root run
        pa.field("depth", pa.int32()),  # 0 for a family's root
        pa.field("parent", pa.string()),
        pa.field("doe_run", pa.string()),
        pa.field("run_id", pa.string()),  # a pipeline's or plan's final run
        pa.field("pipeline_id", pa.string()),
        pa.field("plan_id", pa.string()),  # a Monte Carlo's plan
        pa.field("origin", pa.string()),
        pa.field("samples", pa.int64()),
        pa.field("evaluated", pa.int64()),
        pa.field("feasible", pa.int64()),
        pa.field("front_points", pa.int64()),
        pa.field("hypervolume", pa.float64()),
        pa.field("converged", pa.bool_()),
        pa.field("stop_reason", pa.string()),
        pa.field("launch_epoch_utc", pa.string()),  # the plan's drop
        pa.field("t_total_s", pa.float64()),
        pa.field("dv_total_mps", pa.float64()),
        pa.field("m_load_kg", pa.float64()),
        pa.field("landing_miss_m", pa.float64()),
        pa.field("mc_runs", pa.int64()),
        pa.field("mc_landing_miss_p95_m", pa.float64()),
        pa.field("mc_dv_margin_p95_mps", pa.float64()),
        pa.field("tags", pa.string(), nullable=False),  # JSON object, keys sorted
    ]
)
COLUMNS = SCHEMA.names


def catalog_settings() -> Any:
    """``catalog`` of configs/orchestration.yaml."""
    from ovtraj.config.orchestration import load_orchestration

    return load_orchestration().catalog


def catalog_folder(root: Path | S3Path) -> Path | S3Path:
    """The catalog's folder in the store ``root``."""
    return root / CATALOG_DIR


def checked_id(value: Any, what: str = "id") -> str:
    """``value`` if it is an id of the store, else :func:`ovtraj.runs.ids.checked_id`'s
    error (loaded only then: the run store's code imports the mission chain, ~1.4 s)."""
    if isinstance(value, str) and is_id(value):
        return value
    from ovtraj.runs.ids import checked_id as checked

    return checked(value, what)


# Columns that name another item: ids read from a stored document, so checked like an id
# typed on the command line before a reader follows them (`ovtraj runs`, `history`).
ID_COLUMNS = ("family", "parent", "doe_run", "run_id", "pipeline_id", "plan_id")


def new_row(kind: str, item_id: str, source: str, digest: str, **values: Any) -> dict[str, Any]:
    """The row of an item: every column of :data:`SCHEMA` (None where ``values`` gives
    none), no tags; :class:`ValueError` when a column of :data:`ID_COLUMNS` is not an id."""
    for column in ID_COLUMNS:
        value = values.get(column)
        if value is not None and not (isinstance(value, str) and is_id(value)):
            raise ValueError(f"{column} {printable(str(value))[:40]!r} is not an id")
    row: dict[str, Any] = dict.fromkeys(COLUMNS)
    row.update(kind=kind, id=item_id, source=source, source_sha256=digest, tags="{}")
    row.update(values)
    return row
