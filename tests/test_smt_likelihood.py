"""SMT's Kriging likelihood remembered between TNC's objective and gradient calls: the
same fits, bit for bit, with about half the likelihood evaluations."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from smt.surrogate_models import KPLS, KRG
from smt.surrogate_models.krg_based.likelihood_eval import LikelihoodEvaluator

from ovtraj.surrogate.estimators import KPLSModel, KRGModel
from ovtraj.surrogate.smt_likelihood import RememberedLikelihood


def _fitted(model_class, u, y, **options):
    model = model_class(print_global=False, n_start=3, seed=7, **options)
    model.set_training_values(u, y)
    model.train()
    return model


@pytest.mark.parametrize(
    ("ours", "stock", "options", "dim"),
    [(KRGModel, KRG, {}, 3), (KPLSModel, KPLS, {"n_comp": 2}, 3), (KRGModel, KRG, {}, 1)],
)
def test_fits_equal_stock_smt_with_half_the_evaluations(monkeypatch, ours, stock, options, dim):
    rng = np.random.default_rng(21)
    u = rng.random((20, dim))
    y = np.sin(3.0 * u[:, 0]) + 0.3 * u[:, -1] ** 2
    grid = rng.random((200, dim))
    mine = _fitted(ours, u, y, **options)

    computed = []
    evaluate = LikelihoodEvaluator.evaluate

    def counted(self, theta):
        computed.append(1)
        return evaluate(self, theta)

    monkeypatch.setattr(LikelihoodEvaluator, "evaluate", counted)
    reference = _fitted(stock, u, y, **options)
    monkeypatch.undo()

    np.testing.assert_array_equal(mine.optimal_theta, reference.optimal_theta)
    np.testing.assert_array_equal(mine.corr.theta, reference.corr.theta)
    np.testing.assert_array_equal(mine.predict_values(grid), reference.predict_values(grid))
    np.testing.assert_array_equal(mine.predict_variances(grid), reference.predict_variances(grid))
    assert set(mine.optimal_par) == set(reference.optimal_par)
    for name, value in reference.optimal_par.items():
        np.testing.assert_array_equal(np.asarray(mine.optimal_par[name]), np.asarray(value))
    evaluator = mine._likelihood_evaluator
    assert isinstance(evaluator, RememberedLikelihood)
    # Every call stock SMT made, computed or answered from memory; about half remembered.
    assert evaluator.evaluations + evaluator.remembered == len(computed)
    assert evaluator.remembered >= 0.45 * len(computed)


def test_a_trained_model_keeps_no_memory_and_pickles():
    rng = np.random.default_rng(3)
    u = rng.random((15, 2))
    y = u[:, 0] - 2.0 * u[:, 1] ** 2
    model = _fitted(KRGModel, u, y)
    assert model._likelihood_evaluator._last is None
    restored = pickle.loads(pickle.dumps(model))
    grid = rng.random((50, 2))
    np.testing.assert_array_equal(restored.predict_values(grid), model.predict_values(grid))


def test_another_theta_or_other_training_data_is_computed():
    rng = np.random.default_rng(4)
    u = rng.random((10, 2))
    model = _fitted(KRGModel, u, u[:, 0] + u[:, 1])
    evaluator = RememberedLikelihood(model)
    theta = np.array([0.3, 0.7])
    first, _ = evaluator.evaluate(theta)
    again, _ = evaluator.evaluate(theta.reshape(-1, 1))
    assert (evaluator.evaluations, evaluator.remembered) == (1, 1)
    assert again == first
    evaluator.evaluate(np.array([0.3, 0.70000001]))
    assert evaluator.evaluations == 2
    model.y_norma = model.y_norma.copy()  # new training values: not the remembered ones
    evaluator.evaluate(np.array([0.3, 0.70000001]))
    assert evaluator.evaluations == 3


@pytest.mark.parametrize(("ours", "options"), [(KRGModel, {}), (KPLSModel, {"n_comp": 3})])
def test_the_gradient_from_one_correlation_evaluation_equals_smts(ours, options):
    rng = np.random.default_rng(6)
    u = rng.random((18, 5))
    model = _fitted(ours, u, np.sin(u.sum(axis=1)), **options)
    evaluator = model._likelihood_evaluator
    kernel = model.corr
    for scale in (0.5, 1.0, 3.0):
        theta = np.atleast_1d(model.optimal_theta) * scale
        mine, _ = evaluator.gradient(theta)
        evaluator.forget()
        stock, _ = LikelihoodEvaluator.gradient(evaluator, theta)
        np.testing.assert_array_equal(mine, stock)
    assert model.corr is kernel  # the kernel back after each gradient


@pytest.mark.parametrize(
    ("ours", "options", "dim"), [(KRGModel, {}, 3), (KPLSModel, {"n_comp": 2}, 4)]
)
def test_the_ordinary_path_evaluates_as_stock_smt(ours, options, dim):
    """The evaluation and the gradient through LAPACK directly: stock SMT's value, gradient
    and every parameter, to the bit, over hyperparameters from tiny to large."""
    rng = np.random.default_rng(11)
    u = rng.random((25, dim))
    model = _fitted(ours, u, np.cos(2.0 * u[:, 0]) * u[:, -1], **options)
    evaluator = model._likelihood_evaluator
    for scale in (1e-3, 0.3, 1.0, 4.0, 60.0):
        theta = np.atleast_1d(model.optimal_theta) * scale
        value, par = evaluator.evaluate(theta)
        stock_value, stock_par = LikelihoodEvaluator.evaluate(evaluator, theta)
        assert value == stock_value
        assert list(par) == list(stock_par)
        for name, array in stock_par.items():
            np.testing.assert_array_equal(par[name], array)
        evaluator.forget()
        gradient, gradient_par = evaluator.gradient(theta)
        evaluator.forget()
        stock_gradient, stock_gradient_par = LikelihoodEvaluator.gradient(evaluator, theta)
        np.testing.assert_array_equal(gradient, stock_gradient)
        for name in ("dr", "tr", "dmu", "arg", "dsigma", "dbeta_all"):
            for mine, stock in zip(gradient_par[name], stock_gradient_par[name], strict=True):
                np.testing.assert_array_equal(mine, stock)
        evaluator.forget()


def test_a_correlation_matrix_that_is_not_positive_definite_has_no_likelihood():
    """Two equal inputs make R singular without a nugget: -inf and no parameters, as SMT
    returns (without its printout)."""
    rng = np.random.default_rng(2)
    u = rng.random((8, 2))
    model = _fitted(KRGModel, u, u[:, 0])
    evaluator = model._likelihood_evaluator
    model.options["nugget"] = 0.0
    model.D[0] = 0.0  # the first pair's inputs made equal: their correlation is 1
    value, par = evaluator.evaluate(np.array([1e-3, 1e-3]))
    assert value == -np.inf
    assert par == {}
