"""The run store's datasets and their declared schemas (store format :data:`SCHEMA_VERSION`).

Each dataset is a folder of Parquet parts (one per batch) or one file, and every
part has exactly its dataset's schema, built from the typed results' own
declarations (``ROW_SCHEMA`` and ``TRAJECTORY_SCHEMA`` of each stage's result,
:data:`ovtraj.mission.chain.LAUNCH_ROW_SCHEMA`, :data:`ovtraj.mission.chain.TOTALS_SCHEMA`):

============================  ===============================================================
``samples.parquet``           ``sample_id`` and the design variables
``totals/``                   ``sample_id`` and the mission totals
``stages/<stage>/``           ``sample_id`` and the stage's row, without its timing columns
``trajectories/<stage>/``     ``sample_id`` and the stage's trajectory table as stored:
                              downsampled (:func:`stored_trajectory`); the rendezvous and
                              transfer tables without the target's states (the target's
                              orbit is in the config; ``range_m`` is kept)
============================  ===============================================================

Timing (:data:`TIMING_COLUMNS`) is not a result: it goes to the batch marker, so two
runs of one config and seed write byte-identical Parquet files.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.deorbit.result import ROW_SCHEMA as DEORBIT_ROW
from ovtraj.deorbit.result import TRAJECTORY_SCHEMA as DEORBIT_TRAJECTORY
from ovtraj.mission.chain import DESIGN_NAMES, LAUNCH_ROW_SCHEMA, STAGES, TOTALS_SCHEMA
from ovtraj.reentry.result import ROW_SCHEMA as REENTRY_ROW
from ovtraj.reentry.result import TRAJECTORY_SCHEMA as REENTRY_TRAJECTORY
from ovtraj.rendezvous.result import ROW_SCHEMA as RENDEZVOUS_ROW
from ovtraj.rendezvous.result import TRAJECTORY_SCHEMA as RENDEZVOUS_TRAJECTORY
from ovtraj.store.records import FLOAT, INT, record_schema

__all__ = [
    "DATASETS",
    "SCHEMA_VERSION",
    "TIMING_COLUMNS",
    "stored_columns",
    "stored_rows",
    "stored_trajectory",
    "trajectory_time_column",
]

SCHEMA_VERSION = 2
"""Store format: 2 = declared schemas, checksums in the batch markers, no timing in tables."""

TIMING_COLUMNS = ("wall_time_s",)
"""Stage-row columns that measure the run rather than the result (kept in the marker)."""

_KEY = pa.field("sample_id", INT, nullable=False)

_STAGE_ROWS = {
    "launch": LAUNCH_ROW_SCHEMA,
    "rendezvous": RENDEZVOUS_ROW,
    "transfer": RENDEZVOUS_ROW,
    "deorbit": DEORBIT_ROW,
    "reentry": REENTRY_ROW,
}

_TARGET_COLUMNS = tuple(f for f in RENDEZVOUS_TRAJECTORY.names if f.startswith("target_"))
_STORED_TRAJECTORIES = {
    "rendezvous": RENDEZVOUS_TRAJECTORY,
    "transfer": RENDEZVOUS_TRAJECTORY,
    "deorbit": DEORBIT_TRAJECTORY,
    "reentry": REENTRY_TRAJECTORY,
}
_DROPPED = {"rendezvous": _TARGET_COLUMNS, "transfer": _TARGET_COLUMNS}


def _keyed(schema: pa.Schema, drop: tuple[str, ...] = ()) -> pa.Schema:
    return pa.schema([_KEY, *(f for f in schema if f.name not in drop)])


SAMPLES = record_schema(
    [("sample_id", INT), *[(name, FLOAT) for name in DESIGN_NAMES]],
    required=("sample_id", *DESIGN_NAMES),
)

DATASETS: dict[str, pa.Schema] = {
    "samples": SAMPLES,
    "totals": _keyed(TOTALS_SCHEMA),
    **{f"stages/{s}": _keyed(_STAGE_ROWS[s], TIMING_COLUMNS) for s in STAGES},
    **{
        f"trajectories/{s}": _keyed(schema, _DROPPED.get(s, ()))
        for s, schema in _STORED_TRAJECTORIES.items()
    },
}
"""Every dataset of a run (folder name under the run, or ``samples``) and its schema."""


def trajectory_time_column(stage: str) -> str:
    return "t_s" if stage in ("rendezvous", "transfer") else "time_s"


def stored_rows(table: pd.DataFrame, stage: str, step_s: float) -> np.ndarray:
    """Which rows (a boolean mask) of a stage's trajectory table the store keeps.

    The first and last row of every phase (so burns and phase changes are exact), and
    otherwise the first row at least ``step_s`` after the previous kept one.
    """
    t = table[trajectory_time_column(stage)].to_numpy(dtype=float)
    keep = np.zeros(len(t), dtype=bool)
    if len(t) == 0:
        return keep
    phase = table["phase"].to_numpy() if "phase" in table else np.zeros(len(t))
    ends = np.zeros(len(t), dtype=bool)
    ends[0] = ends[-1] = True
    changes = np.flatnonzero(phase[1:] != phase[:-1])
    ends[changes] = True
    ends[changes + 1] = True
    last = -np.inf
    for k, (time, end) in enumerate(zip(t.tolist(), ends.tolist(), strict=True)):
        if end or time - last >= step_s:
            keep[k] = True
            last = time
    return keep


def stored_columns(stage: str) -> list[str]:
    """The stored columns of a stage's trajectory table, without ``sample_id``."""
    return [c for c in DATASETS[f"trajectories/{stage}"].names if c != "sample_id"]


def stored_trajectory(table: pd.DataFrame, stage: str, step_s: float) -> pd.DataFrame:
    """The rows of a stage's trajectory table that the store keeps (:func:`stored_rows`),
    in the dataset's columns (:data:`DATASETS`), without ``sample_id``."""
    if len(table) == 0:
        return table
    return table.loc[stored_rows(table, stage, step_s), stored_columns(stage)].reset_index(
        drop=True
    )
