"""One candidate fitted on unit-cube data, checked, and its predictions.

:func:`fit_regressor` and :func:`fit_classifier` build a candidate of the registry
(:mod:`ovtraj.surrogate.candidates`), fit it (on a seeded subsample when it is a
subsampled candidate and the settings' ``large_samples`` say so) and refuse one that
predicts non-finite values at its own training samples. A training set that holds a
single class gets a constant classifier instead: probability 1 (or 0) everywhere.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from smt.surrogate_models.surrogate_model import SurrogateModel

from ovtraj.config.mission import SurrogateSettings
from ovtraj.surrogate.candidates import Candidate, CandidateError, classifier, regressor
from ovtraj.surrogate.estimators import TreeEnsemble

__all__ = [
    "FeasibilityClassifier",
    "Regressor",
    "fit_classifier",
    "fit_regressor",
    "refitted",
    "seeded_subsample",
]


def seeded_subsample(
    n: int, limit: int, seed: int, classes: np.ndarray | None = None
) -> np.ndarray:
    """Indices (ascending) of at most ``limit`` of ``n`` samples, drawn at random with
    ``seed``; all of them when ``n <= limit``. ``classes`` (n,) bool: each class keeps its
    share (rounded, at least 2 of a class that has 2), so a rare class stays in."""
    if n <= limit:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    if classes is None:
        return np.sort(rng.choice(n, size=limit, replace=False))
    classes = np.asarray(classes, dtype=bool)
    minority = classes if classes.sum() <= n / 2 else ~classes
    rare = np.flatnonzero(minority)
    common = np.flatnonzero(~minority)
    take_rare = min(rare.size, max(min(rare.size, 2), round(limit * rare.size / n)))
    picked = [rng.choice(rare, size=take_rare, replace=False)]
    picked.append(rng.choice(common, size=limit - take_rare, replace=False))
    return np.sort(np.concatenate(picked))


def _subsampled(
    candidate: Candidate, n: int, settings: SurrogateSettings, classes: Any = None
) -> Any:
    """The rows ``candidate`` is fitted on (``slice(None)``: every one)."""
    large = settings.large_samples
    if large is None or not candidate.subsampled or n <= large.exact_max_samples:
        return slice(None)
    return seeded_subsample(n, large.exact_max_samples, settings.seed, classes)


@dataclass
class Regressor:
    """A fitted SMT model on unit-cube inputs.

    ``columns``: the inputs (column indices of the set's inputs) the model was fitted on,
    in order; ``None``: all of them (and every model stored before the option).
    """

    name: str
    model: SurrogateModel | Any
    columns: tuple[int, ...] | None = None

    def predict(self, u: np.ndarray) -> np.ndarray:
        """Unit-cube points (m, d) of all the set's inputs -> predictions (m,)."""
        u = np.asarray(u, dtype=float)
        if self.columns is not None:
            u = u[:, list(self.columns)]
        return self.predict_fitted(u)

    def predict_fitted(self, u: np.ndarray) -> np.ndarray:
        """Unit-cube points (m, k) of the inputs the model was fitted on -> predictions."""
        return np.asarray(self.model.predict_values(np.asarray(u, dtype=float))).reshape(-1)

    def training(self) -> tuple[np.ndarray, np.ndarray]:
        """The unit-cube inputs (n, k) and values (n,) the model was fitted on."""
        if isinstance(self.model, TreeEnsemble):
            u, y = self.model.training
        else:  # SMT keeps them as its (unnamed) training set
            u, y = self.model.training_points[None][0]
        return np.asarray(u, dtype=float), np.asarray(y, dtype=float).reshape(-1)


def fit_regressor(
    name: str,
    u: np.ndarray,
    y: np.ndarray,
    settings: SurrogateSettings,
    start: np.ndarray | None = None,
) -> Regressor:
    """Fit the SMT candidate ``name`` on unit-cube inputs ``u`` (n, d) and values ``y`` (n,).

    ``start``: Kriging hyperparameters (``theta``) to start the likelihood's maximisation
    from, alone (no other start); ignored by the other candidates.
    """
    candidate = regressor(name)
    n, dim = u.shape
    need = candidate.min_samples(dim)
    if n < need:
        raise CandidateError(f"{name} needs at least {need} training samples in {dim}-D, got {n}")
    model = candidate.build(dim, settings, start)
    rows = _subsampled(candidate, n, settings)
    u_fit, y_fit = np.asarray(u, dtype=float)[rows], np.asarray(y, dtype=float)[rows]
    try:
        model.set_training_values(np.ascontiguousarray(u_fit), y_fit)
        model.train()
    except Exception as err:  # SMT raises bare Exceptions, LinAlgErrors, ValueErrors ...
        raise CandidateError(f"{name} training failed: {type(err).__name__}: {err}") from err
    fitted = Regressor(name, model)
    check = fitted.predict(u_fit)
    if not np.all(np.isfinite(check)):
        raise CandidateError(f"{name} predicts non-finite values at its training samples")
    return fitted


@dataclass
class FeasibilityClassifier:
    """A fitted classifier on unit-cube inputs, or a constant one (single-class training)."""

    name: str
    estimator: Any | None
    constant: float | None = None
    # the unit-cube inputs and flags it was fitted on (what rebuilds it when stored)
    training: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    def proba(self, u: np.ndarray) -> np.ndarray:
        """Unit-cube points (m, d) -> probability of feasibility (m,) in [0, 1]."""
        u = np.asarray(u, dtype=float)
        if self.estimator is None:
            return np.full(u.shape[0], float(self.constant))
        classes = list(self.estimator.classes_)
        p = self.estimator.predict_proba(u)[:, classes.index(True)]
        return np.clip(p, 0.0, 1.0)

    def hyper(self) -> dict[str, float | list[float]]:
        """The fitted hyperparameters its candidate stores (none for most)."""
        if self.estimator is None:
            return {}
        hyper_of = classifier(self.name).hyper_of
        return {} if hyper_of is None else hyper_of(self.estimator)


def fit_classifier(
    name: str,
    u: np.ndarray,
    y: np.ndarray,
    settings: SurrogateSettings,
    hyper: Mapping[str, Any] | None = None,
) -> FeasibilityClassifier:
    """Fit the scikit-learn candidate ``name`` on ``u`` (n, d) and feasibility ``y`` (n,) bool.

    ``hyper``: the candidate's fitted hyperparameters from an earlier fit
    (:meth:`FeasibilityClassifier.hyper`), kept fixed.
    """
    y = np.asarray(y, dtype=bool)
    if y.size == 0:
        raise CandidateError(f"{name}: no training samples")
    if y.all() or not y.any():
        return FeasibilityClassifier(name, None, 1.0 if y.all() else 0.0)
    candidate = classifier(name)
    rows = _subsampled(candidate, y.size, settings, classes=y)
    u, y = np.asarray(u, dtype=float)[rows], y[rows]
    estimator = candidate.build(y, settings, hyper)
    try:
        with warnings.catch_warnings():
            # The classifiers' optimisers may stop at their iteration limit on tiny sets;
            # the fit is still usable and CV judges it.
            warnings.simplefilter("ignore", category=ConvergenceWarning)
            estimator.fit(u, y)
    except Exception as err:
        raise CandidateError(f"{name} training failed: {type(err).__name__}: {err}") from err
    fitted = FeasibilityClassifier(name, estimator, training=(np.array(u, float), y.copy()))
    if not np.all(np.isfinite(fitted.proba(u))):
        raise CandidateError(f"{name} predicts non-finite probabilities")
    return fitted


def refitted(scored: Any, refit: Callable[[], Any]) -> Any:
    """The model ``refit`` returns (a selected model fitted again with the hold-out), or
    the ``scored`` one if that fit fails."""
    try:
        return refit()
    except CandidateError:
        return scored
