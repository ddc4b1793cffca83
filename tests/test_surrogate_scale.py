"""Surrogates on large training sets: subsampled cubic-cost candidates,
bounded cross-validation, gradient-boosted trees, and no change below the limits."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.stats import qmc
from sklearn.metrics import r2_score

from ovtraj.surrogate import SurrogateSet, fit_surrogates
from ovtraj.surrogate.fitted_models import fit_classifier, fit_regressor, seeded_subsample

NAMES = ("parking_altitude_km", "preparation_altitude_km", "separation_delay_h")
LOWER = np.array([250.0, 300.0, 0.0])
UPPER = np.array([350.0, 380.0, 24.0])


@pytest.fixture(scope="module")
def settings(scenario):
    return scenario.mission.surrogate


def _smooth(u: np.ndarray) -> np.ndarray:
    """A smooth test function of the unit cube (a dV-like bowl with a ripple)."""
    return 150.0 + 40.0 * (u[:, 0] - 0.3) ** 2 + 10.0 * u[:, 1] + 3.0 * np.sin(6.0 * u[:, 2])


def _data(n: int, seed: int):
    u = qmc.LatinHypercube(d=3, seed=seed).random(n)
    x = qmc.scale(u, LOWER, UPPER)
    y = _smooth(u)
    # infeasible where the third input is high and the first low: a half-space-like region
    feasible = (u[:, 2] - u[:, 0]) < 0.6
    return x, y, feasible


def test_seeded_subsample_is_bounded_sorted_and_repeatable():
    rows = seeded_subsample(5000, 700, seed=7)
    assert rows.size == 700 and np.all(np.diff(rows) > 0) and rows.max() < 5000
    assert np.array_equal(rows, seeded_subsample(5000, 700, seed=7))
    assert not np.array_equal(rows, seeded_subsample(5000, 700, seed=8))
    assert np.array_equal(seeded_subsample(300, 700, seed=7), np.arange(300))
    # stratified: a 2 % class keeps its share, and at least 2 of it
    classes = np.zeros(5000, dtype=bool)
    classes[::50] = True
    picked = seeded_subsample(5000, 700, seed=7, classes=classes)
    assert picked.size == 700 and classes[picked].sum() == 14
    rare = np.zeros(5000, dtype=bool)
    rare[[3, 4000]] = True
    assert rare[seeded_subsample(5000, 50, seed=7, classes=rare)].sum() == 2


def test_cubic_candidates_fit_a_bounded_subsample(settings):
    large = settings.large_samples
    u = qmc.LatinHypercube(d=3, seed=1).random(large.exact_max_samples + 300)
    y = _smooth(u)
    for name in ("KRG", "RBF"):
        u_fit, y_fit = fit_regressor(name, u, y, settings).training()
        assert u_fit.shape == (large.exact_max_samples, 3)
        rows = seeded_subsample(u.shape[0], large.exact_max_samples, settings.seed)
        assert np.array_equal(u_fit, u[rows]) and np.array_equal(y_fit, y[rows])
    # linear-cost candidates take every sample
    for name in ("QP", "GBT"):
        assert fit_regressor(name, u, y, settings).training()[0].shape == u.shape
    flags = u[:, 0] > 0.2
    svc = fit_classifier("svc", u, flags, settings)
    assert svc.training[0].shape[0] == large.exact_max_samples
    assert fit_classifier("logistic", u, flags, settings).training[0].shape == u.shape


def test_large_fit_bounds_cv_adds_gbt_and_predicts_well(settings, tmp_path):
    """2,000 samples with the shipped settings: the CV runs on cv_max_samples of the
    training samples, GBT is compared, the selected models predict the held-out samples
    of a smooth function within 1 % of its spread, and the stored set predicts the same."""
    large = settings.large_samples
    x, y, feasible = _data(2000, seed=3)
    y = np.where(feasible, y, np.nan)
    fitted = fit_surrogates(x, {"dv": y}, feasible, LOWER, UPPER, settings, input_names=NAMES)
    validation = fitted.validation
    regressors = validation[validation["kind"] == "regressor"]
    assert set(regressors["candidate"]) == {*settings.regressors, *large.extra_regressors}
    assert (regressors["n_train"] > large.cv_max_samples).all()
    cv = fitted.predictions[fitted.predictions["split"] == "cv"]
    assert (cv.groupby("model").size() == large.cv_max_samples).all()
    held = fitted.predictions[
        (fitted.predictions["split"] == "heldout") & (fitted.predictions["model"] == "dv")
    ]
    assert r2_score(held["y_true"], held["y_pred"]) > 0.999
    worst = np.max(np.abs(held["y_true"] - held["y_pred"]))
    assert worst < 0.01 * (np.nanmax(y) - np.nanmin(y))
    fitted.save(tmp_path / "set", meta={"test": True})
    loaded = SurrogateSet.load(tmp_path / "set")
    probe = qmc.scale(qmc.LatinHypercube(d=3, seed=9).random(200), LOWER, UPPER)
    assert np.array_equal(loaded.predict(probe)["dv"], fitted.predict(probe)["dv"])
    assert np.array_equal(loaded.feasibility(probe), fitted.feasibility(probe))


def test_below_the_limits_the_fit_is_unchanged(settings):
    """A training set under exact_max_samples and cv_max_samples: the same selections,
    figures and predictions as with large_samples null (every candidate on every sample)."""
    x, y, feasible = _data(120, seed=5)
    y = np.where(feasible, y, np.nan)
    before = settings.model_copy(update={"large_samples": None})
    now = fit_surrogates(x, {"dv": y}, feasible, LOWER, UPPER, settings, input_names=NAMES)
    then = fit_surrogates(x, {"dv": y}, feasible, LOWER, UPPER, before, input_names=NAMES)
    drop = ["fit_time_s"]
    pd.testing.assert_frame_equal(
        now.validation.drop(columns=drop, errors="ignore"),
        then.validation.drop(columns=drop, errors="ignore"),
    )
    pd.testing.assert_frame_equal(now.predictions, then.predictions)
