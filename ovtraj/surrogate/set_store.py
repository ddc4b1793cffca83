"""A surrogate set in a store: written as data, read back checked.

Layout of :func:`write_set` (one directory)::

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

The two tables have declared schemas (:mod:`ovtraj.surrogate.tables`). ``meta.json`` is
the product's marker (:mod:`ovtraj.store.products`), written last; :func:`read_set`
checks every file against it (size, SHA-256, schema) before parsing, and names a missing
or changed file. Nothing stored is an executable format (a pickle runs code when it is
read, and stores are shared): the models are data, rebuilt with the same library calls
and checked to reproduce their fitted predictions to the bit.
"""

from __future__ import annotations

import platform
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
import pyarrow as pa
import sklearn
import smt
from pydantic import ValidationError

from ovtraj.config.mission import SurrogateSettings
from ovtraj.store.backends import location
from ovtraj.store.files import Digest, StoreError, read_json
from ovtraj.store.products import Product
from ovtraj.store.records import json_text, table_from_frame
from ovtraj.store.seals import authenticated
from ovtraj.surrogate.fit_threads import serial_blas
from ovtraj.surrogate.fitted_models import FeasibilityClassifier, Regressor
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
from ovtraj.surrogate.tables import (
    FEASIBLE,
    PREDICTIONS_SCHEMA,
    STORED_VALIDATION_SCHEMA,
    VALIDATION_SCHEMA,
    predictions_table,
    validation_frame,
)

if TYPE_CHECKING:
    from ovtraj.surrogate.surrogate_set import SurrogateSet

__all__ = ["read_set", "write_set"]

# 2: file digests (size, SHA-256) in meta.json, declared table schemas; 3: the models as
# data (models.parquet and meta.json's "models"), no pickle
STORE_FORMAT = 3
MODELS_FILE = "models.parquet"
VALIDATION_FILE = "validation.parquet"
PREDICTIONS_FILE = "predictions.parquet"
META_FILE = "meta.json"


def write_set(
    fitted: SurrogateSet,
    directory: Path,
    meta: dict[str, Any],
    views: dict[str, Digest] | None = None,
) -> dict[str, Digest]:
    """Write ``fitted`` to ``directory`` (layout in the module notes), ``meta.json`` last;
    the digest of every file written (``SurrogateSet.save`` describes the arguments)."""
    directory = location(directory)
    own = _own_marker(fitted)
    document = _marker_document(meta, own)
    # A set that could not be rebuilt from its data is never written. Fits, their
    # predictions at the training inputs and rebuilds all run with one BLAS thread, as
    # the fits did: a LAPACK factorisation's last bits depend on the thread count.
    with serial_blas():
        models = _model_data(fitted)
        _rebuilt(models, fitted.output_names, fitted.cube.dim, fitted.settings)
    own["models"] = document["models"] = {k: m.description() for k, m in models.items()}
    validation = table_from_frame(
        fitted.validation.drop(columns="fit_time_s"), STORED_VALIDATION_SCHEMA, "validation"
    )
    document["timing"] = {
        "fit_time_s": [
            [row.model, row.candidate, None if pd.isna(row.fit_time_s) else row.fit_time_s]
            for row in fitted.validation.itertuples(index=False)
        ]
    }
    predictions = predictions_table(fitted.predictions)
    with Product(directory, META_FILE).writing() as out:
        out.write_table(MODELS_FILE, arrays_table(models), MODEL_ARRAYS_SCHEMA)
        out.write_table(VALIDATION_FILE, validation, STORED_VALIDATION_SCHEMA)
        out.write_table(PREDICTIONS_FILE, predictions, PREDICTIONS_SCHEMA)
        for name, digest in (views or {}).items():
            out.add(name, digest)
        out.finish(document)
    return dict(out.files)


def _own_marker(fitted: SurrogateSet) -> dict[str, Any]:
    """The set's own keys of ``meta.json`` (``models`` filled once they are rebuilt)."""
    return {
        "format": STORE_FORMAT,
        "data_hash": fitted.data_hash,
        "selected": fitted.selected,
        "settings": fitted.settings.model_dump(mode="json"),
        "input_names": list(fitted.input_names),
        "output_names": list(fitted.output_names),
        "output_inputs": {k: list(v) for k, v in fitted.output_inputs.items()},
        "lower": np.asarray(fitted.cube.lower).tolist(),
        "upper": np.asarray(fitted.cube.upper).tolist(),
        "versions": _versions(),
        "models": {},
    }


def _marker_document(meta: dict[str, Any], own: dict[str, Any]) -> dict[str, Any]:
    """The caller's ``meta`` merged with the set's own keys; SurrogateError if it uses one
    of them or is not JSON-serialisable."""
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
    return document


def _model_data(fitted: SurrogateSet) -> dict[str, ModelData]:
    """Every model as data, outputs in order, then the feasibility classifier."""
    models = {name: regressor_data(fitted.regressor(name)) for name in fitted.output_names}
    return models | {FEASIBLE: classifier_data(fitted.classifier)}


def read_set(directory: Path, expected: Digest | None = None) -> dict[str, Any]:
    """The arguments of ``SurrogateSet`` stored by :func:`write_set` in ``directory``,
    every file checked against ``meta.json`` (``expected``: its digest when a parent
    product lists it); SurrogateError naming a missing or changed file."""
    directory = location(directory)
    product = Product(directory, META_FILE)
    meta = _marker(product, expected)
    meta_path = str(product.marker_path)
    try:
        if not isinstance(meta["files"], dict):
            raise TypeError("'files' is not a mapping")
        settings = SurrogateSettings.model_validate(meta["settings"])
    except (KeyError, TypeError, ValueError, ValidationError) as err:
        raise SurrogateError(f"{meta_path}: corrupt or outdated content ({err})") from None
    arrays, validation, predictions = _tables(product, meta)
    names = _layout(meta, meta_path)
    models = model_data(meta.get("models"), arrays, str(directory / MODELS_FILE))
    with serial_blas():  # as the fit (see write_set)
        regressors, classifier = _rebuilt(
            models, names["output_names"], names["cube"].dim, settings, meta_path
        )
    _warn_of_other_versions(meta, meta_path)
    return names | {
        "regressors": regressors,
        "classifier": classifier,
        "validation": validation,
        "predictions": predictions,
        "data_hash": str(meta["data_hash"]),
        "settings": settings,
        "meta": meta,
    }


def _marker(product: Product, expected: Digest | None) -> dict[str, Any]:
    """``meta.json``, authenticated and of this store format."""
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
    return meta


def _tables(product: Product, meta: dict[str, Any]) -> tuple[pa.Table, pd.DataFrame, pd.DataFrame]:
    """The models' arrays, the validation table (with the marker's fit times) and the
    predictions, each checked against the marker."""
    try:
        arrays = product.read_table(MODELS_FILE, MODEL_ARRAYS_SCHEMA, meta)
        stored = product.read_table(VALIDATION_FILE, STORED_VALIDATION_SCHEMA, meta)
        validation = validation_frame(_with_fit_times(stored, meta))
        predictions = product.read_frame(PREDICTIONS_FILE, PREDICTIONS_SCHEMA, meta)
    except StoreError as err:
        raise SurrogateError(str(err)) from None
    return arrays, validation, predictions


def _with_fit_times(stored: pa.Table, meta: dict[str, Any]) -> pa.Table:
    """The stored validation table with ``fit_time_s`` from the marker's timing record."""
    times = {(m, c): t for m, c, t in meta.get("timing", {}).get("fit_time_s", [])}
    models, candidates = stored.column("model").to_pylist(), stored.column("candidate").to_pylist()
    keys = zip(models, candidates, strict=True)
    column = pa.array([times.get(key) for key in keys], type=pa.float64())
    index = VALIDATION_SCHEMA.get_field_index("fit_time_s")
    return stored.add_column(index, VALIDATION_SCHEMA.field("fit_time_s"), column)


def _layout(meta: dict[str, Any], meta_path: str) -> dict[str, Any]:
    """The set's input and output names, unit cube and selection from the marker."""
    try:
        input_names = tuple(_names(meta, "input_names"))
        output_names = tuple(_names(meta, "output_names"))
        cube = UnitCube(_bounds(meta, "lower"), _bounds(meta, "upper"))
        selected = {str(k): str(v) for k, v in dict(meta["selected"]).items()}
        if len(input_names) != cube.dim:
            raise ValueError(f"{len(input_names)} input names for {cube.dim} bounds")
    except (KeyError, TypeError, ValueError, SurrogateError) as err:
        raise SurrogateError(f"{meta_path}: corrupt or outdated content ({err})") from None
    return {
        "input_names": input_names,
        "output_names": output_names,
        "cube": cube,
        "selected": selected,
    }


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


def _warn_of_other_versions(meta: dict[str, Any], meta_path: str) -> None:
    """A warning when the set was fitted with another smt or scikit-learn version."""
    stored = meta.get("versions", {})
    current = _versions()
    changed = {k: (stored.get(k), v) for k, v in current.items() if stored.get(k) != v}
    if changed.keys() & {"smt", "scikit-learn"}:
        warnings.warn(
            f"{meta_path}: fitted with other library versions {changed}; refit if in doubt",
            stacklevel=4,  # the caller of SurrogateSet.load
        )
