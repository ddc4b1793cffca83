"""Fitting, selecting and storing the surrogate set of the whole-mission chain (issue 7).

:func:`fit_surrogates` turns a design of experiments (physical inputs, the chain's outputs,
the feasibility flags) into a :class:`SurrogateSet`: one SMT regressor per output, chosen
among ``settings.regressors`` by k-fold cross-validation on the feasible training samples,
and one scikit-learn classifier of feasibility, chosen among ``settings.classifiers``.
The method (unit-cube scaling, stratified held-out split, k-fold CV, metrics) is described
in :mod:`ovtraj.surrogate.validation` and ``docs/surrogate.md``.

Store layout of :meth:`SurrogateSet.save` (one directory)::

    models.parquet        the fitted models' arrays (training inputs and values, Kriging's
                          fitted state), declared schema; rebuilt on load
                          (:mod:`ovtraj.surrogate.model_data`)
    validation.parquet    one row per (model, candidate): CV and held-out metrics, errors
    predictions.parquet   CV and held-out predictions of the selected candidates
    meta.json             data hash, selection, settings, names, bounds, library versions,
                          each model's description (``models``: candidate, inputs, fitted
                          hyperparameters), the caller's meta, and ``files``: the size
                          and SHA-256 of the three files above (and of any plots the
                          caller lists)

The two tables have declared schemas (:data:`VALIDATION_SCHEMA`, :data:`PREDICTIONS_SCHEMA`).
``meta.json`` is the product's marker (:mod:`ovtraj.store.products`), written last; :meth:`load`
checks every file against it (size, SHA-256, schema) before parsing, and names a missing or
changed file. Nothing stored is an executable format (issue 44): the models are data,
rebuilt with the same library calls and checked to reproduce their fitted predictions to
the bit.
"""

from __future__ import annotations

import dataclasses
import hashlib
import platform
import threading
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Executor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import sklearn
import smt
from pydantic import ValidationError

from ovtraj.config.mission import SurrogateSettings
from ovtraj.parallel import blas_threads, mapped, started
from ovtraj.store.backends import location
from ovtraj.store.files import Digest, StoreError, read_json
from ovtraj.store.products import Product
from ovtraj.store.records import (
    BOOL,
    FLOAT,
    INT,
    TEXT,
    json_text,
    record_schema,
    table_from_frame,
    table_from_rows,
)
from ovtraj.store.seals import authenticated
from ovtraj.surrogate.candidates import (
    ALL_FEASIBLE,
    KRIGING,
    CandidateError,
    FeasibilityClassifier,
    Regressor,
    fit_classifier,
    fit_regressor,
    seeded_subsample,
)
from ovtraj.surrogate.model_data import (
    MODEL_ARRAYS_SCHEMA,
    ModelData,
    arrays_table,
    classifier_data,
    model_data,
    rebuilt_classifier,
    rebuilt_regressor,
    regressor_data,
)
from ovtraj.surrogate.scaling import SurrogateError, UnitCube
from ovtraj.surrogate.validation import (
    ClassifierScore,
    Folds,
    RegressorFit,
    RegressorScore,
    classification_folds,
    evaluate_classifier,
    holdout_mask,
    regression_folds,
    regressor_fit,
    regressor_fit_arguments,
    regressor_score,
    select_classifier,
    select_regressor,
    subsampled_folds,
)

__all__ = [
    "FEASIBLE",
    "PREDICTIONS_SCHEMA",
    "STORED_VALIDATION_SCHEMA",
    "VALIDATION_SCHEMA",
    "SurrogateSet",
    "fit_surrogates",
    "training_data_hash",
]

FEASIBLE = "feasible"  # model name of the feasibility classifier in the tables
# 2: file digests (size, SHA-256) in meta.json, declared table schemas; 3: the models as
# data (models.parquet and meta.json's "models"), no pickle (issue 44)
STORE_FORMAT = 3
MODELS_FILE = "models.parquet"
VALIDATION_FILE = "validation.parquet"
PREDICTIONS_FILE = "predictions.parquet"
META_FILE = "meta.json"

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
# The validation table in memory: counts as Int64 and metrics as Float64 (<NA> when undefined).
_NULLABLE = {pa.int64(): pd.Int64Dtype(), pa.float64(): pd.Float64Dtype()}


def training_data_hash(
    X: np.ndarray,
    outputs: dict[str, np.ndarray],
    feasible: np.ndarray,
) -> str:
    """SHA-256 (first 16 hex digits) of the exact training data.

    Hashed in this order, each as little-endian float64 bytes preceded by a tag and its
    shape: X, feasible (0/1), then every output in sorted name order. NaNs are hashed as
    one canonical NaN, so only the values count, not a NaN's payload bits.
    """
    digest = hashlib.sha256()

    def add(tag: str, values: np.ndarray) -> None:
        array = np.ascontiguousarray(np.asarray(values, dtype=float), dtype="<f8")
        array = np.where(np.isnan(array), np.nan, array).astype("<f8")
        digest.update(f"{tag}{array.shape}".encode() + b"\0")
        digest.update(array.tobytes())

    add("X", X)
    add("feasible", np.asarray(feasible, dtype=bool).astype(float))
    for name in sorted(outputs):
        add(f"output:{name}", outputs[name])
    return digest.hexdigest()[:16]


def _validation_frame(table: pa.Table) -> pd.DataFrame:
    """The validation table (:data:`VALIDATION_SCHEMA`) in memory: text as objects (None
    when missing), ``selected`` bool, counts Int64, metrics Float64."""
    frame = table.to_pandas(types_mapper=_NULLABLE.get)
    for column in _TEXT:
        values = frame[column].astype(object)
        frame[column] = values.where(values.notna(), None).astype(object)
    return frame


def _with_fit_times(stored: pa.Table, meta: dict[str, Any]) -> pa.Table:
    """The stored validation table with ``fit_time_s`` from the marker's timing record."""
    times = {(m, c): t for m, c, t in meta.get("timing", {}).get("fit_time_s", [])}
    models, candidates = stored.column("model").to_pylist(), stored.column("candidate").to_pylist()
    keys = zip(models, candidates, strict=True)
    column = pa.array([times.get(key) for key in keys], type=pa.float64())
    index = VALIDATION_SCHEMA.get_field_index("fit_time_s")
    return stored.add_column(index, VALIDATION_SCHEMA.field("fit_time_s"), column)


def _validation_table(rows: list[dict[str, Any]]) -> pa.Table:
    return table_from_rows(rows, VALIDATION_SCHEMA, "validation")


def _predictions_table(frame: pd.DataFrame) -> pa.Table:
    return table_from_frame(frame.reset_index(drop=True), PREDICTIONS_SCHEMA, "predictions")


class SurrogateSet:
    """Selected surrogates of every output and of feasibility, with their validation.

    Attributes: ``input_names``, ``output_names``, ``cube`` (the design space's
    :class:`UnitCube`), ``selected`` (output name -> candidate; ``"feasible"`` ->
    classifier or ``"all-feasible"``), ``validation`` and ``predictions`` (tables, see
    ``docs/surrogate.md``), ``data_hash`` (:func:`training_data_hash`), ``settings``, and
    ``meta`` (the contents of ``meta.json`` for a loaded set; empty after a fit).
    """

    def __init__(
        self,
        *,
        input_names: tuple[str, ...],
        output_names: tuple[str, ...],
        cube: UnitCube,
        regressors: dict[str, Regressor],
        classifier: FeasibilityClassifier,
        selected: dict[str, str],
        validation: pd.DataFrame,
        predictions: pd.DataFrame,
        data_hash: str,
        settings: SurrogateSettings,
        meta: dict[str, Any] | None = None,
    ) -> None:
        self.input_names = tuple(input_names)
        self.output_names = tuple(output_names)
        self.cube = cube
        self._regressors = dict(regressors)
        self._classifier = classifier
        self.selected = dict(selected)
        self.validation = validation
        self.predictions = predictions
        self.data_hash = data_hash
        self.settings = settings
        self.meta = dict(meta or {})

    def __repr__(self) -> str:
        return (
            f"SurrogateSet(inputs={self.input_names}, selected={self.selected}, "
            f"data_hash={self.data_hash!r})"
        )

    @property
    def output_inputs(self) -> dict[str, tuple[str, ...]]:
        """The outputs fitted on some of the inputs only -> those inputs' names."""
        return {
            name: tuple(self.input_names[k] for k in regressor.columns)
            for name, regressor in self._regressors.items()
            if regressor.columns is not None
        }

    def _unit(self, X: np.ndarray) -> np.ndarray:
        try:
            x = np.asarray(X, dtype=float)
        except (TypeError, ValueError) as err:
            raise SurrogateError(f"X: not a numeric array ({err})") from None
        if x.ndim != 2 or x.shape[1] != self.cube.dim:
            raise SurrogateError(
                f"X: expected shape (m, {self.cube.dim}) for inputs {self.input_names}, "
                f"got {x.shape}"
            )
        if not np.all(np.isfinite(x)):
            raise SurrogateError("X: NaN or infinite values; every input must be finite")
        return self.cube.to_unit(x)

    def predict(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Physical inputs (m, d) -> {output name: prediction (m,)} of the selected models."""
        u = self._unit(X)
        if u.shape[0] == 0:
            return {name: np.empty(0) for name in self.output_names}
        return {name: self._regressors[name].predict(u) for name in self.output_names}

    def feasibility(self, X: np.ndarray) -> np.ndarray:
        """Physical inputs (m, d) -> probability of feasibility (m,) in [0, 1]."""
        u = self._unit(X)
        return self._classifier.proba(u) if u.shape[0] else np.empty(0)

    # -- storage --------------------------------------------------------------------------

    def _model_data(self) -> dict[str, ModelData]:
        """Every model as data, outputs in order, then the feasibility classifier."""
        models = {name: regressor_data(self._regressors[name]) for name in self.output_names}
        return models | {FEASIBLE: classifier_data(self._classifier)}

    def save(
        self,
        directory: Path,
        *,
        meta: dict[str, Any],
        views: dict[str, Digest] | None = None,
    ) -> dict[str, Digest]:
        """Write the set to ``directory`` (layout in the module docstring), ``meta.json`` last.

        ``meta`` (e.g. the run id) is merged into ``meta.json``; its keys must not collide
        with the set's own keys and its values must be JSON-serialisable. ``views`` are
        files already written there (plots) to list in ``meta.json`` too. Returns the
        digest of every file written, ``meta.json`` included. A stored set is never
        overwritten: saving other content over it raises :class:`~ovtraj.store.files.StoreError`.
        """
        directory = location(directory)
        own: dict[str, Any] = {
            "format": STORE_FORMAT,
            "data_hash": self.data_hash,
            "selected": self.selected,
            "settings": self.settings.model_dump(mode="json"),
            "input_names": list(self.input_names),
            "output_names": list(self.output_names),
            "output_inputs": {k: list(v) for k, v in self.output_inputs.items()},
            "lower": np.asarray(self.cube.lower).tolist(),
            "upper": np.asarray(self.cube.upper).tolist(),
            "versions": _versions(),
            "models": {},
        }
        reserved = {*own, "files", "timing"}
        clash = sorted(reserved & set(meta))
        if clash:
            raise SurrogateError(
                f"save: meta keys {clash} are reserved by the surrogate store "
                f"(reserved: {sorted(reserved)})"
            )
        document = {**meta, **own}
        try:
            json_text(document)
        except (TypeError, ValueError) as err:
            raise SurrogateError(f"save: meta is not JSON-serialisable ({err})") from None
        # A set that could not be rebuilt from its data is never written. Fits, their
        # predictions at the training inputs and rebuilds all run with one BLAS thread, as
        # the fits did: a LAPACK factorisation's last bits depend on the thread count.
        with _serial_blas():
            models = self._model_data()
            _rebuilt(models, self.output_names, self.cube.dim, self.settings)
        own["models"] = document["models"] = {k: m.description() for k, m in models.items()}
        validation = table_from_frame(
            self.validation.drop(columns="fit_time_s"), STORED_VALIDATION_SCHEMA, "validation"
        )
        document["timing"] = {
            "fit_time_s": [
                [row.model, row.candidate, None if pd.isna(row.fit_time_s) else row.fit_time_s]
                for row in self.validation.itertuples(index=False)
            ]
        }
        predictions = _predictions_table(self.predictions)
        with Product(directory, META_FILE).writing() as out:
            out.write_table(MODELS_FILE, arrays_table(models), MODEL_ARRAYS_SCHEMA)
            out.write_table(VALIDATION_FILE, validation, STORED_VALIDATION_SCHEMA)
            out.write_table(PREDICTIONS_FILE, predictions, PREDICTIONS_SCHEMA)
            for name, digest in (views or {}).items():
                out.add(name, digest)
            out.finish(document)
        return dict(out.files)

    @classmethod
    def load(cls, directory: Path, expected: Digest | None = None) -> SurrogateSet:
        """Read a set written by :meth:`save`; SurrogateError names a missing or changed file.

        ``expected`` is the digest of ``meta.json`` when a parent product lists it.
        """
        directory = location(directory)
        product = Product(directory, META_FILE)
        meta_path = product.marker_path
        if not meta_path.is_file():
            raise SurrogateError(f"{meta_path}: missing (not a saved surrogate set)")
        try:
            meta = authenticated(meta_path, read_json(meta_path, expected))
        except StoreError as err:
            raise SurrogateError(str(err)) from None
        found = meta.get("format") if isinstance(meta, dict) else None
        if found != STORE_FORMAT:
            raise SurrogateError(
                f"{meta_path}: unknown store format {found!r} (this version reads format "
                f"{STORE_FORMAT}): fit the surrogates again"
            )
        try:
            if not isinstance(meta["files"], dict):
                raise TypeError("'files' is not a mapping")
            settings = SurrogateSettings.model_validate(meta["settings"])
        except (KeyError, TypeError, ValueError, ValidationError) as err:
            raise SurrogateError(f"{meta_path}: corrupt or outdated content ({err})") from None
        try:
            arrays = product.read_table(MODELS_FILE, MODEL_ARRAYS_SCHEMA, meta)
            stored = product.read_table(VALIDATION_FILE, STORED_VALIDATION_SCHEMA, meta)
            validation = _validation_frame(_with_fit_times(stored, meta))
            predictions = product.read_frame(PREDICTIONS_FILE, PREDICTIONS_SCHEMA, meta)
        except StoreError as err:
            raise SurrogateError(str(err)) from None
        try:
            input_names = tuple(_names(meta, "input_names"))
            output_names = tuple(_names(meta, "output_names"))
            cube = UnitCube(_bounds(meta, "lower"), _bounds(meta, "upper"))
            selected = {str(k): str(v) for k, v in dict(meta["selected"]).items()}
            if len(input_names) != cube.dim:
                raise ValueError(f"{len(input_names)} input names for {cube.dim} bounds")
        except (KeyError, TypeError, ValueError, SurrogateError) as err:
            raise SurrogateError(f"{meta_path}: corrupt or outdated content ({err})") from None
        models = model_data(meta.get("models"), arrays, str(directory / MODELS_FILE))
        with _serial_blas():  # as the fit (see save)
            regressors, classifier = _rebuilt(
                models, output_names, cube.dim, settings, str(meta_path)
            )
        stored = meta.get("versions", {})
        current = _versions()
        changed = {k: (stored.get(k), v) for k, v in current.items() if stored.get(k) != v}
        if changed.keys() & {"smt", "scikit-learn"}:
            warnings.warn(
                f"{meta_path}: fitted with other library versions {changed}; refit if in doubt",
                stacklevel=2,
            )
        return cls(
            input_names=input_names,
            output_names=output_names,
            cube=cube,
            regressors=regressors,
            classifier=classifier,
            selected=selected,
            validation=validation,
            predictions=predictions,
            data_hash=str(meta["data_hash"]),
            settings=settings,
            meta=meta,
        )


def _names(meta: dict[str, Any], key: str) -> list[str]:
    names = meta[key]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise TypeError(f"{key!r} is not a list of names")
    return names


def _bounds(meta: dict[str, Any], key: str) -> np.ndarray:
    values = np.asarray(meta[key], dtype=float)
    if values.ndim != 1 or not np.isfinite(values).all():
        raise ValueError(f"{key!r} is not a list of finite numbers")
    return values


def _rebuilt(
    models: dict[str, ModelData],
    output_names: Sequence[str],
    dim: int,
    settings: SurrogateSettings,
    source: str = "save",
) -> tuple[dict[str, Regressor], FeasibilityClassifier]:
    """Every model rebuilt from its data (each checked to reproduce its fitted
    predictions); SurrogateError naming ``source`` and the model otherwise."""
    expected = {*output_names, FEASIBLE}
    if set(models) != expected:
        raise SurrogateError(f"{source}: models {sorted(models)}, expected {sorted(expected)}")

    def named(name: str, build: Callable[[], Any]) -> Any:
        try:
            return build()
        except SurrogateError as err:
            raise SurrogateError(f"{source}: model {name!r}: {err}") from None

    regressors = {}
    for name in output_names:
        data = models[name]
        if data.constant is not None:
            raise SurrogateError(f"{source}: model {name!r} is not a regressor")
        columns = range(dim) if data.columns is None else data.columns
        if data.arrays["u"].shape[1] != len(columns) or not set(columns) <= set(range(dim)):
            raise SurrogateError(f"{source}: model {name!r}: inputs {list(columns)} of {dim}")
        regressors[name] = named(name, lambda data=data: rebuilt_regressor(data, settings))
    feasible = models[FEASIBLE]
    if feasible.constant is None and feasible.arrays["u"].shape[1] != dim:
        raise SurrogateError(f"{source}: model {FEASIBLE!r}: not fitted on the {dim} inputs")
    classifier = named(FEASIBLE, lambda: rebuilt_classifier(feasible, settings))
    return regressors, classifier


def _versions() -> dict[str, str]:
    return {
        "smt": smt.__version__,
        "scikit-learn": sklearn.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


# -- fitting -----------------------------------------------------------------------------


def _ids(indices: np.ndarray, sample_ids: np.ndarray, limit: int = 8) -> str:
    shown = ", ".join(str(int(sample_ids[i])) for i in indices[:limit])
    more = f", ... ({indices.size} in all)" if indices.size > limit else ""
    return f"[{shown}{more}]"


def _checked(
    X: np.ndarray,
    outputs: dict[str, np.ndarray],
    feasible: np.ndarray,
    input_names: tuple[str, ...],
    sample_ids: np.ndarray | None,
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    try:
        x = np.array(X, dtype=float)
    except (TypeError, ValueError) as err:
        raise SurrogateError(f"X: not a numeric array ({err})") from None
    if x.ndim != 2:
        raise SurrogateError(f"X: expected a 2-D array (n samples, d inputs), got shape {x.shape}")
    n, dim = x.shape
    if n == 0:
        raise SurrogateError("no samples: X has 0 rows; the surrogates need feasible samples")
    if dim == 0:
        raise SurrogateError("X has 0 columns; at least one input is needed")
    if len(input_names) != dim or len(set(input_names)) != dim:
        raise SurrogateError(
            f"input_names: {len(input_names)} names {tuple(input_names)} for X with {dim} "
            "columns; one distinct name per column is needed"
        )
    ids = np.arange(n) if sample_ids is None else np.asarray(sample_ids)
    if ids.shape != (n,) or not np.issubdtype(ids.dtype, np.integer):
        raise SurrogateError(
            f"sample_ids: expected {n} integers (shape ({n},)), got dtype {ids.dtype} and "
            f"shape {ids.shape}"
        )
    if np.unique(ids).size != n:
        raise SurrogateError("sample_ids: the ids must be distinct")
    ids = ids.astype(np.int64)
    flags = np.asarray(feasible)
    if flags.shape != (n,) or flags.dtype != bool:
        raise SurrogateError(
            f"feasible: expected a boolean array of shape ({n},) (one flag per row of X), "
            f"got dtype {flags.dtype} and shape {flags.shape}"
        )
    bad_rows = np.flatnonzero(~np.all(np.isfinite(x), axis=1))
    if bad_rows.size:
        raise SurrogateError(
            f"X: NaN or infinite inputs at sample_id {_ids(bad_rows, ids)}; every input must "
            "be finite"
        )
    values: dict[str, np.ndarray] = {}
    for name, column in outputs.items():
        if not isinstance(name, str) or not name or name == FEASIBLE:
            raise SurrogateError(
                f"outputs: invalid name {name!r} (a non-empty string other than {FEASIBLE!r})"
            )
        try:
            y = np.array(column, dtype=float)
        except (TypeError, ValueError) as err:
            raise SurrogateError(f"output {name!r}: not numeric ({err})") from None
        if y.shape != (n,):
            raise SurrogateError(
                f"output {name!r}: expected shape ({n},) (one value per row of X), got {y.shape}"
            )
        values[name] = y
    n_feasible = int(np.count_nonzero(flags))
    if n_feasible == 0:
        raise SurrogateError(
            f"all {n} samples are infeasible; the surrogates need feasible samples"
        )
    for name, y in values.items():
        bad = np.flatnonzero(flags & ~np.isfinite(y))
        if bad.size:
            raise SurrogateError(
                f"output {name!r}: NaN or infinite values at feasible samples (sample_id "
                f"{_ids(bad, ids)}); a feasible sample needs a finite value of every output"
            )
    return x, values, flags, ids


def _regressor_rows(output: str, scores: list[RegressorScore], chosen: str) -> list[dict]:
    return [
        {
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


def _classifier_rows(scores: list[ClassifierScore], chosen: str) -> list[dict]:
    return [
        {
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


def _prediction_rows(
    model: str,
    train_ids: np.ndarray,
    y_train: np.ndarray,
    cv_pred: np.ndarray,
    held_ids: np.ndarray,
    y_held: np.ndarray,
    held_pred: np.ndarray,
) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "model": model,
            "sample_id": np.concatenate([train_ids, held_ids]),
            "split": ["cv"] * train_ids.size + ["heldout"] * held_ids.size,
            "y_true": np.concatenate([y_train, y_held]).astype(float),
            "y_pred": np.concatenate([cv_pred, held_pred]).astype(float),
        }
    )


def _failures(scores: list[RegressorScore] | list[ClassifierScore]) -> str:
    return "; ".join(f"{s.name}: {s.error}" for s in scores)


_FIT_LOCK = threading.Lock()


def _one_blas_thread() -> Any:
    return blas_threads(1)


@contextmanager
def _serial_blas() -> Iterator[None]:
    """One BLAS thread while fitting, one fit at a time in the process.

    The Kriging likelihood works on n x n matrices with n ~ 30-80, where OpenBLAS's thread
    pool costs far more than it gains: on a busy 2-core machine a KRG fit on 30 samples
    took 0.2-4 s with 2 BLAS threads and a steady 0.12 s with one. The lock keeps two
    threads of one process (a threaded task runner) from restoring each other's limits
    out of order.
    """
    with _FIT_LOCK, _one_blas_thread():
        yield


def fit_surrogates(
    X: np.ndarray,
    outputs: dict[str, np.ndarray],
    feasible: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    settings: SurrogateSettings,
    *,
    input_names: tuple[str, ...],
    sample_ids: np.ndarray | None = None,
    candidates: Mapping[str, str | Sequence[str]] | None = None,
    executor: Executor | None = None,
    output_inputs: Mapping[str, Sequence[str]] | None = None,
    left_out: Mapping[str, np.ndarray] | None = None,
    classified: np.ndarray | None = None,
) -> SurrogateSet:
    """Fit, cross-validate and select the surrogates of ``outputs`` and of feasibility.

    ``X`` (n, d) physical inputs inside [lower, upper]; ``outputs`` name -> (n,) values (NaN
    allowed at infeasible samples only); ``feasible`` (n,) bool; ``sample_ids`` (n,) distinct
    ints for the predictions table (default 0..n-1).

    1. Inputs are scaled to the unit cube of [lower, upper].
    2. A stratified, seeded share ``holdout_fraction`` of all samples is held out
       (:func:`~ovtraj.surrogate.validation.holdout_mask`).
    3. Per output, every candidate of ``settings.regressors`` is cross-validated with the
       same k folds of the feasible training samples (ascending sample order, ``KFold(k,
       shuffle=True, random_state=seed)``); the lowest ``cv_rmse`` is selected (ties: config
       order). Every candidate is then fitted on all feasible training samples and scored
       on the held-out feasible samples, for the report only.
    4. Feasibility: every candidate of ``settings.classifiers`` is cross-validated on all
       training samples (stratified folds); highest balanced accuracy wins (ties: lower log
       loss, then config order). If every training sample is feasible, a constant
       probability 1 ("all-feasible") replaces the classifiers.

    ``candidates`` (output name -> candidate, ``"feasible"`` -> classifier; e.g. an earlier
    fit's ``selected``) restricts the models named there to that one candidate: it is still
    cross-validated and checked on the hold-out, but not compared with the others. A
    regressor may be given a list (a shortlist, :func:`shortlist`): those candidates are
    compared. If none can be fitted on these data (or the earlier set was all feasible and
    this one is not), every configured candidate is tried as without the restriction.

    With ``settings.holdout_refit`` the selected models are then fitted again on every
    sample, the held-out ones included: the held-out figures describe the model fitted
    without them, the model returned has seen them too.

    ``executor`` (a ``concurrent.futures`` process pool or Dask executor) scores the
    regressor candidates (every output's) on its processes: the same models and figures as
    in this process, since every candidate is seeded and fitted with one BLAS thread.

    ``output_inputs`` (output name -> names of ``input_names``) fits those outputs on those
    inputs alone, e.g. a quantity that physically depends on fewer inputs than the set
    takes; the others on all. Such an output is trained on the first of the training
    samples that repeat its inputs (repeated inputs make a Kriging correlation matrix
    singular), with its own k folds of them; it still predicts from all the set's inputs.

    ``left_out`` (output name -> (n,) bool) leaves those samples out of that output's
    regressor (its training, folds and hold-out rows), e.g. samples in a regime the
    output's model is not meant to describe; they still count for the other outputs and
    for the feasibility model. Each output keeps at least ``min_training_samples``.

    ``classified`` ((n,) bool) trains and scores the feasibility classifier on those
    samples alone (its hold-out rows among them), e.g. without samples whose
    infeasibility another model accounts for; the regressors are not affected.

    A candidate that fails gets its reason in the ``error`` column and is not selected.
    Raises :class:`SurrogateError` for unusable data (no samples, none feasible, too few
    feasible training samples, shapes, NaN) or when no candidate of a model can be fitted.
    """
    x, values, flags, ids = _checked(X, outputs, feasible, tuple(input_names), sample_ids)
    columns = _output_columns(output_inputs or {}, tuple(input_names), values)
    omitted = _left_out(left_out or {}, values, x.shape[0])
    n, dim = x.shape
    cube = UnitCube(lower, upper)
    if cube.dim != dim:
        raise SurrogateError(
            f"bounds: {cube.dim} lower/upper values for X with {dim} columns; one per input"
        )
    data_hash = training_data_hash(x, values, flags)
    u = cube.to_unit(x)

    held = holdout_mask(flags, settings.holdout_fraction, settings.seed)
    n_train = int(np.count_nonzero(~held & flags))
    if n_train < settings.min_training_samples:
        raise SurrogateError(
            f"{n_train} feasible training samples ({int(flags.sum())} feasible of {n}, "
            f"{int(held.sum())} held out); at least {settings.min_training_samples} are "
            "needed (surrogate.min_training_samples): evaluate more samples, e.g. a larger DoE"
        )
    for name, mask in omitted.items():
        kept = int(np.count_nonzero(~held & flags & ~mask))
        if kept < settings.min_training_samples:
            raise SurrogateError(
                f"output {name!r}: {kept} feasible training samples once "
                f"{int(np.count_nonzero(flags & mask))} are left out; at least "
                f"{settings.min_training_samples} are needed (surrogate.min_training_samples)"
            )

    with _serial_blas():
        fitted: list[tuple[FeasibilityClassifier, list[dict], pd.DataFrame]] = []
        rows_of = np.ones(n, dtype=bool) if classified is None else np.asarray(classified, bool)
        if rows_of.shape != (n,) or not rows_of.any():
            raise SurrogateError(f"classified: expected a boolean array of shape ({n},), not empty")

        def classify() -> None:
            fitted.append(
                _fit_classifier(
                    u[rows_of],
                    flags[rows_of],
                    ids[rows_of],
                    held[rows_of],
                    settings,
                    (candidates or {}).get(FEASIBLE),
                )
            )

        # The classifier is fitted here while the pool fits the regressors.
        regressors, selected, rows, tables = _fit_regressors(
            u,
            values,
            flags,
            ids,
            held,
            settings,
            dict(candidates or {}),
            executor,
            classify,
            columns,
            omitted,
        )
        classifier, rows_cls, table_cls = fitted[0]
    selected[FEASIBLE] = classifier.name
    rows += rows_cls
    tables.append(table_cls)
    validation = _validation_frame(_validation_table(rows))
    predictions = _predictions_table(pd.concat(tables, ignore_index=True)).to_pandas()
    return SurrogateSet(
        input_names=tuple(input_names),
        output_names=tuple(values),
        cube=cube,
        regressors=regressors,
        classifier=classifier,
        selected=selected,
        validation=validation,
        predictions=predictions,
        data_hash=data_hash,
        settings=settings,
    )


def _output_columns(
    output_inputs: Mapping[str, Sequence[str]],
    input_names: tuple[str, ...],
    outputs: dict[str, np.ndarray],
) -> dict[str, tuple[int, ...]]:
    """Output name -> the column indices (in input order) of its own inputs."""
    columns: dict[str, tuple[int, ...]] = {}
    for output, names in output_inputs.items():
        if output not in outputs:
            raise SurrogateError(
                f"output_inputs: {output!r} is not an output (outputs: {tuple(outputs)})"
            )
        listed = [names] if isinstance(names, str) else list(names)
        unknown = [name for name in listed if name not in input_names]
        if not listed or unknown:
            raise SurrogateError(
                f"output_inputs[{output!r}]: {listed} must be one or more of the inputs "
                f"{input_names}"
            )
        columns[output] = tuple(k for k, name in enumerate(input_names) if name in listed)
    return columns


def _left_out(
    left_out: Mapping[str, np.ndarray], values: dict[str, np.ndarray], n: int
) -> dict[str, np.ndarray]:
    """``fit_surrogates``' ``left_out``, checked: known outputs, one flag per sample."""
    checked = {}
    for name, mask in left_out.items():
        if name not in values:
            raise SurrogateError(f"left_out: {name!r} is not an output (outputs: {tuple(values)})")
        flags = np.asarray(mask)
        if flags.shape != (n,) or flags.dtype != bool:
            raise SurrogateError(
                f"left_out[{name!r}]: expected a boolean array of shape ({n},), got dtype "
                f"{flags.dtype} and shape {flags.shape}"
            )
        checked[name] = flags
    return checked


def _first_of_repeats(rows: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """``rows`` (ascending) without those whose ``inputs`` repeat an earlier row's."""
    if rows.size == 0:
        return rows
    _, first = np.unique(inputs[rows], axis=0, return_index=True)
    return rows[np.sort(first)]


def _fit_regressors(
    u: np.ndarray,
    values: dict[str, np.ndarray],
    flags: np.ndarray,
    ids: np.ndarray,
    held: np.ndarray,
    settings: SurrogateSettings,
    candidates: dict[str, str | list[str]],
    executor: Executor | None = None,
    meanwhile: Callable[[], None] | None = None,
    columns: dict[str, tuple[int, ...]] | None = None,
    omitted: dict[str, np.ndarray] | None = None,
) -> tuple[dict[str, Regressor], dict[str, str], list[dict], list[pd.DataFrame]]:
    """CV, selection and final fit of every output's regressor (feasible samples only).

    ``meanwhile``: called once, in this process, while ``executor`` fits the candidates
    (with no executor, after them); ``columns``: the outputs fitted on some inputs only
    (:func:`fit_surrogates`' ``output_inputs``); ``omitted``: the samples each output
    leaves out (its ``left_out``)."""
    pending = [meanwhile] if meanwhile is not None else []

    def in_the_meantime() -> None:
        while pending:
            pending.pop()()

    columns = columns or {}
    omitted = omitted or {}
    none = np.zeros(flags.shape, dtype=bool)
    # Each output's feasible rows: training (ascending sample order) and hold-out.
    usable = {name: flags & ~omitted.get(name, none) for name in values}
    reg_trains = {name: np.flatnonzero(~held & rows) for name, rows in usable.items()}
    reg_helds = {name: np.flatnonzero(held & rows) for name, rows in usable.items()}
    rows: list[dict] = []
    tables: list[pd.DataFrame] = []
    selected: dict[str, str] = {}
    regressors: dict[str, Regressor] = {}
    # Each output's inputs, training rows and folds: all of them, unless it has inputs of
    # its own (then the first of the rows that repeat those inputs).
    inputs = {name: u[:, list(columns[name])] if name in columns else u for name in values}
    trains = {
        name: _first_of_repeats(reg_trains[name], inputs[name])
        if name in columns
        else reg_trains[name]
        for name in values
    }
    all_folds = {name: _regression_folds(trains[name].size, settings) for name in values}
    configured_for = {name: _configured(trains[name].size, settings) for name in values}

    def scored(names: dict[str, list[str]]) -> dict[str, list[RegressorScore]]:
        jobs = [(name, candidate) for name, listed in names.items() for candidate in listed]
        # Every fold of every candidate is a job of its own: ~6 similar Kriging fits per
        # candidate keep a pool's processes evenly busy where whole candidates did not.
        pieces = [
            regressor_fit_arguments(
                candidate,
                inputs[name][trains[name]],
                values[name][trains[name]],
                inputs[name][reg_helds[name]],
                all_folds[name],
                settings,
            )
            for name, candidate in jobs
        ]
        if settings.cv_warm_start:
            fitted = _warm_started_fits(pieces, executor, in_the_meantime)
        else:
            collect = started(_regressor_fit, [a for p in pieces for a in p], executor)
            if executor is not None:
                in_the_meantime()
            fitted = collect()
        fits = iter(fitted)
        out: dict[str, list[RegressorScore]] = {name: [] for name in names}
        for (name, candidate), arguments in zip(jobs, pieces, strict=True):
            mine = [next(fits) for _ in arguments]
            y, train = values[name], trains[name]
            out[name].append(
                regressor_score(candidate, y[train], y[reg_helds[name]], all_folds[name], mine)
            )
        return out

    first = {name: _shortlisted(candidates.get(name), configured_for[name]) for name in values}
    all_scores = scored(first)
    # A kept candidate that cannot be fitted on these data: every candidate is compared.
    retry = {
        name: configured_for[name]
        for name, listed in first.items()
        if listed != configured_for[name] and select_regressor(all_scores[name]) is None
    }
    all_scores |= scored(retry) if retry else {}
    in_the_meantime()
    for name, y in values.items():
        scores = all_scores[name]
        best = select_regressor(scores)
        if best is None:
            raise SurrogateError(
                f"output {name!r}: no candidate could be fitted ({_failures(scores)})"
            )
        selected[name] = best.name
        regressors[name] = best.model
        x, train = inputs[name], trains[name]
        if settings.holdout_refit and reg_helds[name].size:
            # Scored without the hold-out; the model used has seen it too.
            every = np.flatnonzero(usable[name])
            every = _first_of_repeats(every, x) if name in columns else every
            regressors[name] = _refitted(
                best.model,
                lambda n=best.name, y=y, x=x, every=every: fit_regressor(
                    n, x[every], y[every], settings
                ),
            )
        if name in columns:
            regressors[name] = dataclasses.replace(regressors[name], columns=columns[name])
        folds = all_folds[name]
        rows += [dict(r, n_folds=len(folds)) for r in _regressor_rows(name, scores, best.name)]
        tables.append(
            _prediction_rows(
                name,
                ids[train][best.cv_rows],
                y[train][best.cv_rows],
                best.cv_pred,
                ids[reg_helds[name]],
                y[reg_helds[name]],
                best.heldout_pred,
            )
        )
    return regressors, selected, rows, tables


def _regression_folds(n: int, settings: SurrogateSettings) -> Folds:
    """The k folds of an output's ``n`` training samples: of all of them, or of a seeded
    subsample of ``large_samples.cv_max_samples`` (the cross-validation's cost bounded;
    the models kept are still fitted on all ``n``)."""
    large = settings.large_samples
    if large is None or n <= large.cv_max_samples:
        return regression_folds(n, settings.folds, settings.seed)
    rows = seeded_subsample(n, large.cv_max_samples, settings.seed)
    return subsampled_folds(
        lambda subsample: regression_folds(subsample.size, settings.folds, settings.seed), rows
    )


def _configured(n: int, settings: SurrogateSettings) -> list[str]:
    """The regressor candidates of an output with ``n`` training samples: the configured
    ones, and ``large_samples.extra_regressors`` past ``exact_max_samples``."""
    listed = list(settings.regressors)
    large = settings.large_samples
    if large is not None and n > large.exact_max_samples:
        listed += large.extra_regressors
    return list(dict.fromkeys(listed))


def _warm_started_fits(
    pieces: list[list[tuple]], executor: Executor | None, meanwhile: Callable[[], None]
) -> list[Any]:
    """The fits of every candidate's :func:`regressor_fit_arguments` (folds, then the
    whole training part), in that order: the whole parts first, then each Kriging fold
    started from its whole part's hyperparameters alone (``surrogate.cv_warm_start``).

    The models kept are the whole parts', fitted as without the option; only the folds'
    fits, hence the cross-validation figures, can differ.
    """
    collect = started(_regressor_fit, [p[-1] for p in pieces], executor)
    if executor is not None:
        meanwhile()
    wholes = collect()
    folds = [
        (*arguments, _theta(whole))
        for p, whole in zip(pieces, wholes, strict=True)
        for arguments in p[:-1]
    ]
    fold_fits = iter(mapped(_regressor_fit, folds, executor))
    ordered: list[Any] = []
    for p, whole in zip(pieces, wholes, strict=True):
        ordered += [next(fold_fits) for _ in p[:-1]] + [whole]
    return ordered


def _theta(whole: RegressorFit) -> np.ndarray | None:
    """A whole part's Kriging hyperparameters (``None``: no Kriging model or it failed)."""
    regressor = whole.model
    if regressor is None or regressor.name not in KRIGING:
        return None
    return np.asarray(regressor.model.optimal_theta, dtype=float)


def _regressor_fit(*arguments: Any) -> RegressorFit:
    """:func:`regressor_fit` with one BLAS thread, wherever it runs."""
    with _one_blas_thread():
        return regressor_fit(*arguments)


def _refitted(scored: Any, refit: Any) -> Any:
    """The model refitted with the hold-out, or the scored one if that fit fails."""
    try:
        return refit()
    except CandidateError:
        return scored


def shortlist(validation: pd.DataFrame, size: int) -> dict[str, str | list[str]]:
    """From a fit's validation table: each regressed output's ``size`` candidates of lowest
    CV RMSE (the selection's own criterion, :func:`select_regressor`), and the selected
    classifier: the ``candidates`` of a later fit that compares only these."""
    kept: dict[str, str | list[str]] = {}
    regressors = validation[(validation["kind"] == "regressor") & validation["cv_rmse"].notna()]
    for model, rows in regressors.groupby("model", sort=True):
        ranked = rows.sort_values("cv_rmse", kind="stable")["candidate"].tolist()
        kept[str(model)] = ranked[:size]
    chosen = validation["selected"].astype(bool)
    classifiers = validation[(validation["kind"] == "classifier") & chosen]
    for row in classifiers.itertuples(index=False):
        kept[str(row.model)] = str(row.candidate)  # the last set's (the main model's)
    return kept


def _shortlisted(kept: str | Sequence[str] | None, configured: list[str]) -> list[str]:
    """The configured candidates among ``kept`` (one name or several), in config order; all
    of them when none is kept."""
    listed = [kept] if isinstance(kept, str) else list(kept or ())
    return [c for c in configured if c in listed] or configured


def _fit_classifier(
    u: np.ndarray,
    flags: np.ndarray,
    ids: np.ndarray,
    held: np.ndarray,
    settings: SurrogateSettings,
    kept: str | None = None,
) -> tuple[FeasibilityClassifier, list[dict], pd.DataFrame]:
    """CV, selection and final fit of the feasibility classifier (all training samples)."""
    cls_train = np.flatnonzero(~held)
    cls_held = np.flatnonzero(held)
    y_cls = flags[cls_train]
    cls_folds = _classification_folds(y_cls, settings)
    configured = list(dict.fromkeys(settings.classifiers))

    def scored(names: list[str]) -> list[ClassifierScore]:
        return [
            evaluate_classifier(
                candidate, u[cls_train], y_cls, u[cls_held], flags[cls_held], cls_folds, settings
            )
            for candidate in names
        ]

    if y_cls.all():
        cls_scores = scored([ALL_FEASIBLE])
    else:
        cls_scores = scored([kept]) if kept in configured else []
        if select_classifier(cls_scores) is None:
            cls_scores = scored(configured)
    best = select_classifier(cls_scores)
    if best is None:
        raise SurrogateError(
            f"feasibility: no classifier could be fitted ({_failures(cls_scores)})"
        )
    model = best.model
    if settings.holdout_refit and cls_held.size and best.name != ALL_FEASIBLE:
        model = _refitted(model, lambda: fit_classifier(best.name, u, flags, settings))
    rows = [dict(r, n_folds=len(cls_folds)) for r in _classifier_rows(cls_scores, best.name)]
    table = _prediction_rows(
        FEASIBLE,
        ids[cls_train][best.cv_rows],
        y_cls[best.cv_rows].astype(float),
        best.cv_pred,
        ids[cls_held],
        flags[cls_held].astype(float),
        best.heldout_pred,
    )
    return model, rows, table


def _classification_folds(y: np.ndarray, settings: SurrogateSettings) -> Folds:
    """The stratified folds of the classifier's training samples ``y``: of all of them, or
    of a seeded subsample of ``large_samples.cv_max_samples`` keeping each class's share."""
    large = settings.large_samples
    if large is None or y.size <= large.cv_max_samples:
        return classification_folds(y, settings.folds, settings.seed)
    rows = seeded_subsample(y.size, large.cv_max_samples, settings.seed, classes=y)
    return subsampled_folds(
        lambda subsample: classification_folds(y[subsample], settings.folds, settings.seed), rows
    )
