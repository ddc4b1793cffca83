"""Each output's regressor: its candidates cross-validated with the same k folds of the
output's feasible training samples, the lowest CV RMSE selected, then fitted.

Every fold of every candidate is a job of its own, scored in this process or on an
executor's processes (the same models and figures: every candidate is seeded and fitted
with one BLAS thread). An output fitted on some inputs only trains on the first of the
samples that repeat those inputs (repeated inputs make a Kriging correlation matrix
singular); an output may leave samples out (``fit_surrogates``' ``left_out``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from concurrent.futures import Executor
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config.mission import SurrogateSettings
from ovtraj.parallel import mapped, started
from ovtraj.surrogate.candidates import regressor
from ovtraj.surrogate.compared_candidates import configured_regressors, shortlisted
from ovtraj.surrogate.fit_threads import one_blas_thread
from ovtraj.surrogate.fitted_models import Regressor, fit_regressor, refitted, seeded_subsample
from ovtraj.surrogate.scaling import SurrogateError
from ovtraj.surrogate.tables import prediction_rows, regressor_rows
from ovtraj.surrogate.validation import (
    Folds,
    RegressorFit,
    RegressorScore,
    failures,
    regression_folds,
    regressor_fit,
    regressor_fit_arguments,
    regressor_score,
    select_regressor,
    subsampled_folds,
)

__all__ = ["FittedRegressors", "fit_regressors"]


@dataclasses.dataclass
class FittedRegressors:
    """Every output's selected regressor, with its validation and predictions rows."""

    models: dict[str, Regressor]
    selected: dict[str, str]
    rows: list[dict]
    tables: list[pd.DataFrame]


@dataclasses.dataclass
class _OutputRows:
    """An output's own inputs (unit cube, n x k), its usable samples (feasible, not left
    out; (n,) bool), its training rows (ascending) and hold-out rows, its folds of the
    training rows, its configured candidates and its columns (``None``: every input)."""

    inputs: np.ndarray
    usable: np.ndarray
    train: np.ndarray
    held: np.ndarray
    folds: Folds
    configured: list[str]
    columns: tuple[int, ...] | None


class _Meanwhile:
    """A call made once, in this process, while the executor fits (or after the fits)."""

    def __init__(self, call: Callable[[], None] | None) -> None:
        self._pending = [call] if call is not None else []

    def __call__(self) -> None:
        while self._pending:
            self._pending.pop()()


def fit_regressors(
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
) -> FittedRegressors:
    """CV, selection and final fit of every output's regressor (feasible samples only).

    ``meanwhile``: called once, in this process, while ``executor`` fits the candidates
    (with no executor, after them); ``columns``: the outputs fitted on some inputs only
    (``fit_surrogates``' ``output_inputs``); ``omitted``: the samples each output leaves
    out (its ``left_out``)."""
    in_the_meantime = _Meanwhile(meanwhile)
    plans = _output_rows(u, values, flags, held, settings, columns or {}, omitted or {})
    first = {
        name: shortlisted(candidates.get(name), plan.configured) for name, plan in plans.items()
    }
    all_scores = _scored(first, plans, values, settings, executor, in_the_meantime)
    # A kept candidate that cannot be fitted on these data: every candidate is compared.
    retry = {
        name: plans[name].configured
        for name, listed in first.items()
        if listed != plans[name].configured and select_regressor(all_scores[name]) is None
    }
    if retry:
        all_scores |= _scored(retry, plans, values, settings, executor, in_the_meantime)
    in_the_meantime()
    fitted = FittedRegressors({}, {}, [], [])
    for name, y in values.items():
        _select(fitted, name, y, all_scores[name], plans[name], ids, settings)
    return fitted


def _output_rows(
    u: np.ndarray,
    values: dict[str, np.ndarray],
    flags: np.ndarray,
    held: np.ndarray,
    settings: SurrogateSettings,
    columns: dict[str, tuple[int, ...]],
    omitted: dict[str, np.ndarray],
) -> dict[str, _OutputRows]:
    """Each output's inputs, training rows and folds: all of them, unless it has inputs of
    its own (then the first of the rows that repeat those inputs)."""
    none = np.zeros(flags.shape, dtype=bool)
    plans = {}
    for name in values:
        usable = flags & ~omitted.get(name, none)
        inputs = u[:, list(columns[name])] if name in columns else u
        train = np.flatnonzero(~held & usable)
        if name in columns:
            train = _first_of_repeats(train, inputs)
        plans[name] = _OutputRows(
            inputs=inputs,
            usable=usable,
            train=train,
            held=np.flatnonzero(held & usable),
            folds=_regression_folds(train.size, settings),
            configured=configured_regressors(train.size, settings),
            columns=columns.get(name),
        )
    return plans


def _scored(
    names: dict[str, list[str]],
    plans: dict[str, _OutputRows],
    values: dict[str, np.ndarray],
    settings: SurrogateSettings,
    executor: Executor | None,
    in_the_meantime: _Meanwhile,
) -> dict[str, list[RegressorScore]]:
    """The scores of the candidates ``names`` lists for each output, in that order."""
    jobs = [(name, candidate) for name, listed in names.items() for candidate in listed]
    # Every fold of every candidate is a job of its own: ~6 similar Kriging fits per
    # candidate keep a pool's processes evenly busy where whole candidates did not.
    pieces = [
        regressor_fit_arguments(
            candidate,
            plans[name].inputs[plans[name].train],
            values[name][plans[name].train],
            plans[name].inputs[plans[name].held],
            plans[name].folds,
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
        y, plan = values[name], plans[name]
        out[name].append(regressor_score(candidate, y[plan.train], y[plan.held], plan.folds, mine))
    return out


def _select(
    fitted: FittedRegressors,
    name: str,
    y: np.ndarray,
    scores: list[RegressorScore],
    plan: _OutputRows,
    ids: np.ndarray,
    settings: SurrogateSettings,
) -> None:
    """Output ``name``'s best candidate, refitted with the hold-out if so configured, and
    its rows, added to ``fitted``."""
    best = select_regressor(scores)
    if best is None:
        raise SurrogateError(f"output {name!r}: no candidate could be fitted ({failures(scores)})")
    fitted.selected[name] = best.name
    model = best.model
    x, train = plan.inputs, plan.train
    if settings.holdout_refit and plan.held.size:
        # Scored without the hold-out; the model used has seen it too.
        every = np.flatnonzero(plan.usable)
        every = _first_of_repeats(every, x) if plan.columns is not None else every
        model = refitted(model, lambda: fit_regressor(best.name, x[every], y[every], settings))
    if plan.columns is not None:
        model = dataclasses.replace(model, columns=plan.columns)
    fitted.models[name] = model
    fitted.rows += [
        dict(r, n_folds=len(plan.folds)) for r in regressor_rows(name, scores, best.name)
    ]
    fitted.tables.append(
        prediction_rows(
            name,
            ids[train][best.cv_rows],
            y[train][best.cv_rows],
            best.cv_pred,
            ids[plan.held],
            y[plan.held],
            best.heldout_pred,
        )
    )


def _first_of_repeats(rows: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """``rows`` (ascending) without those whose ``inputs`` repeat an earlier row's."""
    if rows.size == 0:
        return rows
    _, first = np.unique(inputs[rows], axis=0, return_index=True)
    return rows[np.sort(first)]


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
    model = whole.model
    if model is None or not regressor(model.name).kriging:
        return None
    return np.asarray(model.model.optimal_theta, dtype=float)


def _regressor_fit(*arguments: Any) -> RegressorFit:
    """:func:`regressor_fit` with one BLAS thread, wherever it runs."""
    with one_blas_thread():
        return regressor_fit(*arguments)
