"""The validation and predictions tables of a surrogate set: their declared schemas, their
rows as a fit makes them, and their form in memory.

``validation``: one row per (model, candidate) with its CV and held-out metrics or its
error; ``predictions``: the CV and held-out predictions of the selected candidates. Both
are described in ``docs/surrogate.md``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.store.records import (
    BOOL,
    FLOAT,
    INT,
    TEXT,
    record_schema,
    table_from_frame,
    table_from_rows,
)
from ovtraj.surrogate.validation import ClassifierScore, RegressorScore

__all__ = [
    "FEASIBLE",
    "PREDICTIONS_SCHEMA",
    "STORED_VALIDATION_SCHEMA",
    "VALIDATION_SCHEMA",
    "classifier_rows",
    "prediction_rows",
    "predictions_table",
    "regressor_rows",
    "validation_frame",
    "validation_table",
]

FEASIBLE = "feasible"  # model name of the feasibility classifier in the tables

_TEXT = ("model", "kind", "candidate", "error")
_COUNTS = ("n_folds", "n_train", "n_heldout")
_METRICS = (
    "cv_rmse",
    "cv_q2",
    "heldout_rmse",
    "heldout_r2",
    "cv_accuracy",
    "cv_balanced_accuracy",
    "cv_log_loss",
    "heldout_accuracy",
    "fit_time_s",
)
VALIDATION_SCHEMA = record_schema(
    [
        ("model", TEXT),
        ("kind", TEXT),
        ("candidate", TEXT),
        ("selected", BOOL),
        *[(name, INT) for name in _COUNTS],
        *[(name, FLOAT) for name in _METRICS],
        ("error", TEXT),
    ],
    required=("model", "kind", "candidate", "selected"),
)
"""The validation table: one row per (model, candidate); an undefined metric is null."""
STORED_VALIDATION_SCHEMA = pa.schema([f for f in VALIDATION_SCHEMA if f.name != "fit_time_s"])
"""``validation.parquet``: the validation table without ``fit_time_s`` (timing, kept in
``meta.json``), so that two fits of the same data write identical tables."""
PREDICTIONS_SCHEMA = record_schema(
    [
        ("model", TEXT),
        ("sample_id", INT),
        ("split", TEXT),
        ("y_true", FLOAT),
        ("y_pred", FLOAT),
    ],
    required=("model", "sample_id", "split"),
)
"""``predictions.parquet``: CV and held-out predictions of the selected candidates."""
# Every row names every metric: the other kind's are null.
_NO_METRICS = dict.fromkeys(_METRICS)
# The validation table in memory: counts as Int64 and metrics as Float64 (<NA> when undefined).
_NULLABLE = {pa.int64(): pd.Int64Dtype(), pa.float64(): pd.Float64Dtype()}


def validation_frame(table: pa.Table) -> pd.DataFrame:
    """The validation table (:data:`VALIDATION_SCHEMA`) in memory: text as objects (None
    when missing), ``selected`` bool, counts Int64, metrics Float64."""
    frame = table.to_pandas(types_mapper=_NULLABLE.get)
    for column in _TEXT:
        values = frame[column].astype(object)
        frame[column] = values.where(values.notna(), None).astype(object)
    return frame


def validation_table(rows: list[dict[str, Any]]) -> pa.Table:
    """Rows of :func:`regressor_rows` and :func:`classifier_rows` as a checked table."""
    return table_from_rows(rows, VALIDATION_SCHEMA, "validation")


def predictions_table(frame: pd.DataFrame) -> pa.Table:
    """Frames of :func:`prediction_rows` (concatenated) as a checked table."""
    return table_from_frame(frame.reset_index(drop=True), PREDICTIONS_SCHEMA, "predictions")


def regressor_rows(output: str, scores: list[RegressorScore], chosen: str) -> list[dict]:
    """The validation rows of an output's regressor candidates."""
    return [
        {
            **_NO_METRICS,
            "model": output,
            "kind": "regressor",
            "candidate": s.name,
            "selected": s.name == chosen,
            "n_train": s.n_train,
            "n_heldout": s.n_heldout,
            "cv_rmse": s.cv_rmse,
            "cv_q2": s.cv_q2,
            "heldout_rmse": s.heldout_rmse,
            "heldout_r2": s.heldout_r2,
            "fit_time_s": s.fit_time_s,
            "error": s.error,
        }
        for s in scores
    ]


def classifier_rows(scores: list[ClassifierScore], chosen: str) -> list[dict]:
    """The validation rows of the feasibility classifier's candidates."""
    return [
        {
            **_NO_METRICS,
            "model": FEASIBLE,
            "kind": "classifier",
            "candidate": s.name,
            "selected": s.name == chosen,
            "n_train": s.n_train,
            "n_heldout": s.n_heldout,
            "cv_accuracy": s.cv_accuracy,
            "cv_balanced_accuracy": s.cv_balanced_accuracy,
            "cv_log_loss": s.cv_log_loss,
            "heldout_accuracy": s.heldout_accuracy,
            "fit_time_s": s.fit_time_s,
            "error": s.error,
        }
        for s in scores
    ]


def prediction_rows(
    model: str,
    train_ids: np.ndarray,
    y_train: np.ndarray,
    cv_pred: np.ndarray,
    held_ids: np.ndarray,
    y_held: np.ndarray,
    held_pred: np.ndarray,
) -> pd.DataFrame:
    """The predictions rows of a selected model: its CV predictions, then its held-out ones."""
    return pd.DataFrame(
        {
            "model": model,
            "sample_id": np.concatenate([train_ids, held_ids]),
            "split": ["cv"] * train_ids.size + ["heldout"] * held_ids.size,
            "y_true": np.concatenate([y_train, y_held]).astype(float),
            "y_pred": np.concatenate([cv_pred, held_pred]).astype(float),
        }
    )
