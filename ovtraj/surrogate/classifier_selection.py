"""The feasibility classifier of a surrogate set: its candidates cross-validated on every
training sample (stratified folds), the best selected and fitted.

Highest CV balanced accuracy wins (ties: lower log loss, then config order;
:func:`~ovtraj.surrogate.validation.select_classifier`). If every training sample is
feasible, a constant probability 1 (``all-feasible``) replaces the classifiers.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ovtraj.config.mission import SurrogateSettings
from ovtraj.surrogate.candidates import ALL_FEASIBLE
from ovtraj.surrogate.compared_candidates import configured_classifiers
from ovtraj.surrogate.fitted_models import (
    FeasibilityClassifier,
    fit_classifier,
    refitted,
    seeded_subsample,
)
from ovtraj.surrogate.scaling import SurrogateError
from ovtraj.surrogate.tables import FEASIBLE, classifier_rows, prediction_rows
from ovtraj.surrogate.validation import (
    ClassifierScore,
    Folds,
    classification_folds,
    evaluate_classifier,
    failures,
    select_classifier,
    subsampled_folds,
)

__all__ = ["fit_feasibility"]


def fit_feasibility(
    u: np.ndarray,
    flags: np.ndarray,
    ids: np.ndarray,
    held: np.ndarray,
    settings: SurrogateSettings,
    kept: str | None = None,
) -> tuple[FeasibilityClassifier, list[dict], pd.DataFrame]:
    """CV, selection and final fit of the feasibility classifier (all training samples):
    the model, its validation rows and its predictions rows.

    ``kept``: an earlier fit's classifier, compared alone unless it cannot be fitted.
    """
    cls_train = np.flatnonzero(~held)
    cls_held = np.flatnonzero(held)
    y_cls = flags[cls_train]
    cls_folds = _classification_folds(y_cls, settings)
    configured = configured_classifiers(settings)

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
        raise SurrogateError(f"feasibility: no classifier could be fitted ({failures(cls_scores)})")
    model = best.model
    if settings.holdout_refit and cls_held.size and best.name != ALL_FEASIBLE:
        model = refitted(model, lambda: fit_classifier(best.name, u, flags, settings))
    rows = [dict(r, n_folds=len(cls_folds)) for r in classifier_rows(cls_scores, best.name)]
    table = prediction_rows(
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
