"""What a batch of mission records stores: the stage rows, the mission totals and the
trajectory tables, as Parquet tables of the run store's declared schemas
(:mod:`ovtraj.runs.schemas`), and the timing columns the batch marker keeps instead."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.mission import STAGES, MissionRecord
from ovtraj.runs.schemas import DATASETS, TIMING_COLUMNS, stored_columns, stored_rows
from ovtraj.store.records import table_from_frame, table_from_rows

__all__ = ["batch_tables", "part_name", "result_rows"]


def part_name(batch: int) -> str:
    """The file name of batch ``batch``'s part of every dataset."""
    return f"part-{batch:05d}.parquet"


def result_rows(
    pairs: list[tuple[int, MissionRecord]],
) -> tuple[dict[str, list[dict[str, Any]]], dict[str, dict[str, Any]]]:
    """The rows a batch of (sample id, record) pairs stores, by dataset (``stages/<stage>``,
    for the stages some sample reached, and ``totals``), and the timing columns taken out of
    the stage rows (stage -> sample id -> value; kept in the batch marker, never in a table)."""
    rows: dict[str, list[dict[str, Any]]] = {}
    timing: dict[str, dict[str, Any]] = {}
    for stage in STAGES:
        found = []
        for sid, rec in pairs:
            if stage not in rec.stages:
                continue
            row = dict(rec.stages[stage])
            for column in TIMING_COLUMNS:
                if column in row:
                    timing.setdefault(stage, {})[str(sid)] = row.pop(column)
            found.append({"sample_id": sid, **row})
        if found:
            rows[f"stages/{stage}"] = found
    rows["totals"] = [{"sample_id": sid, **rec.totals()} for sid, rec in pairs]
    return rows, timing


def batch_tables(
    rows: dict[str, list[dict[str, Any]]],
    pairs: list[tuple[int, MissionRecord]],
    batch: int,
    trajectory_steps: dict[str, float],
) -> Iterator[tuple[str, pa.Table, str]]:
    """(file relative to the run, table, dataset) of every Parquet file batch ``batch``
    stores, each table built when it is asked for: per stage its rows (``rows`` from
    :func:`result_rows`) and its trajectories (sampled at ``trajectory_steps[stage]``,
    :func:`.schemas.stored_rows`), then the totals."""
    part = part_name(batch)
    for stage in STAGES:
        dataset = f"stages/{stage}"
        if dataset in rows:
            table = table_from_rows(rows[dataset], DATASETS[dataset], dataset)
            yield f"{dataset}/{part}", table, dataset
        dataset = f"trajectories/{stage}"
        if dataset not in DATASETS:
            continue
        frame = _trajectory_frame(pairs, stage, trajectory_steps)
        if frame is not None:
            yield f"{dataset}/{part}", table_from_frame(frame, DATASETS[dataset], dataset), dataset
    yield f"totals/{part}", table_from_rows(rows["totals"], DATASETS["totals"], "totals"), "totals"


def _trajectory_frame(
    pairs: list[tuple[int, MissionRecord]], stage: str, trajectory_steps: dict[str, float]
) -> pd.DataFrame | None:
    """The stored rows of a stage's trajectory tables of the batch, keyed by sample id; None
    when no sample has one."""
    tables = [
        (sid, rec.trajectories[stage]) for sid, rec in pairs if len(rec.trajectories.get(stage, ()))
    ]
    if not tables:
        return None
    # One concatenation and one selection for the batch: per sample they cost
    # ~6 ms, two thirds of a sample's storing (docs/mission.md).
    columns = stored_columns(stage)
    frame = pd.concat([table for _, table in tables], ignore_index=True)[columns]
    ids = np.repeat([sid for sid, _ in tables], [len(t) for _, t in tables])
    keep = np.concatenate([stored_rows(t, stage, trajectory_steps[stage]) for _, t in tables])
    frame = frame.loc[keep].reset_index(drop=True)
    frame.insert(0, "sample_id", ids[keep])
    return frame
