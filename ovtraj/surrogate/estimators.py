"""The model classes the candidates build: SMT's Kriging with this package's options and
speed-ups, and scikit-learn tree ensembles behind the part of SMT's interface used here.

SMT's speed-ups (:mod:`ovtraj.surrogate.smt_linalg`, :mod:`ovtraj.surrogate.smt_differences`)
replace functions inside SMT's Kriging modules: the same fits and predictions to the bit,
~40 % less time (see those modules). They are installed by the Kriging models themselves,
when one is built or unpickled (a pool's process receives fitted models), not when a
module is imported: importing ``ovtraj`` changes nothing in SMT, and every process that
holds one of these models has them (installing is idempotent).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from smt.surrogate_models import KPLS, KRG
from smt.surrogate_models.krg_based.hyperparam_optim import TNCOptimizer

from ovtraj.parallel import openmp_threads
from ovtraj.surrogate import smt_differences, smt_linalg
from ovtraj.surrogate.smt_likelihood import RememberedLikelihoodMixin

__all__ = ["KPLSModel", "KRGModel", "TreeEnsemble", "install_smt_speedups"]


def install_smt_speedups() -> None:
    """SMT's Kriging likelihood without scipy's finite-value scan on each factorisation,
    and its predictions without scikit-learn's checks of their inputs (idempotent)."""
    smt_linalg.install()
    smt_differences.install()


class _WithoutRandomStart(TNCOptimizer):
    """SMT's TNC from its starts but the second, the seeded random one SMT always adds to
    theta0 (``kriging_random_start: false``)."""

    def optimize(self, objective: Any, theta_starts: np.ndarray, **kwargs: Any) -> Any:
        return super().optimize(objective, np.delete(theta_starts, 1, axis=0), **kwargs)


class _KrigingOptions:
    """Mixed into SMT's KRG and KPLS: the speed-ups installed (module notes), and SMT's
    likelihood optimiser with or without its random start (SMT's documented extension
    point, ``_create_optimizer``)."""

    def __init__(self, *, random_start: bool = True, **options: Any) -> None:
        install_smt_speedups()
        super().__init__(**options)
        self.random_start = random_start

    def __setstate__(self, state: dict[str, Any]) -> None:
        install_smt_speedups()
        self.__dict__.update(state)

    def _create_optimizer(self) -> Any:
        return super()._create_optimizer() if self.random_start else _WithoutRandomStart()


class KRGModel(_KrigingOptions, RememberedLikelihoodMixin, KRG):
    """SMT's KRG, its random start optional, each likelihood point evaluated once."""


class KPLSModel(_KrigingOptions, RememberedLikelihoodMixin, KPLS):
    """SMT's KPLS, its random start optional, each likelihood point evaluated once."""


class TreeEnsemble:
    """A scikit-learn tree ensemble behind the part of SMT's interface used here, on one
    OpenMP thread (the fits run side by side in the pool's processes)."""

    def __init__(self, estimator: Any) -> None:
        self.estimator = estimator
        self.training: tuple[np.ndarray, np.ndarray] | None = None

    def set_training_values(self, u: np.ndarray, y: np.ndarray) -> None:
        self.training = (np.asarray(u, dtype=float), np.asarray(y, dtype=float).reshape(-1))

    def train(self) -> None:
        u, y = self.training
        with openmp_threads(1):
            self.estimator.fit(u, y)

    def predict_values(self, u: np.ndarray) -> np.ndarray:
        with openmp_threads(1):
            return self.estimator.predict(np.asarray(u, dtype=float))[:, None]
