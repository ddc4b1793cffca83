"""SMT's Kriging likelihood evaluated once per point of its maximisation, not twice.

SMT 2.15 maximises the reduced likelihood of KRG and KPLS with scipy's TNC, which asks
for the objective and its gradient at each point separately; SMT's gradient
(``LikelihoodEvaluator.gradient``) starts by evaluating the likelihood again at that
point (the Cholesky factor, the GLS solution and ``sigma2`` it needs). Every point is
therefore factorised twice: on a benchmark pipeline's fits 20 294 evaluations for 10 075
gradients.

:class:`RememberedLikelihood` is SMT's evaluator that keeps its last evaluation: asked
again for the same ``theta`` (the same values, to the bit, whatever the array's shape:
TNC's gradient call passes the column ``(n, 1)`` of the row its objective call passed),
it returns that evaluation's value and a fresh copy of its parameter dictionary (the
gradient adds its derivatives to the copy, as it did to the fresh dictionary of a second
evaluation), after redoing the one thing an evaluation changes on the model besides its
result: the kernel's ``theta``. The best-value bookkeeping an evaluation also does
(``_update_best_iteration``) would not change on a second call with the same value.
The fits are the same to the bit (``tests/test_smt_likelihood.py``).

The gradient itself asks the power-exponential kernel for its derivative along each
hyperparameter, and SMT's kernel recomputes the correlations for every one; the
evaluator's gradient computes them once and forms each derivative from them with the
kernel's own expression (``-d[:, k] * r``): a 5-D KRG gradient on 20 samples 610 -> 502 us,
KPLS with 3 components 362 -> 318 us, the same values.

The models get it through :class:`RememberedLikelihoodMixin`: SMT builds a fresh evaluator
in every training (``_new_train``), and the mixin's ``_likelihood_evaluator`` turns it
into a remembering one; the memory is dropped when the training ends, so a stored model
holds none of it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from smt.kernels.kernels import PowExp
from smt.surrogate_models.krg_based.likelihood_eval import LikelihoodEvaluator

__all__ = ["RememberedLikelihood", "RememberedLikelihoodMixin"]


class RememberedLikelihood(LikelihoodEvaluator):
    """SMT's likelihood evaluator that answers a repeated ``theta`` from memory."""

    def __init__(self, model: Any) -> None:
        super().__init__(model)
        self.evaluations = 0  # computed
        self.remembered = 0  # answered from memory
        self.forget()

    def forget(self) -> None:
        """Drops the remembered evaluation (its arrays)."""
        self._last_key: tuple | None = None
        self._last: tuple[float, dict] | None = None

    def _key(self, theta: Any) -> tuple:
        m = self._model
        values = np.asarray(theta, dtype=float)
        # The training data the evaluation reads: the same arrays within one training.
        return (values.tobytes(), values.size, id(m.D), id(m.F), id(m.y_norma), m.nt)

    def evaluate(self, theta: Any) -> tuple[float, dict]:
        key = self._key(theta)
        if self._last is not None and key == self._last_key:
            m = self._model
            if m.is_continuous:
                # What the evaluation sets on the kernel before computing (SMT's order).
                noise_theta = m._eval_noise and not m.options["use_het_noise"]
                m.corr.theta = theta[0:-1] if noise_theta else theta
            self.remembered += 1
            value, par = self._last
            return value, dict(par)
        value, par = super().evaluate(theta)
        self.evaluations += 1
        self._last_key, self._last = key, (value, dict(par))
        return value, par

    def gradient(self, theta: Any) -> tuple[Any, dict]:
        m = self._model
        kernel = m.corr
        if not (m.is_continuous and type(kernel) is PowExp):
            return super().gradient(theta)
        m.corr = _CorrelationOnce(kernel)
        try:
            return super().gradient(theta)
        finally:
            m.corr = kernel


class _CorrelationOnce:
    """SMT's power-exponential kernel for one gradient: asked for the correlations'
    derivative along each hyperparameter, it computes the correlations ``r`` once and
    returns ``-d[:, k] * r`` for each ``k`` (SMT's own expression, which recomputed ``r``
    for every one); anything else is the kernel's."""

    def __init__(self, kernel: PowExp) -> None:
        self._kernel = kernel
        self._key: tuple | None = None
        self._r: np.ndarray | None = None

    @property
    def theta(self) -> np.ndarray:
        return self._kernel.theta

    @theta.setter
    def theta(self, theta: Any) -> None:
        self._kernel.theta = theta

    def __call__(
        self,
        d: np.ndarray,
        grad_ind: Any = None,
        hess_ind: Any = None,
        derivative_params: Any = None,
    ) -> Any:
        if grad_ind is None or hess_ind is not None or derivative_params is not None:
            return self._kernel(d, grad_ind, hess_ind, derivative_params)
        key = (id(d), d.shape, self._kernel.theta.tobytes())
        if key != self._key:
            self._key, self._r = key, self._kernel(d)
        r = np.zeros((d.shape[0], 1))
        r[:, 0] = -d[:, grad_ind] * self._r[:, 0]
        return r


class RememberedLikelihoodMixin:
    """Mixed into an SMT Kriging model (before it): its trainings evaluate the likelihood
    through :class:`RememberedLikelihood`."""

    @property
    def _likelihood_evaluator(self) -> LikelihoodEvaluator | None:
        return self.__dict__.get("_likelihood_evaluator")

    @_likelihood_evaluator.setter
    def _likelihood_evaluator(self, evaluator: LikelihoodEvaluator | None) -> None:
        if type(evaluator) is LikelihoodEvaluator:
            evaluator = RememberedLikelihood(evaluator._model)
        self.__dict__["_likelihood_evaluator"] = evaluator

    def _new_train(self) -> None:
        try:
            super()._new_train()
        finally:
            evaluator = self._likelihood_evaluator
            if isinstance(evaluator, RememberedLikelihood):
                evaluator.forget()
