"""The fitted surrogate models as data, and rebuilt from it.

A surrogate set is stored without any executable format (a pickle runs code when it is
read, and run stores are shared between analysts, workers and CI): each fitted model is
kept as what rebuilds it,

* its **description**: the candidate, the inputs it was fitted on (``columns``) and its
  fitted hyperparameters as JSON numbers (``hyper``), in the set's ``meta.json``;
* its **arrays**: float64 arrays in one Parquet table of declared schema
  (:data:`MODEL_ARRAYS_SCHEMA`, a row per array: its model, name, shape and values),

and rebuilt on load with the same library calls the fit made (each candidate's fitted
state and hyperparameters are declared in its registry entry,
:mod:`ovtraj.surrogate.candidates`):

=================  ======================================================================
candidate          arrays (besides the training inputs ``u``, values ``y``, ``check``)
=================  ======================================================================
KRG, KPLS          the fitted state SMT's ``predict_values`` reads: ``X_offset``,
                   ``X_scale``, ``y_mean``, ``y_std``, ``optimal_theta``, the GLS
                   solution ``beta`` and ``gamma`` (SMT's ``optimal_par``), KPLS's
                   ``coeff_pls``; the hyperparameters are not maximised again
RBF, QP, ET, GBT   none: fitted again on ``u``, ``y`` (linear solves; the trees are
                   seeded, ``n_jobs=1``: the same trees)
svc, logistic      none: fitted again (seeded calibration folds, deterministic solvers)
gpc                none; ``hyper`` holds the fitted kernel (``constant_value``,
                   ``length_scale``), used as is (``optimizer=None``): the same Laplace
                   approximation as the fit's last step
=================  ======================================================================

``check`` is the model's predictions (probabilities for a classifier) at its training
inputs when it was fitted: a rebuilt model must reproduce them **to the bit**, on save (a
set that could not be rebuilt is never written) and on load (another library version or
a changed file is refused with a line naming the model), so a loaded set predicts what
the fitted one did.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyarrow as pa

from ovtraj.config.mission import SurrogateSettings
from ovtraj.store.records import FLOAT, INT, TEXT, record_schema
from ovtraj.surrogate.candidates import (
    ALL_FEASIBLE,
    CLASSIFIERS,
    KRIGING_PAR,
    REGRESSORS,
    Candidate,
    CandidateError,
    regressor,
)
from ovtraj.surrogate.fitted_models import (
    FeasibilityClassifier,
    Regressor,
    fit_classifier,
    fit_regressor,
)
from ovtraj.surrogate.scaling import SurrogateError

__all__ = [
    "MODEL_ARRAYS_SCHEMA",
    "ModelData",
    "arrays_table",
    "classifier_data",
    "model_data",
    "rebuilt_classifier",
    "rebuilt_regressor",
    "regressor_data",
]

MODEL_ARRAYS_SCHEMA = record_schema(
    [
        ("model", TEXT),
        ("array", TEXT),
        ("shape", pa.list_(INT)),
        ("values", pa.list_(FLOAT)),
    ],
    required=("model", "array", "shape", "values"),
)
"""``models.parquet``: one row per (model, array); ``values`` in C order of ``shape``."""

# Every model's arrays: its training data, its predictions there, then its candidate's
# fitted state (the registry's ``state``: Kriging's).
_COMMON = ("u", "y", "check")
_CANDIDATES: dict[str, Candidate] = REGRESSORS | CLASSIFIERS
_ARRAYS = {name: (*_COMMON, *c.state) for name, c in _CANDIDATES.items()}
_MAX_DIMENSIONS = 2


@dataclass(frozen=True)
class ModelData:
    """One fitted model as data: ``candidate``, ``columns`` (the set's inputs it was
    fitted on; ``None``: all), ``hyper`` (fitted hyperparameters, JSON numbers),
    ``constant`` (a single-class classifier's probability) and ``arrays`` (float64)."""

    candidate: str
    columns: tuple[int, ...] | None = None
    hyper: dict[str, float | list[float]] = field(default_factory=dict)
    constant: float | None = None
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def description(self) -> dict[str, Any]:
        """The JSON part (everything but the arrays), for ``meta.json``."""
        return {
            "candidate": self.candidate,
            "columns": None if self.columns is None else list(self.columns),
            "hyper": dict(self.hyper),
            "constant": self.constant,
        }


def regressor_data(fitted: Regressor) -> ModelData:
    """What rebuilds a fitted regressor (the module's table)."""
    u, y = fitted.training()
    model = fitted.model
    arrays = {"u": u, "y": y, "check": fitted.predict_fitted(u)}
    for name in regressor(fitted.name).state:
        arrays[name] = model.optimal_par[name] if name in KRIGING_PAR else getattr(model, name)
    return ModelData(
        fitted.name,
        fitted.columns,
        arrays={k: np.array(v, dtype=float) for k, v in arrays.items()},
    )


def classifier_data(classifier: FeasibilityClassifier) -> ModelData:
    """What rebuilds a fitted feasibility classifier (the module's table)."""
    if classifier.estimator is None:
        return ModelData(classifier.name, constant=float(classifier.constant))
    u, flags = classifier.training
    hyper = classifier.hyper()
    arrays = {"u": u, "y": np.asarray(flags, dtype=float), "check": classifier.proba(u)}
    return ModelData(
        classifier.name, hyper=hyper, arrays={k: np.array(v, float) for k, v in arrays.items()}
    )


def rebuilt_regressor(data: ModelData, settings: SurrogateSettings) -> Regressor:
    """The regressor ``data`` describes, rebuilt; SurrogateError if it does not
    reproduce its fitted predictions to the bit."""
    u, y = data.arrays["u"], data.arrays["y"]
    try:
        candidate = regressor(data.candidate)
        if candidate.kriging:
            model = _kriging_with_state(candidate, data, settings)
        else:
            model = fit_regressor(data.candidate, u, y, settings).model
        rebuilt = Regressor(data.candidate, model, data.columns)
        predicted = rebuilt.predict_fitted(u)
    except (CandidateError, AttributeError, ValueError, np.linalg.LinAlgError) as err:
        raise SurrogateError(f"{data.candidate}: cannot be rebuilt ({err})") from None
    _same(predicted, data.arrays["check"], data.candidate)
    return rebuilt


def _kriging_with_state(candidate: Candidate, data: ModelData, settings: SurrogateSettings) -> Any:
    """A fresh SMT Kriging model given its training data and fitted state (the likelihood
    is not maximised again)."""
    u, y = data.arrays["u"], data.arrays["y"]
    model = candidate.build(u.shape[1], settings, None)
    model.set_training_values(np.ascontiguousarray(u), y)
    for name in candidate.state:
        if name not in KRIGING_PAR:
            setattr(model, name, data.arrays[name])
    model.optimal_par = {name: data.arrays[name] for name in KRIGING_PAR}
    # As SMT's training leaves them: the standardised inputs, the sample count and the
    # kernel's hyperparameters (its ``theta``; the correlation reads it).
    model.X_norma = (u - model.X_offset) / model.X_scale
    model.nt = u.shape[0]
    model.corr.theta = model.optimal_theta
    return model


def rebuilt_classifier(data: ModelData, settings: SurrogateSettings) -> FeasibilityClassifier:
    """The classifier ``data`` describes, rebuilt; SurrogateError if it does not
    reproduce its fitted probabilities to the bit."""
    if data.constant is not None:
        return FeasibilityClassifier(data.candidate, None, data.constant)
    u, flags = data.arrays["u"], data.arrays["y"].astype(bool)
    try:
        classifier = fit_classifier(data.candidate, u, flags, settings, data.hyper or None)
    except CandidateError as err:
        raise SurrogateError(f"{data.candidate}: cannot be rebuilt ({err})") from None
    _same(classifier.proba(u), data.arrays["check"], data.candidate)
    return classifier


def _same(predicted: np.ndarray, check: np.ndarray, candidate: str) -> None:
    if predicted.shape != check.shape or not np.array_equal(predicted, check):
        raise SurrogateError(
            f"{candidate}: the rebuilt model does not reproduce its fitted predictions "
            "(another smt or scikit-learn version, or changed data): fit the surrogates again"
        )


# -- the stored form ------------------------------------------------------------------------


def arrays_table(models: Mapping[str, ModelData]) -> pa.Table:
    """Every model's arrays as rows of :data:`MODEL_ARRAYS_SCHEMA` (models in the given
    order, arrays in the order of the module's table)."""
    rows: dict[str, list[Any]] = {name: [] for name in MODEL_ARRAYS_SCHEMA.names}
    for model, data in models.items():
        for name in _ARRAYS[data.candidate] if data.constant is None else ():
            values = np.ascontiguousarray(data.arrays[name], dtype=float)
            rows["model"].append(model)
            rows["array"].append(name)
            rows["shape"].append(list(values.shape))
            rows["values"].append(values.reshape(-1))
    return pa.table(
        {
            "model": pa.array(rows["model"], TEXT),
            "array": pa.array(rows["array"], TEXT),
            "shape": pa.array(rows["shape"], pa.list_(INT)),
            "values": pa.array(rows["values"], pa.list_(FLOAT)),
        },
        schema=MODEL_ARRAYS_SCHEMA,
    )


def model_data(
    descriptions: Mapping[str, Any], table: pa.Table, source: str
) -> dict[str, ModelData]:
    """The models of a stored set from their descriptions (``meta.json``'s ``models``)
    and arrays (:func:`arrays_table`, read by the store's bounded, checked reads);
    SurrogateError naming ``source`` for anything missing, unknown, repeated, non-finite
    or misshapen."""

    def bad(why: str) -> SurrogateError:
        return SurrogateError(f"{source}: {why}")

    if not isinstance(descriptions, Mapping):
        raise bad("'models' is not a mapping")
    arrays: dict[str, dict[str, np.ndarray]] = {}
    for model, name, shape, values in zip(
        table["model"].to_pylist(),
        table["array"].to_pylist(),
        table["shape"].to_pylist(),
        table["values"].to_numpy(zero_copy_only=False),
        strict=True,
    ):
        if not 1 <= len(shape) <= _MAX_DIMENSIONS or any(n < 0 for n in shape):
            raise bad(f"{model}.{name}: shape {shape}")
        values = np.asarray(values, dtype=float)
        if math.prod(shape) != values.size or not np.isfinite(values).all():
            raise bad(f"{model}.{name}: {values.size} values for shape {shape} or not finite")
        if name in arrays.setdefault(model, {}):
            raise bad(f"{model}.{name}: stored twice")
        arrays[model][name] = values.reshape(shape)
    found = {}
    for model, description in descriptions.items():
        found[model] = _described(model, description, arrays.pop(model, {}), bad)
    if arrays:
        raise bad(f"arrays of undescribed models {sorted(arrays)}")
    return found


def _described(model: str, description: Any, arrays: dict, bad: Any) -> ModelData:
    if not isinstance(description, Mapping) or set(description) != {
        "candidate",
        "columns",
        "hyper",
        "constant",
    }:
        raise bad(f"{model}: not a model description")
    candidate, columns = description["candidate"], description["columns"]
    hyper, constant = description["hyper"], description["constant"]
    if constant is not None:
        if type(constant) is not float or constant not in (0.0, 1.0) or arrays or hyper:
            raise bad(f"{model}: a constant classifier is 0.0 or 1.0 and nothing else")
        if candidate not in (*CLASSIFIERS, ALL_FEASIBLE) or columns is not None:
            raise bad(f"{model}: unknown constant classifier {candidate!r}")
        return ModelData(candidate, constant=constant)
    if candidate not in _ARRAYS:
        raise bad(f"{model}: unknown candidate {candidate!r}")
    if columns is not None and not (
        isinstance(columns, list) and all(type(c) is int and c >= 0 for c in columns)
    ):
        raise bad(f"{model}: columns {columns!r}")
    expected = set(_ARRAYS[candidate])
    if set(arrays) != expected:
        raise bad(f"{model}: arrays {sorted(arrays)}, expected {sorted(expected)}")
    if not isinstance(hyper, Mapping) or set(hyper) != set(_CANDIDATES[candidate].hyper):
        raise bad(f"{model}: hyperparameters {hyper!r}")
    for name, value in hyper.items():
        numbers = value if isinstance(value, list) else [value]
        if not all(type(x) is float and math.isfinite(x) and x > 0 for x in numbers):
            raise bad(f"{model}: hyperparameter {name} {value!r}")
    n = arrays["u"].shape[0]
    if arrays["u"].ndim != _MAX_DIMENSIONS or arrays["y"].shape != (n,):
        raise bad(f"{model}: training inputs {arrays['u'].shape}, values {arrays['y'].shape}")
    return ModelData(
        candidate,
        None if columns is None else tuple(columns),
        dict(hyper),
        None,
        arrays,
    )
