"""SMT's Kriging predictions without scikit-learn's input checks: the same values."""

from __future__ import annotations

import numpy as np
import pytest
from smt.surrogate_models import KPLS, KRG
from smt.surrogate_models.krg_based import distances

from ovtraj.surrogate import smt_differences
from ovtraj.surrogate.estimators import install_smt_speedups


@pytest.fixture(autouse=True, scope="module")
def _installed():
    """As in the pipeline: installed by the first Kriging model built."""
    install_smt_speedups()


def test_the_differences_equal_smts_and_other_inputs_go_to_smt():
    rng = np.random.default_rng(8)
    x, y = rng.random((7, 3)), rng.random((5, 3))
    np.testing.assert_array_equal(smt_differences.differences(x, y), distances.differences(x, y))
    # Inputs outside the direct path: SMT's function, its conversions and its errors.
    ints = np.arange(6).reshape(2, 3)
    np.testing.assert_array_equal(
        smt_differences.differences(ints, y), distances.differences(ints, y)
    )
    with pytest.raises(ValueError, match="NaN"):
        smt_differences.differences(np.full((2, 3), np.nan), y)
    with pytest.raises(ValueError):
        smt_differences.differences(x, rng.random((5, 2)))


@pytest.mark.parametrize(("model_class", "options"), [(KRG, {}), (KPLS, {"n_comp": 2})])
def test_predictions_equal_those_of_stock_smt(model_class, options):
    from smt.surrogate_models.krg_based import krg_based

    assert krg_based.differences is smt_differences.differences
    rng = np.random.default_rng(9)
    u = rng.random((25, 3))
    model = model_class(print_global=False, n_start=1, seed=3, **options)
    model.set_training_values(u, np.cos(2.0 * u[:, 0]) + u[:, 1] * u[:, 2])
    model.train()
    grid = rng.random((300, 3))
    values, variances = model.predict_values(grid), model.predict_variances(grid)
    smt_differences.uninstall()
    try:
        np.testing.assert_array_equal(values, model.predict_values(grid))
        np.testing.assert_array_equal(variances, model.predict_variances(grid))
    finally:
        smt_differences.install()
