"""SMT's Kriging with scipy's validation layers skipped: the same fits, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from smt.surrogate_models import KPLS, KRG

from ovtraj.surrogate import smt_linalg
from ovtraj.surrogate.estimators import install_smt_speedups


@pytest.fixture(autouse=True, scope="module")
def _installed():
    """As in the pipeline: installed by the first Kriging model built."""
    install_smt_speedups()


def _fitted(model_class, u: np.ndarray, y: np.ndarray, **options):
    model = model_class(print_global=False, n_start=1, seed=7, **options)
    model.set_training_values(u, y)
    model.train()
    return model


@pytest.mark.parametrize(("model_class", "options"), [(KRG, {}), (KPLS, {"n_comp": 2})])
def test_fits_equal_those_of_stock_smt(model_class, options):
    rng = np.random.default_rng(21)
    u = rng.random((30, 3))
    y = np.sin(3.0 * u[:, 0]) + u[:, 1] ** 2 + 0.3 * u[:, 2]
    grid = rng.random((200, 3))
    installed = _fitted(model_class, u, y, **options)
    smt_linalg.uninstall()
    try:
        stock = _fitted(model_class, u, y, **options)
    finally:
        smt_linalg.install()
    np.testing.assert_array_equal(installed.optimal_theta, stock.optimal_theta)
    np.testing.assert_array_equal(installed.predict_values(grid), stock.predict_values(grid))
    np.testing.assert_array_equal(installed.predict_variances(grid), stock.predict_variances(grid))


def test_the_namespace_is_scipy_linalg_but_the_four_unchecked_functions():
    from importlib import import_module

    smt_linalg.install()  # idempotent: already installed
    for module_name in smt_linalg.SMT_MODULES:
        namespace = import_module(module_name).linalg
        assert namespace.unchecked
        for name in scipy.linalg.__all__:
            if name not in smt_linalg.UNCHECKED:
                assert getattr(namespace, name) is getattr(scipy.linalg, name)
        for name in smt_linalg.UNCHECKED:
            assert getattr(namespace, name) is getattr(smt_linalg, name)


def test_economic_qr_and_singular_values_equal_scipy_and_defer_the_rest():
    """The LAPACK paths of ``qr(mode="economic")`` and ``svd(compute_uv=False)``:
    scipy's numbers to the bit on tall, square and one-column matrices, C- or
    Fortran-ordered; other modes, ``compute_uv`` and wide matrices are scipy's own."""
    rng = np.random.default_rng(8)
    for shape in ((30, 1), (30, 4), (12, 12), (7, 3)):
        for a in (rng.random(shape), np.asfortranarray(rng.random(shape))):
            q, r = smt_linalg.qr(a, mode="economic")
            q_ref, r_ref = scipy.linalg.qr(a, mode="economic")
            np.testing.assert_array_equal(q, q_ref)
            np.testing.assert_array_equal(r, r_ref)
            assert r.flags.c_contiguous == r_ref.flags.c_contiguous
            np.testing.assert_array_equal(
                smt_linalg.svd(a, compute_uv=False), scipy.linalg.svd(a, compute_uv=False)
            )
    wide = rng.random((3, 7))
    for got, ref in zip(
        smt_linalg.qr(wide, mode="economic"), scipy.linalg.qr(wide, mode="economic"), strict=True
    ):
        np.testing.assert_array_equal(got, ref)
    full = smt_linalg.qr(rng.random((6, 2)))
    assert full[0].shape == (6, 6)
    u, s, vt = smt_linalg.svd(wide)  # scipy's full factors
    assert (u.shape, vt.shape) == ((3, 3), (7, 7))
    np.testing.assert_allclose(u @ np.diag(s) @ vt[:3], wide, atol=1e-12)


def test_direct_lapack_calls_equal_scipy_and_raise_as_scipy():
    rng = np.random.default_rng(5)
    a = rng.random((12, 12)) + 12.0 * np.eye(12)
    spd = a @ a.T
    for lower in (True, False):
        factor = smt_linalg.cholesky(spd, lower=lower)
        np.testing.assert_array_equal(factor, scipy.linalg.cholesky(spd, lower=lower))
        for b in (rng.random(12), rng.random((12, 3))):
            for matrix in (factor, factor.T, np.asfortranarray(factor)):
                for trans in (0, 1, "T"):
                    np.testing.assert_array_equal(
                        smt_linalg.solve_triangular(matrix, b, trans=trans, lower=lower),
                        scipy.linalg.solve_triangular(matrix, b, trans=trans, lower=lower),
                    )
    # Inputs outside the direct path go to scipy's own function.
    np.testing.assert_array_equal(
        smt_linalg.solve_triangular(np.eye(2, dtype=np.float32), np.ones(2, dtype=np.float32)),
        np.ones(2),
    )
    indefinite = np.diag([1.0, -1.0])
    with pytest.raises(scipy.linalg.LinAlgError, match="not positive definite"):
        smt_linalg.cholesky(indefinite)
    singular = np.triu(np.ones((3, 3)))
    singular[1, 1] = 0.0
    with pytest.raises(scipy.linalg.LinAlgError, match="singular matrix"):
        smt_linalg.solve_triangular(singular, np.ones(3))


def test_importing_ovtraj_changes_nothing_in_smt_until_a_kriging_model_is_built(tmp_path):
    """No side effect at import: SMT is stock after importing the library (the pipeline
    too); unpickling a fitted Kriging candidate installs both speed-ups (a pool's parent
    receives a fold's model without building one), and so does building one."""
    import pickle
    import subprocess
    import sys

    from smt.surrogate_models.krg_based import distances, krg_based, likelihood_eval

    from ovtraj.surrogate import smt_differences
    from ovtraj.surrogate.estimators import KRGModel

    u = np.random.default_rng(3).random((8, 2))
    fitted = KRGModel(print_global=False, n_start=1, seed=7)
    fitted.set_training_values(u, u[:, 0] + u[:, 1] ** 2)
    fitted.train()
    stored = tmp_path / "krg.pickle"
    stored.write_bytes(pickle.dumps(fitted))
    script = (
        "import pickle, scipy.linalg\n"
        "from smt.surrogate_models.krg_based import distances, krg_based, likelihood_eval\n"
        "def stock():\n"
        "    return (krg_based.linalg is scipy.linalg and likelihood_eval.linalg is scipy.linalg\n"
        "            and krg_based.differences is distances.differences)\n"
        "import ovtraj.surrogate, ovtraj.pipeline.features, ovtraj.pipeline.steps\n"
        "assert stock(), 'changed at import'\n"
        f"pickle.loads(open({str(stored)!r}, 'rb').read())\n"
        "assert not stock(), 'not installed by an unpickled model'\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    # Built: installed again after an uninstall (idempotent otherwise).
    smt_linalg.uninstall()
    smt_differences.uninstall()
    KRGModel(print_global=False)
    assert krg_based.linalg is likelihood_eval.linalg
    assert krg_based.linalg is not scipy.linalg and krg_based.linalg.unchecked
    assert krg_based.differences is smt_differences.differences
    assert krg_based.differences is not distances.differences
