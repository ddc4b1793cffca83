"""Fitting, cross-validating and selecting the surrogate set of the whole-mission chain.

:func:`fit_surrogates` turns a design of experiments (physical inputs, the chain's
outputs, the feasibility flags) into a :class:`~ovtraj.surrogate.surrogate_set.SurrogateSet`:

1. Inputs are scaled to the unit cube of [lower, upper].
2. A stratified, seeded share ``holdout_fraction`` of all samples is held out
   (:func:`~ovtraj.surrogate.validation.holdout_mask`).
3. Per output, every candidate of ``settings.regressors`` is cross-validated with the
   same k folds of the feasible training samples (ascending sample order, ``KFold(k,
   shuffle=True, random_state=seed)``); the lowest ``cv_rmse`` is selected (ties: config
   order). Every candidate is then fitted on all feasible training samples and scored
   on the held-out feasible samples, for the report only
   (:mod:`ovtraj.surrogate.regressor_selection`).
4. Feasibility: every candidate of ``settings.classifiers`` is cross-validated on all
   training samples (stratified folds); highest balanced accuracy wins (ties: lower log
   loss, then config order). If every training sample is feasible, a constant
   probability 1 ("all-feasible") replaces the classifiers
   (:mod:`ovtraj.surrogate.classifier_selection`).

With ``settings.holdout_refit`` the selected models are then fitted again on every
sample, the held-out ones included: the held-out figures describe the model fitted
without them, the model returned has seen them too.

``candidates`` (output name -> candidate, ``"feasible"`` -> classifier; e.g. an earlier
fit's ``selected``) restricts the models named there to that one candidate: it is still
cross-validated and checked on the hold-out, but not compared with the others. A
regressor may be given a list (a shortlist,
:func:`~ovtraj.surrogate.compared_candidates.shortlist`): those candidates are compared.
If none can be fitted on these data (or the earlier set was all feasible and this one is
not), every configured candidate is tried as without the restriction.

``executor`` (a ``concurrent.futures`` process pool or Dask executor) scores the regressor
candidates (every output's) on its processes: the same models and figures as in this
process, since every candidate is seeded and fitted with one BLAS thread.

A candidate that fails gets its reason in the ``error`` column and is not selected. The
method (unit-cube scaling, stratified held-out split, k-fold CV, metrics) is described in
:mod:`ovtraj.surrogate.validation` and ``docs/surrogate.md``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from concurrent.futures import Executor

import numpy as np
import pandas as pd

from ovtraj.config.mission import SurrogateSettings
from ovtraj.surrogate.classifier_selection import fit_feasibility
from ovtraj.surrogate.fit_threads import serial_blas
from ovtraj.surrogate.fitted_models import FeasibilityClassifier
from ovtraj.surrogate.regressor_selection import FittedRegressors, fit_regressors
from ovtraj.surrogate.scaling import SurrogateError, UnitCube
from ovtraj.surrogate.surrogate_set import SurrogateSet
from ovtraj.surrogate.tables import (
    FEASIBLE,
    predictions_table,
    validation_frame,
    validation_table,
)
from ovtraj.surrogate.training_data import (
    checked_left_out,
    checked_training_data,
    output_columns,
    training_data_hash,
)
from ovtraj.surrogate.validation import holdout_mask

__all__ = ["fit_surrogates"]


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
    """Fit, cross-validate and select the surrogates of ``outputs`` and of feasibility
    (the steps in the module notes).

    ``X`` (n, d) physical inputs inside [lower, upper]; ``outputs`` name -> (n,) values (NaN
    allowed at infeasible samples only); ``feasible`` (n,) bool; ``sample_ids`` (n,) distinct
    ints for the predictions table (default 0..n-1).

    ``candidates`` and ``executor``: kept candidates and where the regressors are scored
    (module notes).

    ``output_inputs`` (output name -> names of ``input_names``) fits those outputs on those
    inputs alone, e.g. a quantity that physically depends on fewer inputs than the set
    takes; the others on all. Such an output is trained on the first of the training
    samples that repeat its inputs, with its own k folds of them; it still predicts from
    all the set's inputs.

    ``left_out`` (output name -> (n,) bool) leaves those samples out of that output's
    regressor (its training, folds and hold-out rows), e.g. samples in a regime the
    output's model is not meant to describe; they still count for the other outputs and
    for the feasibility model. Each output keeps at least ``min_training_samples``.

    ``classified`` ((n,) bool) trains and scores the feasibility classifier on those
    samples alone (its hold-out rows among them), e.g. without samples whose
    infeasibility another model accounts for; the regressors are not affected.

    Raises :class:`SurrogateError` for unusable data (no samples, none feasible, too few
    feasible training samples, shapes, NaN) or when no candidate of a model can be fitted.
    """
    x, values, flags, ids = checked_training_data(
        X, outputs, feasible, tuple(input_names), sample_ids
    )
    columns = output_columns(output_inputs or {}, tuple(input_names), values)
    omitted = checked_left_out(left_out or {}, values, x.shape[0])
    cube = UnitCube(lower, upper)
    if cube.dim != x.shape[1]:
        raise SurrogateError(
            f"bounds: {cube.dim} lower/upper values for X with {x.shape[1]} columns; one per input"
        )
    data_hash = training_data_hash(x, values, flags)
    u = cube.to_unit(x)
    held = _held_out(flags, settings, omitted)
    kept = dict(candidates or {})
    with serial_blas():
        rows_of = _classified(classified, x.shape[0])
        fitted = []

        def classify() -> None:
            args = (u[rows_of], flags[rows_of], ids[rows_of], held[rows_of], settings)
            fitted.append(fit_feasibility(*args, kept.get(FEASIBLE)))

        # The classifier is fitted here while the pool fits the regressors.
        regressors = fit_regressors(
            u, values, flags, ids, held, settings, kept, executor, classify, columns, omitted
        )
    return _fitted_set(regressors, *fitted[0], tuple(input_names), cube, data_hash, settings)


def _held_out(
    flags: np.ndarray, settings: SurrogateSettings, omitted: dict[str, np.ndarray]
) -> np.ndarray:
    """The held-out samples (n,) bool; SurrogateError when too few feasible training
    samples remain, for the set or for an output once its own samples are left out."""
    n = flags.size
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
    return held


def _classified(classified: np.ndarray | None, n: int) -> np.ndarray:
    """The samples the classifier learns from (n,) bool: ``classified``, or all."""
    rows_of = np.ones(n, dtype=bool) if classified is None else np.asarray(classified, bool)
    if rows_of.shape != (n,) or not rows_of.any():
        raise SurrogateError(f"classified: expected a boolean array of shape ({n},), not empty")
    return rows_of


def _fitted_set(
    regressors: FittedRegressors,
    classifier: FeasibilityClassifier,
    classifier_rows: list[dict],
    classifier_table: pd.DataFrame,
    input_names: tuple[str, ...],
    cube: UnitCube,
    data_hash: str,
    settings: SurrogateSettings,
) -> SurrogateSet:
    """The set of the selected models and their tables, the classifier's last."""
    selected = {**regressors.selected, FEASIBLE: classifier.name}
    rows = regressors.rows + classifier_rows
    tables = [*regressors.tables, classifier_table]
    return SurrogateSet(
        input_names=input_names,
        output_names=tuple(regressors.selected),
        cube=cube,
        regressors=regressors.models,
        classifier=classifier,
        selected=selected,
        validation=validation_frame(validation_table(rows)),
        predictions=predictions_table(pd.concat(tables, ignore_index=True)).to_pandas(),
        data_hash=data_hash,
        settings=settings,
    )
