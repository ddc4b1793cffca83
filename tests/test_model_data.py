"""The fitted surrogate models stored as data and rebuilt (ovtraj.surrogate.model_data).

Every candidate, rebuilt from its data alone (through the stored table), predicts what the
fitted model predicts, to the bit, at points it was not fitted on; a stored model whose
data were changed, or whose description is hostile, is refused naming the model.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from scipy.stats import qmc

from ovtraj.surrogate import SurrogateError
from ovtraj.surrogate.fitted_models import fit_classifier, fit_regressor
from ovtraj.surrogate.model_data import (
    arrays_table,
    classifier_data,
    model_data,
    rebuilt_classifier,
    rebuilt_regressor,
    regressor_data,
)


@pytest.fixture(scope="module")
def settings(scenario):
    return scenario.mission.surrogate


@pytest.fixture(scope="module")
def samples():
    u = qmc.LatinHypercube(d=4, seed=11).random(60)
    y = np.sin(3 * u[:, 0]) + u[:, 1] ** 2 - 0.4 * u[:, 2] * u[:, 3]
    feasible = np.linalg.norm(u - 0.45, axis=1) < 0.6
    probe = qmc.LatinHypercube(d=4, seed=12).random(400)
    return u, y, feasible, probe


def _through_the_store(data, name="m"):
    """The data as written and read back (the Parquet table and the JSON description)."""
    import json

    description = json.loads(json.dumps({name: data.description()}))
    return model_data(description, arrays_table({name: data}), "models.parquet")[name]


@pytest.mark.parametrize("candidate", ["KRG", "KPLS", "RBF", "QP", "ET"])
def test_every_regressor_is_rebuilt_to_the_bit(candidate, settings, samples):
    u, y, _, probe = samples
    fitted = fit_regressor(candidate, u, y, settings)
    rebuilt = rebuilt_regressor(_through_the_store(regressor_data(fitted)), settings)
    np.testing.assert_array_equal(rebuilt.predict(probe), fitted.predict(probe))
    assert rebuilt.model is not fitted.model


@pytest.mark.parametrize("candidate", ["svc", "gpc", "logistic"])
def test_every_classifier_is_rebuilt_to_the_bit(candidate, settings, samples):
    u, _, feasible, probe = samples
    fitted = fit_classifier(candidate, u, feasible, settings)
    rebuilt = rebuilt_classifier(_through_the_store(classifier_data(fitted)), settings)
    np.testing.assert_array_equal(rebuilt.proba(probe), fitted.proba(probe))
    if candidate == "gpc":  # the fitted kernel kept, not maximised again from the start
        assert rebuilt.estimator.kernel_ == fitted.estimator.kernel_
        assert rebuilt.estimator.optimizer is None
        assert fitted.estimator.kernel != fitted.estimator.kernel_


def test_a_constant_classifier_is_stored_without_arrays(settings, samples):
    u, *_ = samples
    fitted = fit_classifier("svc", u, np.ones(len(u), bool), settings)
    data = _through_the_store(classifier_data(fitted))
    assert data.constant == 1.0 and data.arrays == {}
    assert rebuilt_classifier(data, settings).proba(u[:3]).tolist() == [1.0, 1.0, 1.0]


def test_a_changed_fitted_state_is_refused(settings, samples):
    """Kriging's stored GLS solution moved by one part in a billion: the rebuilt model no
    longer reproduces its fitted predictions, and says so."""
    u, y, *_ = samples
    data = regressor_data(fit_regressor("KRG", u, y, settings))
    data.arrays["gamma"][0] *= 1 + 1e-9
    with pytest.raises(SurrogateError, match="does not reproduce its fitted predictions"):
        rebuilt_regressor(data, settings)


def test_hostile_descriptions_and_arrays_are_refused(settings, samples):
    u, y, *_ = samples
    data = regressor_data(fit_regressor("QP", u, y, settings))
    table = arrays_table({"m": data})
    good = {"m": data.description()}

    def refused(descriptions, arrays=table, match=""):
        with pytest.raises(SurrogateError, match=match):
            model_data(descriptions, arrays, "models.parquet")

    refused({"m": good["m"] | {"candidate": "os.system"}}, match="unknown candidate")
    refused({"m": good["m"] | {"extra": 1}}, match="not a model description")
    refused({"m": good["m"] | {"columns": [-1]}}, match="columns")
    refused({"m": good["m"] | {"hyper": {"x": 1.0}}}, match="hyperparameters")
    refused({"m": good["m"] | {"constant": 0.5}}, match="constant classifier")
    refused({}, match="undescribed models")
    refused("models", match="not a mapping")
    # Shapes and values.
    values = table.column("values").to_pylist()
    for change, match in (
        (lambda v: v[:-1], "values for shape"),
        (lambda v: [float("nan"), *v[1:]], "not finite"),
    ):
        rows = list(values)
        rows[0] = change(rows[0])
        column = pa.array(rows, table.schema.field("values").type)
        refused(good, table.set_column(3, table.schema.field(3), column), match=match)
    shapes = table.column("shape").to_pylist()
    shapes[0] = [1, 1, len(values[0])]
    column = pa.array(shapes, table.schema.field("shape").type)
    refused(good, table.set_column(2, table.schema.field(2), column), match="shape")
    doubled = pa.concat_tables([table, table.slice(0, 1)])
    refused(good, doubled, match="stored twice")
