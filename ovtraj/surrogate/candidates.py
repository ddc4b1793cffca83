"""The candidate models: SMT regressors and scikit-learn feasibility classifiers.

Regressors (SMT 2.15, https://smt.readthedocs.io, "Surrogate models"):

- ``KRG``: ordinary Kriging (constant trend, squared-exponential correlation), hyper-
  parameters by maximum likelihood with SMT's TNC optimiser, ``n_start`` =
  ``kriging_starts`` multistarts, seeded with ``seed`` (SMT 2.15's option; it replaced the
  older ``random_state``).
- ``KPLS``: Kriging with partial-least-squares reduced length scales (Bouhlel et al. 2016),
  ``n_comp`` = ``kpls_components`` capped at the number of inputs; seeded like KRG.
- ``RBF``: Gaussian radial basis function interpolation, basis scale ``d0`` = ``rbf_d0`` on
  unit-cube inputs.
- ``QP``: full quadratic polynomial by least squares; needs (d + 1)(d + 2) / 2 samples.
- ``ET``: extremely randomised trees (Geurts, Ernst & Wehenkel 2006; scikit-learn's
  ``ExtraTreesRegressor``, ``extra_trees`` trees, seeded): piecewise constant, so it can
  follow the mission's steps (T_total moves by whole days when the deorbit waits for the
  next pass) that the smooth SMT models blur. Not SMT: wrapped in SMT's interface.

Classifiers (scikit-learn), for the probability that a design is feasible:

- ``svc``: RBF-kernel SVC with Platt (sigmoid) scaling of its decision function, built as
  ``CalibratedClassifierCV(SVC(random_state=seed), method="sigmoid", ensemble=False)`` -
  scikit-learn 1.9 deprecated ``SVC(probability=True)`` in favour of exactly this, and the
  internal calibration folds are a seeded stratified k-fold here.
- ``gpc``: ``GaussianProcessClassifier(kernel, random_state=seed)`` (Laplace approximation)
  with ``kernel = ConstantKernel(a) * RBF(gpc_length_scale)``, both hyperparameters fitted
  within ``gpc_amplitude_bounds`` / ``gpc_length_scale_bounds`` (a = the amplitude's lower
  bound). scikit-learn's default kernel keeps 1.0 * RBF(1.0) *fixed*, which on unit-cube
  inputs is far too smooth (mean accuracy ~0.70 against 0.91 on ball-shaped regions).
- ``logistic``: ``LogisticRegression`` (L2-regularised, lbfgs).

A training set that holds a single class (a CV fold without any infeasible sample, or all
samples feasible) gets a constant classifier instead: probability 1 (or 0) everywhere.

Any failure while fitting a candidate is raised as :class:`CandidateError`; the caller
records its text and moves on to the next candidate.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn.base import ClassifierMixin
from sklearn.calibration import CalibratedClassifierCV
from sklearn.ensemble import ExtraTreesRegressor, HistGradientBoostingRegressor
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessClassifier
from sklearn.gaussian_process.kernels import RBF as RBFKernel
from sklearn.gaussian_process.kernels import ConstantKernel
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import StratifiedKFold
from sklearn.svm import SVC
from smt.surrogate_models import KPLS, KRG, QP, RBF
from smt.surrogate_models.krg_based.hyperparam_optim import TNCOptimizer
from smt.surrogate_models.surrogate_model import SurrogateModel

from ovtraj.config.mission import SurrogateSettings
from ovtraj.parallel import openmp_threads
from ovtraj.surrogate import smt_differences, smt_linalg
from ovtraj.surrogate.smt_likelihood import RememberedLikelihoodMixin

__all__ = [
    "ALL_FEASIBLE",
    "CandidateError",
    "FeasibilityClassifier",
    "Regressor",
    "fit_classifier",
    "fit_regressor",
    "min_regressor_samples",
    "new_regressor",
    "seeded_subsample",
]

ALL_FEASIBLE = "all-feasible"
# The candidates with Kriging hyperparameters (``optimal_theta``).
KRIGING = ("KRG", "KPLS")
# The candidates whose fit grows as n^2-n^3: subsampled on large training sets.
SUBSAMPLED = ("KRG", "KPLS", "RBF", "svc", "gpc")

# SMT's Kriging likelihood without scipy's finite-value scan on each factorisation (the
# same fits, ~40 % less time; see the module).
smt_linalg.install()
# and its predictions without scikit-learn's checks of their inputs (the same values).
smt_differences.install()


class CandidateError(RuntimeError):
    """A candidate model that could not be fitted or predicts non-finite values."""


def min_regressor_samples(name: str, dim: int) -> int:
    """The fewest training samples a regressor can be fitted on."""
    if name == "QP":
        # A full quadratic in d inputs has (d + 1)(d + 2) / 2 coefficients.
        return (dim + 1) * (dim + 2) // 2
    return 2


class _WithoutRandomStart(TNCOptimizer):
    """SMT's TNC from its starts but the second, the seeded random one SMT always adds to
    theta0 (``kriging_random_start: false``)."""

    def optimize(self, objective: Any, theta_starts: np.ndarray, **kwargs: Any) -> Any:
        return super().optimize(objective, np.delete(theta_starts, 1, axis=0), **kwargs)


class _RandomStartChoice:
    """SMT's likelihood optimiser with or without its random start (SMT's documented
    extension point, ``_create_optimizer``); mixed into KRG and KPLS."""

    def __init__(self, *, random_start: bool = True, **options: Any) -> None:
        super().__init__(**options)
        self.random_start = random_start

    def _create_optimizer(self) -> Any:
        return super()._create_optimizer() if self.random_start else _WithoutRandomStart()


class _KRG(_RandomStartChoice, RememberedLikelihoodMixin, KRG):
    """SMT's KRG, its random start optional, each likelihood point evaluated once."""


class _KPLS(_RandomStartChoice, RememberedLikelihoodMixin, KPLS):
    """SMT's KPLS, its random start optional, each likelihood point evaluated once."""


def new_regressor(
    name: str, dim: int, settings: SurrogateSettings, start: np.ndarray | None = None
) -> SurrogateModel | Any:
    """The unfitted candidate ``name`` for ``dim`` inputs, with its configured options."""
    common: dict[str, Any] = {"print_global": False}
    kriging = {
        "n_start": settings.kriging_starts,
        "seed": settings.seed,
        "random_start": settings.kriging_random_start,
        **common,
    }
    if start is not None and name in KRIGING:
        # A known good start (the whole training part's optimum): from it alone.
        kriging.update(theta0=np.asarray(start, dtype=float).tolist(), random_start=False)
    if name == "KRG":
        return _KRG(**kriging)
    if name == "KPLS":
        return _KPLS(n_comp=min(settings.kpls_components, dim), **kriging)
    if name == "RBF":
        return RBF(d0=settings.rbf_d0, **common)
    if name == "QP":
        return QP(**common)
    if name == "ET":
        return _Trees(
            ExtraTreesRegressor(settings.extra_trees, random_state=settings.seed, n_jobs=1)
        )
    if name == "GBT":
        large = settings.large_samples
        if large is None:
            raise CandidateError("GBT needs the surrogate's large_samples settings")
        return _Trees(
            HistGradientBoostingRegressor(
                max_iter=large.gbt_iterations,
                learning_rate=large.gbt_learning_rate,
                max_leaf_nodes=large.gbt_leaf_nodes,
                min_samples_leaf=large.gbt_min_samples_leaf,
                early_stopping=False,
                random_state=settings.seed,
            )
        )
    raise CandidateError(f"unknown regressor {name!r} (allowed: KRG, KPLS, RBF, QP, ET, GBT)")


class _Trees:
    """A scikit-learn tree ensemble behind the part of SMT's interface used here, on one
    OpenMP thread (the fits run side by side in the pool's processes)."""

    def __init__(self, estimator: Any) -> None:
        self.estimator = estimator
        self._training: tuple[np.ndarray, np.ndarray] | None = None

    def set_training_values(self, u: np.ndarray, y: np.ndarray) -> None:
        self._training = (np.asarray(u, dtype=float), np.asarray(y, dtype=float).reshape(-1))

    def train(self) -> None:
        u, y = self._training
        with openmp_threads(1):
            self.estimator.fit(u, y)

    def predict_values(self, u: np.ndarray) -> np.ndarray:
        with openmp_threads(1):
            return self.estimator.predict(np.asarray(u, dtype=float))[:, None]


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


def _subsampled(name: str, n: int, settings: SurrogateSettings, classes: Any = None) -> Any:
    """The rows candidate ``name`` is fitted on (``slice(None)``: every one)."""
    large = settings.large_samples
    if large is None or name not in SUBSAMPLED or n <= large.exact_max_samples:
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
        if isinstance(self.model, _Trees):
            u, y = self.model._training
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
    n, dim = u.shape
    need = min_regressor_samples(name, dim)
    if n < need:
        raise CandidateError(f"{name} needs at least {need} training samples in {dim}-D, got {n}")
    model = new_regressor(name, dim, settings, start)
    rows = _subsampled(name, n, settings)
    u_fit, y_fit = np.asarray(u, dtype=float)[rows], np.asarray(y, dtype=float)[rows]
    try:
        model.set_training_values(np.ascontiguousarray(u_fit), y_fit)
        model.train()
    except Exception as err:  # SMT raises bare Exceptions, LinAlgErrors, ValueErrors ...
        raise CandidateError(f"{name} training failed: {type(err).__name__}: {err}") from err
    regressor = Regressor(name, model)
    check = regressor.predict(u_fit)
    if not np.all(np.isfinite(check)):
        raise CandidateError(f"{name} predicts non-finite values at its training samples")
    return regressor


def _classifier(
    name: str,
    y: np.ndarray,
    settings: SurrogateSettings,
    fitted_kernel: tuple[float, float | list[float]] | None = None,
) -> ClassifierMixin:
    if name == "svc":
        minority = int(min(np.count_nonzero(y), np.count_nonzero(~y)))
        if minority < 2:
            raise CandidateError(
                "svc: the Platt calibration needs at least 2 samples of each class, "
                f"the smaller class has {minority}"
            )
        folds = StratifiedKFold(
            n_splits=min(settings.folds, minority), shuffle=True, random_state=settings.seed
        )
        return CalibratedClassifierCV(
            SVC(random_state=settings.seed), method="sigmoid", cv=folds, ensemble=False
        )
    if name == "gpc":
        # scikit-learn's default kernel for GPC is 1.0 * RBF(1.0) with *fixed* hyperparameters;
        # an explicit kernel makes the length scale and amplitude maximum-likelihood fits.
        amplitude = settings.gpc_amplitude_bounds
        length = settings.gpc_length_scale_bounds
        start = (amplitude.lower, settings.gpc_length_scale)
        constant, scale = start if fitted_kernel is None else fitted_kernel
        kernel = ConstantKernel(
            constant, constant_value_bounds=(amplitude.lower, amplitude.upper)
        ) * RBFKernel(scale, length_scale_bounds=(length.lower, length.upper))
        # A fitted kernel is used as is: the fit's last step, the Laplace approximation
        # with the maximum-likelihood hyperparameters, again.
        optimizer = "fmin_l_bfgs_b" if fitted_kernel is None else None
        return GaussianProcessClassifier(
            kernel=kernel, optimizer=optimizer, random_state=settings.seed
        )
    if name == "logistic":
        return LogisticRegression()
    raise CandidateError(f"unknown classifier {name!r} (allowed: svc, gpc, logistic)")


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


def fit_classifier(
    name: str,
    u: np.ndarray,
    y: np.ndarray,
    settings: SurrogateSettings,
    fitted_kernel: tuple[float, float | list[float]] | None = None,
) -> FeasibilityClassifier:
    """Fit the scikit-learn candidate ``name`` on ``u`` (n, d) and feasibility ``y`` (n,) bool.

    ``fitted_kernel``: gpc's (amplitude, length scale) from an earlier fit, kept fixed.
    """
    y = np.asarray(y, dtype=bool)
    if y.size == 0:
        raise CandidateError(f"{name}: no training samples")
    if y.all() or not y.any():
        return FeasibilityClassifier(name, None, 1.0 if y.all() else 0.0)
    rows = _subsampled(name, y.size, settings, classes=y)
    u, y = np.asarray(u, dtype=float)[rows], y[rows]
    estimator = _classifier(name, y, settings, fitted_kernel)
    try:
        with warnings.catch_warnings():
            # The classifiers' optimisers may stop at their iteration limit on tiny sets;
            # the fit is still usable and CV judges it.
            warnings.simplefilter("ignore", category=ConvergenceWarning)
            estimator.fit(u, y)
    except Exception as err:
        raise CandidateError(f"{name} training failed: {type(err).__name__}: {err}") from err
    classifier = FeasibilityClassifier(name, estimator, training=(np.array(u, float), y.copy()))
    if not np.all(np.isfinite(classifier.proba(u))):
        raise CandidateError(f"{name} predicts non-finite probabilities")
    return classifier
