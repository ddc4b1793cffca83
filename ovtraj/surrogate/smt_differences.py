"""SMT's Kriging predictions without scikit-learn's validation of their inputs.

Every KRG and KPLS prediction (NSGA-II asks for one per output and generation, each CV
fold for its held-out samples) begins with ``differences(x, X_train)``, the componentwise
differences of the points and the training samples, which SMT 2.15 computes after
scikit-learn's ``check_pairwise_arrays``: two ``check_array`` calls, ~0.25 ms each here,
several times the arithmetic for 64 points and 30 samples (a third of a surrogate
front's model time, profiled). :func:`differences` does the same arithmetic on the same
values when both inputs are finite float64 matrices with the same columns (what
:class:`ovtraj.surrogate.SurrogateSet` passes: it refuses non-finite inputs); anything
else goes to SMT's own function, which validates and raises as before. The predictions
are the same to the bit (``tests/test_smt_differences.py``).

:func:`install` puts it in SMT's Kriging module (idempotent; the Kriging models call it
when one is built or unpickled, :mod:`ovtraj.surrogate.estimators`, never an import);
:func:`uninstall` restores SMT's.
"""

from __future__ import annotations

from importlib import import_module

import numpy as np

# The module whose Kriging predictions call ``differences`` by that name.
SMT_MODULE = "smt.surrogate_models.krg_based.krg_based"
_SMT_DIFFERENCES = import_module("smt.surrogate_models.krg_based.distances").differences

__all__ = ["differences", "install", "uninstall"]


def differences(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``X[i] - Y[j]`` for every pair, rows in ``i``-major order (n_x * n_y, d): SMT's
    ``differences`` without scikit-learn's checks for finite float64 matrices."""
    x, y = np.asarray(X), np.asarray(Y)
    if not (
        x.dtype == np.float64
        and y.dtype == np.float64
        and x.ndim == 2
        and y.ndim == 2
        and x.shape[1] == y.shape[1]
        and x.size
        and y.size
        and np.isfinite(x).all()
        and np.isfinite(y).all()
    ):
        return _SMT_DIFFERENCES(X, Y)
    return (x[:, np.newaxis, :] - y[np.newaxis, :, :]).reshape((-1, x.shape[1]))


def install() -> None:
    """SMT's Kriging predictions use :func:`differences` (idempotent)."""
    module = import_module(SMT_MODULE)
    if module.differences is not differences and module.differences is not _SMT_DIFFERENCES:
        raise RuntimeError(f"{SMT_MODULE}.differences is not SMT's: SMT changed")
    module.differences = differences


def uninstall() -> None:
    """SMT's own ``differences`` back (for the test that compares the two)."""
    import_module(SMT_MODULE).differences = _SMT_DIFFERENCES
