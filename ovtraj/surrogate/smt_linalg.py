"""SMT's Kriging likelihood without scipy's validation layers on every factorisation.

SMT 2.15 fits KRG and KPLS by maximising the reduced likelihood with TNC; every
evaluation of the likelihood and its gradient makes ~25 calls of ``scipy.linalg``'s
``solve_triangular``, ``cholesky``, ``qr`` and ``svd`` on n x n matrices (n ~ 10-60
training samples). On matrices this small scipy's layers around LAPACK (the scan for
inf and NaN, ``check_finite``; array validation; the batching decorator) cost more than
the factorisation itself. Without them, the same fits to the bit (the layers only read
the inputs; the LAPACK calls are scipy's own, with its arguments):

* a KRG fit on 40 samples in 3-D, interleaved in one process: 141.5 -> 92.5 ms median;
* the three fit steps of a benchmark pipeline (``benchmarks/surrogate_vs_direct.py``,
  seed 2027), serial: 9.53 -> 6.20 s; on the pipeline's 2 worker processes, fits
  4.5-5.2 -> 3.4-4.2 s per pipeline, the hypervolumes unchanged (docs/optimize.md).

The scan cannot find anything here: :func:`ovtraj.surrogate.fitting.fit_surrogates` refuses
non-finite inputs and feasible outputs before any fit, the correlations are
``exp(-sum theta d^2)`` in [0, 1] with ``theta`` inside SMT's bounds, and a fit whose
predictions at its own samples are not finite is refused
(:func:`ovtraj.surrogate.fitted_models.fit_regressor`).

:func:`install` gives SMT's two Kriging modules a ``linalg`` namespace equal to
``scipy.linalg`` except for those four functions, straight to the LAPACK routines scipy
calls, with its arguments: ``solve_triangular`` and ``cholesky`` (``dtrtrs``, ``dpotrf``),
the economic ``qr`` (``dgeqrf``, ``dorgqr``) and the singular values of ``svd``
(``dgesdd``); float64 matrices of those shapes, anything else to scipy's functions
without the scan (the last two save ~5-10 us a call each). It changes nothing else; the
Kriging models call it when one is built or unpickled (:mod:`ovtraj.surrogate.estimators`,
in the pipeline's worker processes too), never an import.
"""

from __future__ import annotations

import functools
import types
from importlib import import_module

import numpy as np
import scipy.linalg
from scipy.linalg import LinAlgError
from scipy.linalg.lapack import dgeqrf, dgesdd, dgesdd_lwork, dorgqr, dpotrf, dtrtrs

# SMT's modules that call ``linalg.<function>`` from ``from scipy import linalg``.
SMT_MODULES = (
    "smt.surrogate_models.krg_based.likelihood_eval",
    "smt.surrogate_models.krg_based.krg_based",
)
UNCHECKED = ("solve_triangular", "cholesky", "qr", "svd")


def solve_triangular(
    a: np.ndarray,
    b: np.ndarray,
    trans: int | str = 0,
    lower: bool = False,
    unit_diagonal: bool = False,
    overwrite_b: bool = False,
    check_finite: bool = False,
) -> np.ndarray:
    """``scipy.linalg.solve_triangular`` of a float64 (n, n) matrix and (n,) or (n, k)
    right-hand side, straight to LAPACK's ``dtrtrs`` with the arguments scipy passes it
    (the same solution, without scipy's validation and batching layers); any other input
    goes to scipy's function."""
    a1, b1 = np.asarray(a), np.asarray(b)
    trans = {"N": 0, "T": 1}.get(trans, trans) if isinstance(trans, str) else trans
    if not (
        a1.dtype == np.float64
        and b1.dtype == np.float64
        and a1.ndim == 2
        and b1.ndim in (1, 2)
        and a1.shape[0] == a1.shape[1] == b1.shape[0]
        and b1.size
        and trans in (0, 1)
    ):
        return _UNCHECKED_SCIPY["solve_triangular"](
            a, b, trans=trans, lower=lower, unit_diagonal=unit_diagonal, overwrite_b=overwrite_b
        )
    if a1.flags.f_contiguous:
        x, info = dtrtrs(a1, b1, lower=lower, trans=trans, unitdiag=unit_diagonal)
    else:  # the transposed system, as scipy does: trtrs expects Fortran order
        x, info = dtrtrs(a1.T, b1, lower=not lower, trans=not trans, unitdiag=unit_diagonal)
    if info > 0:
        raise LinAlgError(f"singular matrix: resolution failed at diagonal {info - 1}")
    if info < 0:
        raise ValueError(f"illegal value in {-info}-th argument of internal trtrs")
    return x


def cholesky(
    a: np.ndarray, lower: bool = False, overwrite_a: bool = False, check_finite: bool = False
) -> np.ndarray:
    """``scipy.linalg.cholesky`` of a float64 (n, n) matrix, straight to LAPACK's ``dpotrf``
    as scipy calls it (``clean=True``); any other input goes to scipy's function."""
    a1 = np.asarray(a)
    if not (a1.dtype == np.float64 and a1.ndim == 2 and a1.shape[0] == a1.shape[1] and a1.size):
        return _UNCHECKED_SCIPY["cholesky"](a, lower=lower, overwrite_a=overwrite_a)
    c, info = dpotrf(a1, lower=lower, clean=True)
    if info > 0:
        raise LinAlgError(f"{info}-th leading minor of the array is not positive definite")
    if info < 0:
        raise ValueError(
            f'LAPACK reported an illegal value in {-info}-th argument on entry to "POTRF".'
        )
    return c


def qr(a: np.ndarray, mode: str = "full", **options: object) -> tuple[np.ndarray, ...]:
    """``scipy.linalg.qr`` of a tall float64 matrix in ``mode="economic"``, straight to
    LAPACK's ``dgeqrf`` and ``dorgqr`` with the workspaces scipy queries (the same Q and
    R); any other input or option goes to scipy's function (without the scan)."""
    a1 = np.asarray(a)
    if options or mode != "economic" or not _tall_float64(a1):
        return _UNCHECKED_SCIPY["qr"](a, mode=mode, **options)
    columns = a1.shape[1]
    qr_, tau, _, info = dgeqrf(a1, lwork=int(dgeqrf(a1, lwork=-1)[-2][0]))
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal geqrf")
    r = np.triu(qr_[:columns, :])
    q, _, info = dorgqr(qr_, tau, lwork=int(dorgqr(qr_, tau, lwork=-1)[-2][0]), overwrite_a=1)
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal gorgqr/gungqr")
    return q, r


def svd(a: np.ndarray, compute_uv: bool = True, **options: object) -> object:
    """``scipy.linalg.svd(a, compute_uv=False)`` of a float64 matrix, straight to LAPACK's
    ``dgesdd`` with scipy's workspace (the same singular values); anything else goes to
    scipy's function (without the scan)."""
    a1 = np.asarray(a)
    if options or compute_uv or not _tall_float64(a1):
        return _UNCHECKED_SCIPY["svd"](a, compute_uv=compute_uv, **options)
    lwork, _ = dgesdd_lwork(a1.shape[0], a1.shape[1], compute_uv=0, full_matrices=0)
    _, s, _, info = dgesdd(a1, compute_uv=0, full_matrices=0, lwork=int(np.ceil(lwork)))
    if info > 0:
        raise LinAlgError("SVD did not converge")
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal gesdd")
    return s


def _tall_float64(a: np.ndarray) -> bool:
    return a.dtype == np.float64 and a.ndim == 2 and a.shape[0] >= a.shape[1] > 0


_UNCHECKED_SCIPY = {
    name: functools.partial(getattr(scipy.linalg, name), check_finite=False) for name in UNCHECKED
}


def unchecked_linalg() -> types.SimpleNamespace:
    """``scipy.linalg``'s public names; :data:`UNCHECKED` without the finite-value scan,
    the triangular solve and the Cholesky factorisation straight to LAPACK."""
    names = {name: getattr(scipy.linalg, name) for name in scipy.linalg.__all__}
    names.update(_UNCHECKED_SCIPY)
    names.update(solve_triangular=solve_triangular, cholesky=cholesky, qr=qr, svd=svd)
    namespace = types.SimpleNamespace(**names)
    namespace.unchecked = True
    return namespace


def install() -> None:
    """Give SMT's Kriging modules :func:`unchecked_linalg` (idempotent)."""
    namespace = unchecked_linalg()
    for module_name in SMT_MODULES:
        module = import_module(module_name)
        if getattr(module.linalg, "unchecked", False):
            continue
        if module.linalg is not scipy.linalg:
            raise RuntimeError(f"{module_name}.linalg is not scipy.linalg: SMT changed")
        module.linalg = namespace


def uninstall() -> None:
    """SMT's own ``scipy.linalg`` back (for the test that compares the two)."""
    for module_name in SMT_MODULES:
        import_module(module_name).linalg = scipy.linalg
