"""Held-out split, k-fold cross-validation and the metrics that select and judge surrogates.

Method
------
- **Held-out set.** A seeded random share ``holdout_fraction`` of *all* samples,
  stratified by feasibility (:func:`holdout_mask`). It is used for nothing but the final
  report (``heldout_*`` metrics): neither for fitting nor for choosing a candidate, so its
  errors are an unbiased estimate of the selected model's error (Hastie, Tibshirani &
  Friedman, *The Elements of Statistical Learning*, 2nd ed., 2009, sec. 7.2 and 7.10.2).
- **k-fold cross-validation** on the training part (ESL sec. 7.10.1): the samples are
  shuffled with ``seed`` and cut into k folds (``sklearn.model_selection.KFold``; the
  classifiers use ``StratifiedKFold`` so every fold keeps both classes when it can); each
  fold is predicted by the candidate fitted on the other k - 1 folds. The pooled
  out-of-fold predictions give the CV metrics, and the candidate with the best CV metric
  is selected. k is ``min(folds, n)`` (leave-one-out when there are fewer samples than
  folds; for the stratified split, at most the size of the larger class).

Metrics (``y`` observed, ``ŷ`` out-of-fold or held-out prediction, ``ȳ`` the mean of ``y``)
---------------------------------------------------------------------------------------
- ``PRESS = Σ (y - ŷ_cv)²`` (prediction error sum of squares);
  ``cv_rmse = sqrt(PRESS / n)``.
- ``Q² = 1 - PRESS / Σ (y - ȳ)²``: the cross-validated coefficient of determination
  (Forrester, Sóbester & Keane, *Engineering Design via Surrogate Modelling*, Wiley 2008,
  ch. 2, model validation); 1 is a perfect predictor, 0 no better than the mean.
- ``heldout_rmse = sqrt(mean (y - ŷ)²)`` and ``heldout_r2 = 1 - Σ (y - ŷ)² / Σ (y - ȳ)²``
  on the held-out feasible samples (ȳ their own mean, as ``sklearn.metrics.r2_score``).
- Classifier: ``accuracy`` of the decision "feasible iff p >= 0.5", ``balanced accuracy``
  (mean of the recalls of both classes, robust to a rare class) and ``log loss``
  ``-mean(y log p + (1 - y) log(1 - p))`` (scikit-learn's definitions).

A metric that is undefined is ``None`` (``pd.NA`` in the tables), never NaN: R² or Q² when
the reference values have no spread or fewer than 2 held-out samples exist, and every
held-out metric when no held-out sample of the needed kind exists.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from sklearn.metrics import accuracy_score, balanced_accuracy_score, log_loss
from sklearn.model_selection import KFold, StratifiedKFold

from ovtraj.config.mission import SurrogateSettings
from ovtraj.surrogate.candidates import CandidateError
from ovtraj.surrogate.fitted_models import (
    FeasibilityClassifier,
    Regressor,
    fit_classifier,
    fit_regressor,
)

__all__ = [
    "DECISION_PROBABILITY",
    "ClassifierScore",
    "Folds",
    "RegressorScore",
    "classification_folds",
    "cross_validated_rows",
    "evaluate_classifier",
    "evaluate_regressor",
    "failures",
    "holdout_mask",
    "q2",
    "r2",
    "regression_folds",
    "regressor_fit",
    "regressor_fit_arguments",
    "regressor_score",
    "rmse",
    "select_classifier",
    "select_regressor",
    "subsampled_folds",
]

# The decision "feasible" for the accuracy metrics: the more probable class (equal costs).
DECISION_PROBABILITY = 0.5

Folds = list[tuple[np.ndarray, np.ndarray]]


def _round_half_up(x: float) -> int:
    return int(np.floor(x + 0.5))


def holdout_mask(feasible: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    """Boolean mask (n,) of the held-out samples: ``fraction`` of all, stratified by feasibility.

    ``n_hold = max(1, round(fraction n))`` (none when n < 2) is shared between the feasible
    and infeasible samples in proportion to their counts, with at least one of each class
    when that class has 2 or more samples and never all of a class (a class with a single
    sample stays in training, where it informs the classifier). Within each class the
    samples are drawn with ``numpy.random.default_rng(seed)`` (feasible class first).
    """
    feasible = np.asarray(feasible, dtype=bool)
    n = feasible.size
    mask = np.zeros(n, dtype=bool)
    if n < 2:
        return mask
    n_hold = min(max(1, _round_half_up(fraction * n)), n - 1)
    members = (np.flatnonzero(feasible), np.flatnonzero(~feasible))
    counts = [m.size for m in members]
    take = [0, 0]
    if min(counts) >= 2:
        take[1] = int(np.clip(_round_half_up(n_hold * counts[1] / n), 1, counts[1] - 1))
        take[0] = int(np.clip(n_hold - take[1], 1, counts[0] - 1))
    else:
        big = 0 if counts[0] >= counts[1] else 1
        take[big] = min(n_hold, counts[big] - 1)
    rng = np.random.default_rng(seed)
    for idx, k in zip(members, take, strict=True):
        if k:
            mask[rng.permutation(idx)[:k]] = True
    return mask


def regression_folds(n: int, folds: int, seed: int) -> Folds:
    """``KFold(min(folds, n), shuffle=True, random_state=seed)`` over samples 0..n-1."""
    if n < 2:
        raise CandidateError(f"cross-validation needs at least 2 samples, got {n}")
    kfold = KFold(n_splits=min(folds, n), shuffle=True, random_state=seed)
    return list(kfold.split(np.zeros((n, 1))))


def classification_folds(y: np.ndarray, folds: int, seed: int) -> Folds:
    """``StratifiedKFold(k, shuffle=True, random_state=seed)``, k = min(folds, larger class)."""
    y = np.asarray(y, dtype=bool)
    k = min(folds, max(np.count_nonzero(y), np.count_nonzero(~y)))
    if k < 2:
        raise CandidateError(f"cross-validation needs at least 2 samples, got {y.size}")
    skf = StratifiedKFold(n_splits=k, shuffle=True, random_state=seed)
    with warnings.catch_warnings():
        # "The least populated class has only m members": expected with few infeasible samples.
        warnings.filterwarnings("ignore", message="The least populated class", category=UserWarning)
        return list(skf.split(np.zeros((y.size, 1)), y))


def subsampled_folds(folds_of: Callable[[np.ndarray], Folds], rows: np.ndarray) -> Folds:
    """Folds of the training samples at positions ``rows`` (a subsample, ascending):
    ``folds_of`` cuts the subsample, the folds name training positions."""
    return [(rows[fit], rows[test]) for fit, test in folds_of(rows)]


def cross_validated_rows(folds: Folds, n: int) -> np.ndarray:
    """The training positions the folds predict, ascending: all ``n`` of them unless the
    folds were cut from a subsample (:func:`subsampled_folds`)."""
    covered = np.sort(np.concatenate([test for _, test in folds])) if folds else np.arange(0)
    return np.arange(n) if covered.size == n else covered


def rmse(y: np.ndarray, y_hat: np.ndarray) -> float | None:
    """Root-mean-square error; None without samples."""
    y, y_hat = np.asarray(y, float), np.asarray(y_hat, float)
    if y.size == 0:
        return None
    return float(np.sqrt(np.mean((y - y_hat) ** 2)))


def _determination(y: np.ndarray, y_hat: np.ndarray) -> float | None:
    y, y_hat = np.asarray(y, float), np.asarray(y_hat, float)
    if y.size < 2:
        return None
    total = float(np.sum((y - y.mean()) ** 2))
    if total <= 0.0:
        return None
    return 1.0 - float(np.sum((y - y_hat) ** 2)) / total


def q2(y: np.ndarray, y_cv: np.ndarray) -> float | None:
    """``1 - PRESS / Σ (y - ȳ)²`` from out-of-fold predictions; None if y has no spread."""
    return _determination(y, y_cv)


def r2(y: np.ndarray, y_hat: np.ndarray) -> float | None:
    """Coefficient of determination; None with fewer than 2 samples or no spread in y."""
    return _determination(y, y_hat)


@dataclass
class RegressorScore:
    """CV and held-out results of one regressor candidate for one output."""

    name: str
    n_train: int
    n_heldout: int
    error: str | None = None
    cv_pred: np.ndarray | None = None
    cv_rmse: float | None = None
    cv_q2: float | None = None
    heldout_pred: np.ndarray | None = None
    heldout_rmse: float | None = None
    heldout_r2: float | None = None
    fit_time_s: float = 0.0
    model: Regressor | None = field(default=None, repr=False)
    # The training samples (positions) ``cv_pred`` covers, in order: all of them unless
    # the cross-validation ran on a subsample (``large_samples.cv_max_samples``).
    cv_rows: np.ndarray | None = None


@dataclass(frozen=True)
class RegressorFit:
    """One fit of a candidate and its predictions: on a CV fold's fitting part (predicting
    the fold) or on the whole training part (predicting the hold-out; ``model`` kept)."""

    predictions: np.ndarray | None
    model: Regressor | None = field(default=None, repr=False)
    error: str | None = None
    seconds: float = 0.0


def regressor_fit(
    name: str,
    u_fit: np.ndarray,
    y_fit: np.ndarray,
    u_predict: np.ndarray,
    settings: SurrogateSettings,
    keep_model: bool = False,
    theta0: np.ndarray | None = None,
) -> RegressorFit:
    """Fit candidate ``name`` on (``u_fit``, ``y_fit``) and predict ``u_predict``.

    The pieces of :func:`evaluate_regressor` (each fold, then the whole training part):
    independent, so a process pool may run them in any order with the same result.
    ``theta0``: a Kriging start (:func:`~ovtraj.surrogate.fitted_models.fit_regressor`).
    """
    start = time.perf_counter()
    try:
        model = fit_regressor(name, u_fit, y_fit, settings, theta0)
        predictions = model.predict(u_predict) if len(u_predict) else np.empty(0)
    except CandidateError as err:
        return RegressorFit(None, error=str(err), seconds=time.perf_counter() - start)
    return RegressorFit(
        predictions, model if keep_model else None, seconds=time.perf_counter() - start
    )


def regressor_fit_arguments(
    name: str,
    u_train: np.ndarray,
    y_train: np.ndarray,
    u_held: np.ndarray,
    folds: Folds,
    settings: SurrogateSettings,
) -> list[tuple]:
    """The :func:`regressor_fit` arguments of candidate ``name``: every fold, then the
    whole training part (the model kept)."""
    pieces = [
        (name, u_train[fit_idx], y_train[fit_idx], u_train[test_idx], settings, False)
        for fit_idx, test_idx in folds
    ]
    return [*pieces, (name, u_train, y_train, u_held, settings, True)]


def regressor_score(
    name: str, y_train: np.ndarray, y_held: np.ndarray, folds: Folds, fits: list[RegressorFit]
) -> RegressorScore:
    """The candidate's score from its fits (:func:`regressor_fit_arguments`' order).

    The first failure in that order is the candidate's ``error``: a fold's, the CV
    predictions' (non-finite), the whole fit's, the held-out predictions' (non-finite).
    """
    score = RegressorScore(name, n_train=y_train.size, n_heldout=y_held.size)
    score.fit_time_s = sum(f.seconds for f in fits)
    *fold_fits, whole = fits
    cv_pred = np.empty_like(y_train, dtype=float)
    for k, ((_, test_idx), fit) in enumerate(zip(folds, fold_fits, strict=True)):
        if fit.error is not None:
            score.error = f"CV fold {k + 1}/{len(folds)}: {fit.error}"
            return score
        cv_pred[test_idx] = fit.predictions
    covered = cross_validated_rows(folds, y_train.size)
    y_train, cv_pred = y_train[covered], cv_pred[covered]
    if not np.all(np.isfinite(cv_pred)):
        score.error = f"{name} gives non-finite cross-validation predictions"
    elif whole.error is not None:
        score.error = whole.error
    elif not np.all(np.isfinite(whole.predictions)):
        score.error = f"{name} gives non-finite held-out predictions"
    if score.error is not None:
        return score
    score.cv_pred = cv_pred
    score.cv_rows = covered
    score.cv_rmse = rmse(y_train, cv_pred)
    score.cv_q2 = q2(y_train, cv_pred)
    score.heldout_pred = whole.predictions
    score.heldout_rmse = rmse(y_held, whole.predictions)
    score.heldout_r2 = r2(y_held, whole.predictions)
    score.model = whole.model
    return score


def evaluate_regressor(
    name: str,
    u_train: np.ndarray,
    y_train: np.ndarray,
    u_held: np.ndarray,
    y_held: np.ndarray,
    folds: Folds,
    settings: SurrogateSettings,
) -> RegressorScore:
    """k-fold CV of candidate ``name``, then its fit on the whole training part.

    The held-out samples only get predicted by the final model; they never enter a fit.
    A failure in any fold or in the final fit is recorded in ``error``.
    """
    arguments = regressor_fit_arguments(name, u_train, y_train, u_held, folds, settings)
    fits = [regressor_fit(*a) for a in arguments]
    return regressor_score(name, y_train, y_held, folds, fits)


@dataclass
class ClassifierScore:
    """CV and held-out results of one feasibility classifier candidate."""

    name: str
    n_train: int
    n_heldout: int
    error: str | None = None
    cv_pred: np.ndarray | None = None
    cv_accuracy: float | None = None
    cv_balanced_accuracy: float | None = None
    cv_log_loss: float | None = None
    heldout_pred: np.ndarray | None = None
    heldout_accuracy: float | None = None
    fit_time_s: float = 0.0
    model: FeasibilityClassifier | None = field(default=None, repr=False)
    cv_rows: np.ndarray | None = None  # as RegressorScore's


def _classification_metrics(y: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
    decided = p >= DECISION_PROBABILITY
    with warnings.catch_warnings():
        # A single class in y (all feasible) makes balanced accuracy warn; its value is defined.
        warnings.simplefilter("ignore", category=UserWarning)
        balanced = float(balanced_accuracy_score(y, decided))
    loss = float(log_loss(y, np.column_stack([1.0 - p, p]), labels=[False, True]))
    return float(accuracy_score(y, decided)), balanced, loss


def evaluate_classifier(
    name: str,
    u_train: np.ndarray,
    y_train: np.ndarray,
    u_held: np.ndarray,
    y_held: np.ndarray,
    folds: Folds,
    settings: SurrogateSettings,
) -> ClassifierScore:
    """Stratified k-fold CV of classifier ``name``, then its fit on the whole training part."""
    score = ClassifierScore(name, n_train=y_train.size, n_heldout=y_held.size)
    start = time.perf_counter()
    try:
        cv_pred = np.empty(y_train.size, dtype=float)
        for k, (fit_idx, test_idx) in enumerate(folds):
            try:
                fold_model = fit_classifier(name, u_train[fit_idx], y_train[fit_idx], settings)
            except CandidateError as err:
                raise CandidateError(f"CV fold {k + 1}/{len(folds)}: {err}") from err
            cv_pred[test_idx] = fold_model.proba(u_train[test_idx])
        model = fit_classifier(name, u_train, y_train, settings)
        held_pred = model.proba(u_held) if y_held.size else np.empty(0)
    except CandidateError as err:
        score.error = str(err)
        score.fit_time_s = time.perf_counter() - start
        return score
    score.fit_time_s = time.perf_counter() - start
    covered = cross_validated_rows(folds, y_train.size)
    score.cv_pred = cv_pred[covered]
    score.cv_rows = covered
    score.cv_accuracy, score.cv_balanced_accuracy, score.cv_log_loss = _classification_metrics(
        y_train[covered], score.cv_pred
    )
    score.heldout_pred = held_pred
    if y_held.size:
        score.heldout_accuracy = float(accuracy_score(y_held, held_pred >= DECISION_PROBABILITY))
    score.model = model
    return score


def select_regressor(scores: Sequence[RegressorScore]) -> RegressorScore | None:
    """The fitted candidate with the lowest cv_rmse (ties: the first in config order)."""
    best = None
    for s in scores:
        if s.error is None and (best is None or s.cv_rmse < best.cv_rmse):
            best = s
    return best


def select_classifier(scores: Sequence[ClassifierScore]) -> ClassifierScore | None:
    """Highest CV balanced accuracy; ties: lower CV log loss, then config order."""
    best = None
    for s in scores:
        if s.error is not None:
            continue
        if best is None or (-s.cv_balanced_accuracy, s.cv_log_loss) < (
            -best.cv_balanced_accuracy,
            best.cv_log_loss,
        ):
            best = s
    return best


def failures(scores: Sequence[RegressorScore] | Sequence[ClassifierScore]) -> str:
    """Each candidate's name and error, for the line that says none could be fitted."""
    return "; ".join(f"{s.name}: {s.error}" for s in scores)
