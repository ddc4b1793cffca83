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

On the ordinary path (continuous inputs, no re-interpolation, no noise estimated: every
fit of the pipeline's) the evaluation and the gradient are SMT's own statements, without
its generic code around them (the path's checks on every call, the kernel called again
for the gradient, the correlation matrices filled by 2-D fancy indexing) and with
:mod:`ovtraj.surrogate.smt_linalg`'s LAPACK calls (the economic QR and the singular
values straight to LAPACK too): a benchmark pipeline's fits 1.12 -> 0.80-0.98 s on its two
processes (the direct method had become faster, so the surrogate pipeline's wall-time
ratio against it needed faster fits). The same operations give the same bits
(``tests/test_smt_likelihood.py``: every value and parameter of both, and whole fits,
equal to stock SMT's).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from scipy.linalg import LinAlgError
from smt.kernels.kernels import PowExp
from smt.surrogate_models.krg_based.likelihood_eval import LikelihoodEvaluator

from ovtraj.surrogate.smt_linalg import cholesky, qr, solve_triangular, svd

__all__ = ["RememberedLikelihood", "RememberedLikelihoodMixin"]


class RememberedLikelihood(LikelihoodEvaluator):
    """SMT's likelihood evaluator that answers a repeated ``theta`` from memory."""

    def __init__(self, model: Any) -> None:
        super().__init__(model)
        self.evaluations = 0  # computed
        self.remembered = 0  # answered from memory
        # The model's path (:func:`_ordinary`, a power-exponential kernel), asked once: the
        # checks walk SMT's design space on every call.
        self._ordinary: bool | None = None
        self._power_exponential: bool | None = None
        self.forget()

    def forget(self) -> None:
        """Drops the remembered evaluation (its arrays)."""
        self._last_key: tuple | None = None
        self._last: tuple[float, dict] | None = None
        # The last computed ordinary evaluation's correlations (the gradient's too) and the
        # flat positions of the correlation matrix's two triangles.
        self._correlations: np.ndarray | None = None
        self._triangles: tuple[tuple, np.ndarray, np.ndarray] | None = None

    def _paths(self) -> tuple[bool, bool]:
        if self._ordinary is None:
            m = self._model
            self._power_exponential = bool(m.is_continuous and type(m.corr) is PowExp)
            self._ordinary = _ordinary(m)
        return bool(self._ordinary), bool(self._power_exponential)

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Flat indices of the pairs ``m.ij`` and of their mirror in an (nt, nt) matrix."""
        m = self._model
        key = (id(m.ij), m.ij.shape, m.nt)
        if self._triangles is None or self._triangles[0] != key:
            i, j = m.ij[:, 0], m.ij[:, 1]
            self._triangles = (key, i * m.nt + j, j * m.nt + i)
        return self._triangles[1], self._triangles[2]

    def _key(self, theta: Any) -> tuple:
        m = self._model
        values = np.asarray(theta, dtype=float)
        # The training data the evaluation reads: the same arrays within one training.
        return (values.tobytes(), values.size, id(m.D), id(m.F), id(m.y_norma), m.nt)

    def evaluate(self, theta: Any) -> tuple[float, dict]:
        key = self._key(theta)
        if self._last is not None and key == self._last_key:
            m = self._model
            if self._paths()[1] or m.is_continuous:
                # What the evaluation sets on the kernel before computing (SMT's order).
                noise_theta = m._eval_noise and not m.options["use_het_noise"]
                m.corr.theta = theta[0:-1] if noise_theta else theta
            self.remembered += 1
            value, par = self._last
            return value, dict(par)
        value, par = (
            _ordinary_evaluation(self, theta) if self._paths()[0] else super().evaluate(theta)
        )
        self.evaluations += 1
        self._last_key, self._last = key, (value, dict(par))
        return value, par

    def gradient(self, theta: Any) -> tuple[Any, dict]:
        m = self._model
        kernel = m.corr
        ordinary, power_exponential = self._paths()
        if not power_exponential:
            return super().gradient(theta)
        if ordinary:
            return _ordinary_gradient(self, theta)
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


def _ordinary(m: Any) -> bool:
    """Whether an SMT model's likelihood takes the ordinary path: continuous inputs, no
    re-interpolation, no noise estimated."""
    return (
        m.is_continuous
        and not m.options["is_ri"]
        and not m._eval_noise
        and not m.options["use_het_noise"]
    )


def _ordinary_evaluation(evaluator: RememberedLikelihood, theta: Any) -> tuple[float, dict]:
    """SMT 2.15's ``LikelihoodEvaluator.evaluate`` on the ordinary path, statement by
    statement, with :mod:`ovtraj.surrogate.smt_linalg`'s LAPACK calls (those of the
    module SMT is given, without its generic code). The reduced likelihood (log10 form,
    Lophaven, Nielsen & Sondergaard, DACE, 2002) and the GLS parameters."""
    m = evaluator._model
    value = -np.inf
    par: dict = {}
    nugget, noise = m.options["nugget"], m.noise0
    m.corr.theta = theta
    evaluator._correlations = None
    try:
        r = m.corr(m.D).reshape(-1, 1)
        if np.isnan(r).any():
            return value, par
    except FloatingPointError:
        warnings.warn(
            "Theta upper bound is too high.  please reduced it in the parameter theta_bounds.",
            stacklevel=2,
        )
        return value, par
    evaluator._correlations = r
    upper, lower = evaluator.triangles()
    R = np.eye(m.nt) * (1.0 + nugget + noise)
    R.ravel()[upper] = r[:, 0]
    R.ravel()[lower] = r[:, 0]
    p, q = m._get_pq()
    try:
        C = cholesky(R, lower=True)
    except (LinAlgError, ValueError):  # not positive definite (SMT prints its eigenvalues)
        return value, par
    Ft = solve_triangular(C, m.F, lower=True)
    Q, G = qr(Ft, mode="economic")
    sv = svd(G, compute_uv=False)
    # SMT's own thresholds (likelihood_eval.py), kept as SMT has them: part of its method.
    if sv[-1] / sv[0] < 1e-10:
        sv = svd(m.F, compute_uv=False)
        if sv[0] / sv[-1] > 1e15:
            raise Exception(
                "F is too ill conditioned. Poor combination of regression model and observations."
            )
        return value, par
    Yt = solve_triangular(C, m.y_norma, lower=True)
    beta = solve_triangular(G, np.dot(Q.T, Yt))
    rho = Yt - np.dot(Ft, beta)
    detR = (np.diag(C) ** (2.0 / m.nt)).prod()
    sigma2 = (rho**2.0).sum(axis=0) / (m.nt - p - q)
    value = -(m.nt - p - q) * np.log10(sigma2.sum()) - m.nt * np.log10(detR)
    par["sigma2"] = sigma2 * m.y_std**2.0
    par["beta"] = beta
    par["gamma"] = solve_triangular(C.T, rho)
    par["C"] = C
    par["Ft"] = Ft
    par["G"] = G
    par["Q"] = Q
    value += m._reduced_log_prior(theta)
    evaluator._update_best_iteration(value, theta)
    if value > 1e15:
        value = 1e15
    return value, par


def _ordinary_gradient(evaluator: RememberedLikelihood, theta: Any) -> tuple[Any, dict]:
    """SMT 2.15's ``LikelihoodEvaluator.gradient`` on the ordinary path with a
    power-exponential kernel, statement by statement: the correlations once
    (:class:`_CorrelationOnce`'s expression for their derivatives), the triangular
    solves of :mod:`ovtraj.surrogate.smt_linalg`."""
    m = evaluator._model
    _, par = evaluator.evaluate(theta)
    try:
        C, gamma, Q, G = par["C"], par["gamma"], par["Q"], par["G"]
        sigma_2 = par["sigma2"] + m.options["nugget"]
    except KeyError:
        return 1, par
    nb_theta = len(theta)
    grad_red = np.zeros(nb_theta)
    # The correlations at theta: the evaluation's (the same kernel call), else computed.
    r = evaluator._correlations if evaluator._correlations is not None else m.corr(m.D)
    upper, lower = evaluator.triangles()
    dr_all, tr_all, dmu_all, arg_all, dsigma_all, dbeta_all = [], [], [], [], [], []
    for i_der in range(nb_theta):
        dr = np.zeros((m.D.shape[0], 1))
        dr[:, 0] = -m.D[:, i_der] * r[:, 0]
        dr_all.append(dr)
        dR = np.zeros((m.nt, m.nt))
        dR.ravel()[upper] = dr[:, 0]
        dR.ravel()[lower] = dr[:, 0]
        dR_gamma = np.dot(dR, gamma)
        Cinv_dR_gamma = solve_triangular(C, dR_gamma, lower=True)
        dbeta = -solve_triangular(G, np.dot(Q.T, Cinv_dR_gamma))
        arg_all.append(Cinv_dR_gamma)
        dbeta_all.append(dbeta)
        dmu = np.dot(m.F, dbeta)
        dmu_all.append(dmu)
        tr_1 = solve_triangular(C, dR, lower=True)
        tr = solve_triangular(C.T, tr_1)
        tr_all.append(tr)
        dsigma_2 = (
            (1 / m.nt)
            * (-dmu.T.dot(gamma) - gamma.T.dot(dmu) - np.dot(gamma.T, dR_gamma))
            * m.y_std**2.0
        )
        dsigma_all.append(dsigma_2)
        grad_red[i_der] = (-m.nt / np.log(10) * (dsigma_2 / sigma_2 + np.trace(tr) / m.nt)).item()
    par["dr"] = dr_all
    par["tr"] = tr_all
    par["dmu"] = dmu_all
    par["arg"] = arg_all
    par["dsigma"] = dsigma_all
    par["dbeta_all"] = dbeta_all
    grad_red = np.atleast_2d(grad_red).T
    grad_red += m._reduced_log_prior(theta, grad=True)
    return grad_red, par
