"""The candidate models, each declared once: SMT regressors and scikit-learn feasibility
classifiers.

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

Each candidate is a :class:`Candidate` of :data:`REGRESSORS` or :data:`CLASSIFIERS`: its
name, what builds it from the settings, and what the fit and the store need to know of it
(subsampled on many samples, Kriging hyperparameters, the fitted state and hyperparameters
stored as data, the fewest samples it takes). The config accepts the same names
(:mod:`ovtraj.config.surrogate_candidates`, which the config layer can import); the fit
(:mod:`ovtraj.surrogate.fitted_models`) and the stored form
(:mod:`ovtraj.surrogate.model_data`) read everything else from here.

Any failure while building or fitting a candidate is raised as :class:`CandidateError`;
the caller records its text and moves on to the next candidate.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from sklearn.calibration import CalibratedClassifierCV
from sklearn.ensemble import ExtraTreesRegressor, HistGradientBoostingRegressor
from sklearn.gaussian_process import GaussianProcessClassifier
from sklearn.gaussian_process.kernels import RBF as RBFKernel
from sklearn.gaussian_process.kernels import ConstantKernel
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import StratifiedKFold
from sklearn.svm import SVC
from smt.surrogate_models import QP, RBF

from ovtraj.config.mission import SurrogateSettings
from ovtraj.surrogate.estimators import KPLSModel, KRGModel, TreeEnsemble

__all__ = [
    "ALL_FEASIBLE",
    "CLASSIFIERS",
    "KRIGING_PAR",
    "REGRESSORS",
    "Candidate",
    "CandidateError",
    "classifier",
    "regressor",
]

# The constant classifier of a training set without any infeasible sample (not configurable).
ALL_FEASIBLE = "all-feasible"
# SMT's fitted Kriging state that its predictions read (SMT 2.15, krg_based.py
# ``_predict_values``; KPLS's ``_componentwise_distance`` reads ``coeff_pls``): attributes
# of the model, then the GLS solution, kept in its ``optimal_par``.
_KRIGING_STATE = ("X_offset", "X_scale", "y_mean", "y_std", "optimal_theta")
KRIGING_PAR = ("beta", "gamma")


class CandidateError(RuntimeError):
    """A candidate model that could not be fitted or predicts non-finite values."""


def _two(dim: int) -> int:
    return 2


@dataclass(frozen=True)
class Candidate:
    """One candidate model.

    ``build``: the unfitted model from the settings; a regressor's from ``(dim, settings,
    start)`` (``start``: Kriging hyperparameters to maximise the likelihood from, alone;
    ignored by the others), a classifier's from ``(y, settings, hyper)`` (``hyper``: its
    fitted hyperparameters from an earlier fit, kept fixed).
    """

    name: str
    kind: Literal["regressor", "classifier"]
    build: Callable[..., Any]
    # Its cost grows as n^2-n^3: fitted on a seeded subsample past
    # ``large_samples.exact_max_samples`` training samples.
    subsampled: bool = False
    # SMT Kriging: fitted hyperparameters ``optimal_theta`` (a CV fold's warm start) and a
    # fitted state its predictions read, stored and set back on load.
    kriging: bool = False
    # The fitted arrays stored besides the training data (model_data), in stored order.
    state: tuple[str, ...] = ()
    # The fitted hyperparameters stored as JSON numbers, read by ``hyper_of`` from the
    # fitted estimator and given back to ``build``.
    hyper: tuple[str, ...] = ()
    hyper_of: Callable[[Any], dict[str, float | list[float]]] | None = None
    # The fewest training samples it can be fitted on in ``dim`` inputs.
    min_samples: Callable[[int], int] = _two


# -- regressors ----------------------------------------------------------------------------


def _kriging_options(settings: SurrogateSettings, start: np.ndarray | None) -> dict[str, Any]:
    options: dict[str, Any] = {
        "n_start": settings.kriging_starts,
        "seed": settings.seed,
        "random_start": settings.kriging_random_start,
        "print_global": False,
    }
    if start is not None:
        # A known good start (the whole training part's optimum): from it alone.
        options.update(theta0=np.asarray(start, dtype=float).tolist(), random_start=False)
    return options


def _krg(dim: int, settings: SurrogateSettings, start: np.ndarray | None) -> KRGModel:
    return KRGModel(**_kriging_options(settings, start))


def _kpls(dim: int, settings: SurrogateSettings, start: np.ndarray | None) -> KPLSModel:
    return KPLSModel(n_comp=min(settings.kpls_components, dim), **_kriging_options(settings, start))


def _rbf(dim: int, settings: SurrogateSettings, start: np.ndarray | None) -> Any:
    return RBF(d0=settings.rbf_d0, print_global=False)


def _qp(dim: int, settings: SurrogateSettings, start: np.ndarray | None) -> Any:
    return QP(print_global=False)


def _quadratic_terms(dim: int) -> int:
    """A full quadratic in ``dim`` inputs has (d + 1)(d + 2) / 2 coefficients."""
    return (dim + 1) * (dim + 2) // 2


def _et(dim: int, settings: SurrogateSettings, start: np.ndarray | None) -> TreeEnsemble:
    return TreeEnsemble(
        ExtraTreesRegressor(settings.extra_trees, random_state=settings.seed, n_jobs=1)
    )


def _gbt(dim: int, settings: SurrogateSettings, start: np.ndarray | None) -> TreeEnsemble:
    large = settings.large_samples
    if large is None:
        raise CandidateError("GBT needs the surrogate's large_samples settings")
    return TreeEnsemble(
        HistGradientBoostingRegressor(
            max_iter=large.gbt_iterations,
            learning_rate=large.gbt_learning_rate,
            max_leaf_nodes=large.gbt_leaf_nodes,
            min_samples_leaf=large.gbt_min_samples_leaf,
            early_stopping=False,
            random_state=settings.seed,
        )
    )


# -- classifiers ---------------------------------------------------------------------------


def _svc(y: np.ndarray, settings: SurrogateSettings, hyper: Mapping | None) -> Any:
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


def _gpc(y: np.ndarray, settings: SurrogateSettings, hyper: Mapping | None) -> Any:
    # scikit-learn's default kernel for GPC is 1.0 * RBF(1.0) with *fixed* hyperparameters;
    # an explicit kernel makes the length scale and amplitude maximum-likelihood fits.
    amplitude = settings.gpc_amplitude_bounds
    length = settings.gpc_length_scale_bounds
    if hyper is None:
        constant, scale = amplitude.lower, settings.gpc_length_scale
    else:
        constant, scale = hyper["constant_value"], hyper["length_scale"]
    kernel = ConstantKernel(
        constant, constant_value_bounds=(amplitude.lower, amplitude.upper)
    ) * RBFKernel(scale, length_scale_bounds=(length.lower, length.upper))
    # A fitted kernel is used as is: the fit's last step, the Laplace approximation with
    # the maximum-likelihood hyperparameters, again.
    optimizer = "fmin_l_bfgs_b" if hyper is None else None
    return GaussianProcessClassifier(kernel=kernel, optimizer=optimizer, random_state=settings.seed)


def _gpc_kernel(estimator: Any) -> dict[str, float | list[float]]:
    kernel = estimator.kernel_
    return {
        "constant_value": float(kernel.k1.constant_value),
        "length_scale": np.asarray(kernel.k2.length_scale, dtype=float).tolist(),
    }


def _logistic(y: np.ndarray, settings: SurrogateSettings, hyper: Mapping | None) -> Any:
    return LogisticRegression()


# -- the registry --------------------------------------------------------------------------

REGRESSORS: dict[str, Candidate] = {
    c.name: c
    for c in (
        Candidate(
            "KRG",
            "regressor",
            _krg,
            subsampled=True,
            kriging=True,
            state=(*_KRIGING_STATE, *KRIGING_PAR),
        ),
        Candidate(
            "KPLS",
            "regressor",
            _kpls,
            subsampled=True,
            kriging=True,
            state=(*_KRIGING_STATE, *KRIGING_PAR, "coeff_pls"),
        ),
        Candidate("RBF", "regressor", _rbf, subsampled=True),
        Candidate("QP", "regressor", _qp, min_samples=_quadratic_terms),
        Candidate("ET", "regressor", _et),
        Candidate("GBT", "regressor", _gbt),
    )
}
"""The regressor candidates, in the config's order
(:data:`~ovtraj.config.surrogate_candidates.REGRESSOR_NAMES`)."""

CLASSIFIERS: dict[str, Candidate] = {
    c.name: c
    for c in (
        Candidate("svc", "classifier", _svc, subsampled=True),
        Candidate(
            "gpc",
            "classifier",
            _gpc,
            subsampled=True,
            hyper=("constant_value", "length_scale"),
            hyper_of=_gpc_kernel,
        ),
        Candidate("logistic", "classifier", _logistic),
    )
}
"""The classifier candidates, in the config's order
(:data:`~ovtraj.config.surrogate_candidates.CLASSIFIER_NAMES`)."""


def regressor(name: str) -> Candidate:
    """The regressor candidate ``name``; CandidateError naming the allowed ones otherwise."""
    if name not in REGRESSORS:
        raise CandidateError(f"unknown regressor {name!r} (allowed: {', '.join(REGRESSORS)})")
    return REGRESSORS[name]


def classifier(name: str) -> Candidate:
    """The classifier candidate ``name``; CandidateError naming the allowed ones otherwise."""
    if name not in CLASSIFIERS:
        raise CandidateError(f"unknown classifier {name!r} (allowed: {', '.join(CLASSIFIERS)})")
    return CLASSIFIERS[name]
