"""Surrogate models (ovtraj.surrogate): selection by k-fold CV, held-out set, storage, plots."""

from __future__ import annotations

import hashlib
import json
import os
import pickle

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from scipy.optimize import minimize
from scipy.stats import qmc
from sklearn.metrics import r2_score
from sklearn.model_selection import KFold
from smt.surrogate_models import QP, RBF
from smt.surrogate_models.krg_based.hyperparam_optim import TNCOptimizer

from ovtraj.plots.surrogate import parity_plots
from ovtraj.store.files import StoreError
from ovtraj.surrogate import (
    SurrogateError,
    SurrogateSet,
    UnitCube,
    fit_surrogates,
    training_data_hash,
)
from ovtraj.surrogate import candidates as candidates_module
from ovtraj.surrogate import validation as validation_module
from ovtraj.surrogate.fitted_models import fit_regressor
from ovtraj.surrogate.tables import PREDICTIONS_SCHEMA, STORED_VALIDATION_SCHEMA
from ovtraj.surrogate.validation import holdout_mask

NAMES = ("parking_altitude_km", "preparation_altitude_km", "separation_delay_h")
LOWER = np.array([250.0, 300.0, 0.0])
UPPER = np.array([350.0, 380.0, 24.0])
METRICS = [
    "cv_rmse",
    "cv_q2",
    "heldout_rmse",
    "heldout_r2",
    "cv_accuracy",
    "cv_balanced_accuracy",
    "cv_log_loss",
    "heldout_accuracy",
]


@pytest.fixture(scope="module")
def settings(scenario):
    return scenario.mission.surrogate


def lhs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit-cube and physical Latin hypercube samples."""
    u = qmc.LatinHypercube(d=3, seed=seed).random(n)
    return u, qmc.scale(u, LOWER, UPPER)


def ball(u: np.ndarray, centre=(0.45, 0.5, 0.55), radius: float = 0.4) -> np.ndarray:
    return np.linalg.norm(u - np.asarray(centre), axis=1) < radius


def chain_like(n: int, seed: int) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """Two smooth outputs (NaN where infeasible) and a ball-shaped feasible region."""
    u, x = lhs(n, seed)
    feasible = ball(u, radius=0.55)
    t = 100 + 50 * np.sum((u - [0.3, 0.6, 0.5]) ** 2, axis=1) + 3 * np.sin(4 * u[:, 0])
    dv = 200 + 80 * u[:, 1] - 30 * u[:, 2] ** 2
    outputs = {name: np.where(feasible, y, np.nan) for name, y in (("t_h", t), ("dv_mps", dv))}
    return x, outputs, feasible


@pytest.fixture(scope="module")
def fitted(settings):
    x, outputs, feasible = chain_like(50, seed=5)
    ids = np.arange(100, 150)
    fit = fit_surrogates(
        x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES, sample_ids=ids
    )
    return fit, (x, outputs, feasible, ids)


# -- unit cube and held-out split ---------------------------------------------------------


def test_unit_cube_maps_the_box_and_rejects_bad_bounds():
    cube = UnitCube(LOWER, UPPER)
    np.testing.assert_allclose(cube.to_unit(np.array([LOWER, UPPER])), [[0, 0, 0], [1, 1, 1]])
    x = np.array([[300.0, 340.0, 6.0]])
    np.testing.assert_allclose(cube.to_unit(x), [[0.5, 0.5, 0.25]])
    np.testing.assert_allclose(cube.from_unit(cube.to_unit(x)), x)
    with pytest.raises(SurrogateError, match=r"lower must be < upper.*input 1: \[300, 300\]"):
        UnitCube(LOWER, np.array([350.0, 300.0, 24.0]))
    with pytest.raises(SurrogateError, match="one value per input"):
        UnitCube(LOWER, UPPER[:2])


def test_holdout_is_stratified_seeded_and_keeps_a_lone_class_in_training():
    feasible = np.array([True] * 35 + [False] * 15)
    mask = holdout_mask(feasible, 0.2, seed=3)
    # 10 of 50, shared 7/3 in proportion to the classes (15/50 of 10 = 3).
    assert mask.sum() == 10
    assert (mask & ~feasible).sum() == 3
    np.testing.assert_array_equal(mask, holdout_mask(feasible, 0.2, seed=3))
    assert not np.array_equal(mask, holdout_mask(feasible, 0.2, seed=4))
    lone = np.array([True] * 19 + [False])
    mask = holdout_mask(lone, 0.2, seed=3)
    assert mask.sum() == 4 and not mask[-1]
    # A small set still holds one sample out.
    assert holdout_mask(np.ones(4, bool), 0.1, seed=0).sum() == 1
    assert holdout_mask(np.ones(1, bool), 0.5, seed=0).sum() == 0


# -- accuracy on analytic problems --------------------------------------------------------


def test_analytic_minimum_is_recovered(settings):
    # f = |z|^2 + 0.3 (1 - cos 3 z0), z = (x - c) / s: both terms >= 0 and zero only at c.
    c = np.array([290.0, 355.0, 9.0])
    s = np.array([40.0, 35.0, 12.0])

    def f(x):
        z = (x - c) / s
        return np.sum(z**2, axis=1) + 0.3 * (1 - np.cos(3 * z[:, 0]))

    _, x = lhs(60, seed=0)
    fit = fit_surrogates(
        x, {"f": f(x)}, np.ones(60, bool), LOWER, UPPER, settings, input_names=NAMES
    )
    row = fit.validation.query("model == 'f' and selected").iloc[0]
    assert row["candidate"] == fit.selected["f"]
    assert row["heldout_r2"] > 0.99
    assert row["n_heldout"] == 12 and row["n_train"] == 48
    # Every sample is feasible: no classifier, probability 1.
    assert fit.selected["feasible"] == "all-feasible"
    np.testing.assert_array_equal(fit.feasibility(x[:5]), 1.0)
    # Minimise the surrogate (Kriging predictions are noisy at ~1e-7, so derivative-free),
    # from the best point of a dense grid, in unit-cube coordinates.
    grid = qmc.Sobol(d=3, seed=1).random(4096)
    start = grid[np.argmin(fit.predict(fit.cube.from_unit(grid))["f"])]
    best = minimize(
        lambda u: fit.predict(fit.cube.from_unit(u[None]))["f"][0],
        start,
        method="Nelder-Mead",
        bounds=[(0, 1)] * 3,
        options={"xatol": 1e-6, "fatol": 1e-10},
    )
    np.testing.assert_allclose(best.x, fit.cube.to_unit(c[None])[0], atol=0.01)
    assert abs(best.fun) < 0.01  # the true minimum is 0; f spans ~0-7 on the box


def test_cv_metrics_match_a_hand_computation(settings):
    u, x = lhs(30, seed=2)
    y = 1 + 2 * u[:, 0] - u[:, 1] + 0.5 * u[:, 0] * u[:, 2] + 3 * u[:, 1] ** 2  # quadratic
    quick = settings.model_copy(update={"regressors": ["QP", "RBF"], "classifiers": ["logistic"]})
    fit = fit_surrogates(x, {"y": y}, np.ones(30, bool), LOWER, UPPER, quick, input_names=NAMES)
    rows = fit.validation.set_index("candidate")
    # QP reproduces a quadratic exactly: PRESS = 0, Q^2 = 1.
    assert fit.selected["y"] == "QP"
    assert rows.loc["QP", "cv_rmse"] < 1e-10 * np.ptp(y)
    assert rows.loc["QP", "cv_q2"] == pytest.approx(1.0, abs=1e-12)
    assert rows.loc["QP", "heldout_r2"] == pytest.approx(1.0, abs=1e-12)

    # RBF by hand: the training samples in ascending order, sklearn KFold, SMT's RBF.
    cv = fit.predictions.query("model == 'y' and split == 'cv'")
    held = fit.predictions.query("model == 'y' and split == 'heldout'")
    train = np.sort(cv["sample_id"].to_numpy())
    test = np.sort(held["sample_id"].to_numpy())
    assert train.size + test.size == 30 and test.size == 6

    def rbf(idx):
        model = RBF(d0=quick.rbf_d0, print_global=False)
        model.set_training_values(u[idx], y[idx])
        model.train()
        return model

    y_cv = np.empty(train.size)
    for fit_idx, test_idx in KFold(quick.folds, shuffle=True, random_state=quick.seed).split(train):
        y_cv[test_idx] = rbf(train[fit_idx]).predict_values(u[train[test_idx]]).ravel()
    press = np.sum((y[train] - y_cv) ** 2)
    assert rows.loc["RBF", "cv_rmse"] == pytest.approx(np.sqrt(press / train.size), rel=1e-9)
    q2 = 1 - press / np.sum((y[train] - y[train].mean()) ** 2)
    assert rows.loc["RBF", "cv_q2"] == pytest.approx(q2, rel=1e-9)
    assert 0.5 < q2 < 0.9999  # a real, imperfect fit: the comparison is not trivial
    y_held = rbf(train).predict_values(u[test]).ravel()
    assert rows.loc["RBF", "heldout_r2"] == pytest.approx(r2_score(y[test], y_held), rel=1e-9)
    rmse = np.sqrt(np.mean((y[test] - y_held) ** 2))
    assert rows.loc["RBF", "heldout_rmse"] == pytest.approx(rmse, rel=1e-9)

    # The CV predictions of the selected candidate are the same hand loop's (QP here).
    y_qp = np.empty(train.size)
    for fit_idx, test_idx in KFold(quick.folds, shuffle=True, random_state=quick.seed).split(train):
        model = QP(print_global=False)
        model.set_training_values(u[train[fit_idx]], y[train[fit_idx]])
        model.train()
        y_qp[test_idx] = model.predict_values(u[train[test_idx]]).ravel()
    stored = cv.set_index("sample_id").loc[train, "y_pred"].to_numpy()
    np.testing.assert_allclose(stored, y_qp, rtol=1e-12)


def test_heldout_samples_never_enter_a_fit(settings, monkeypatch):
    u, x = lhs(60, seed=4)
    feasible = ball(u, radius=0.5)
    y = np.where(feasible, np.sum(u**2, axis=1), np.nan)
    seen: list[np.ndarray] = []

    def recording(real):
        def wrapper(name, u_fit, y_fit, s, *start):
            seen.append(np.array(u_fit))
            return real(name, u_fit, y_fit, s, *start)

        return wrapper

    monkeypatch.setattr(
        validation_module, "fit_regressor", recording(validation_module.fit_regressor)
    )
    monkeypatch.setattr(
        validation_module, "fit_classifier", recording(validation_module.fit_classifier)
    )
    quick = settings.model_copy(
        update={"regressors": ["QP", "RBF"], "classifiers": ["logistic"], "holdout_refit": False}
    )
    fit = fit_surrogates(x, {"y": y}, feasible, LOWER, UPPER, quick, input_names=NAMES)

    table = fit.predictions
    held = set(table.loc[table["split"] == "heldout", "sample_id"])
    assert held.isdisjoint(table.loc[table["split"] == "cv", "sample_id"])
    assert len(held) == 12  # 20 % of all 60 samples
    assert {True, False} <= set(feasible[list(held)])  # stratified: both classes held out
    # Regressors see each feasible training sample once in CV, never an infeasible one.
    cv_y = table.query("model == 'y' and split == 'cv'")["sample_id"]
    assert set(cv_y) == set(np.flatnonzero(feasible)) - held
    # Instrumented: no held-out point is in any training set of any fit (folds and final).
    held_points = {tuple(p) for p in fit.cube.to_unit(x[sorted(held)])}
    assert len(seen) == 2 * (quick.folds + 1) + (quick.folds + 1)
    for u_fit in seen:
        assert held_points.isdisjoint(map(tuple, u_fit))


def test_holdout_refit_scores_without_the_hold_out_and_uses_it(settings):
    """RBF interpolates: refitted with the hold-out, it passes through the held-out values;
    the stored held-out predictions stay those of the model fitted without them."""
    u, x = lhs(40, seed=8)
    y = np.sin(3 * u[:, 0]) + u[:, 1] ** 2 - u[:, 2]
    feasible = np.ones(40, bool)
    fits = {}
    for refit in (False, True):
        rbf = settings.model_copy(
            update={"regressors": ["RBF"], "classifiers": ["logistic"], "holdout_refit": refit}
        )
        fits[refit] = fit_surrogates(x, {"y": y}, feasible, LOWER, UPPER, rbf, input_names=NAMES)
    table = fits[True].predictions.query("model == 'y' and split == 'heldout'")
    held = table["sample_id"].to_numpy()
    assert len(held) == 8
    assert np.allclose(fits[True].predict(x[held])["y"], y[held], atol=1e-8)
    assert not np.allclose(fits[False].predict(x[held])["y"], y[held], atol=1e-3)
    # The validation and the stored held-out predictions: the model scored without them.
    for column in ("cv_rmse", "heldout_rmse"):
        assert fits[True].validation[column].tolist() == fits[False].validation[column].tolist()
    before = fits[False].predictions.query("model == 'y' and split == 'heldout'")
    assert table["y_pred"].tolist() == before["y_pred"].tolist()


def test_feasibility_classifier_on_a_known_region(settings):
    u, x = lhs(120, seed=0)
    feasible = ball(u)  # feasible iff |u - c| < 0.4 (~27 % of the cube)
    y = np.where(feasible, u.sum(axis=1), np.nan)
    every = ["svc", "gpc", "logistic"]
    quick = settings.model_copy(update={"regressors": ["QP"], "classifiers": every})
    fit = fit_surrogates(x, {"y": y}, feasible, LOWER, UPPER, quick, input_names=NAMES)
    rows = fit.validation.query("model == 'feasible'").set_index("candidate")
    assert set(rows.index) == set(every)
    chosen = fit.selected["feasible"]
    assert rows.loc[chosen, "selected"] and rows["selected"].sum() == 1
    assert rows.loc[chosen, "cv_balanced_accuracy"] == rows["cv_balanced_accuracy"].max()
    assert rows.loc[chosen, "heldout_accuracy"] > 0.9
    # Against the true region on independent points.
    probe = qmc.LatinHypercube(d=3, seed=99).random(4000)
    p = fit.feasibility(fit.cube.from_unit(probe))
    assert np.all((p >= 0) & (p <= 1))
    assert np.mean((p >= 0.5) == ball(probe)) > 0.9


# -- storage, hash, determinism -----------------------------------------------------------


def test_fitted_set_tables(fitted):
    fit, (x, outputs, feasible, ids) = fitted
    assert fit.output_names == ("t_h", "dv_mps") and fit.input_names == NAMES
    v = fit.validation
    regressors, classifiers = fit.settings.regressors, fit.settings.classifiers
    assert len(v) == 2 * len(regressors) + len(classifiers)
    assert set(v.loc[v["model"] == "t_h", "candidate"]) == set(regressors)
    for model, group in v.groupby("model"):
        assert group["selected"].sum() == 1
        assert fit.selected[model] == group.loc[group["selected"], "candidate"].iloc[0]
    reg = v[v["kind"] == "regressor"]
    assert reg[["cv_rmse", "cv_q2", "heldout_rmse", "heldout_r2"]].notna().all().all()
    cls = v[v["kind"] == "classifier"]
    assert cls[["cv_accuracy", "cv_balanced_accuracy", "cv_log_loss"]].notna().all().all()
    assert v["error"].isna().all() and all(e is None for e in v["error"])
    # No NaN anywhere: undefined metrics are <NA>.
    assert not any(np.isnan(value) for c in METRICS for value in v[c].dropna())
    assert set(fit.predictions["sample_id"]) <= set(ids)
    assert fit.data_hash == training_data_hash(x, outputs, feasible)
    pred = fit.predict(x)
    assert set(pred) == {"t_h", "dv_mps"} and pred["t_h"].shape == (50,)
    assert fit.predict(x[:0])["t_h"].shape == (0,) and fit.feasibility(x[:0]).shape == (0,)
    with pytest.raises(SurrogateError, match=r"shape \(m, 3\)"):
        fit.predict(x[:, :2])
    with pytest.raises(SurrogateError, match="NaN or infinite"):
        fit.feasibility(np.full((1, 3), np.nan))


def test_save_load_round_trip(fitted, tmp_path):
    fit, _ = fitted
    fit.save(tmp_path / "set", meta={"run_id": "r-42"})
    meta = json.loads((tmp_path / "set" / "meta.json").read_text())
    assert meta["run_id"] == "r-42" and meta["data_hash"] == fit.data_hash
    assert meta["selected"] == fit.selected and meta["input_names"] == list(NAMES)
    assert meta["settings"]["folds"] == fit.settings.folds and "smt" in meta["versions"]
    back = SurrogateSet.load(tmp_path / "set")
    probe = qmc.scale(qmc.LatinHypercube(d=3, seed=8).random(200), LOWER, UPPER)
    for name in fit.output_names:
        np.testing.assert_array_equal(back.predict(probe)[name], fit.predict(probe)[name])
    np.testing.assert_array_equal(back.feasibility(probe), fit.feasibility(probe))
    pd.testing.assert_frame_equal(back.validation, fit.validation)
    pd.testing.assert_frame_equal(back.predictions, fit.predictions)
    assert back.cube == fit.cube and back.selected == fit.selected
    assert back.meta["run_id"] == "r-42"


def test_load_names_the_missing_or_corrupt_file(fitted, tmp_path):
    fit, _ = fitted
    with pytest.raises(SurrogateError, match=r"meta\.json: missing"):
        SurrogateSet.load(tmp_path / "nothing")
    with pytest.raises(SurrogateError, match="reserved"):
        fit.save(tmp_path / "x", meta={"data_hash": "mine"})
    fit.save(tmp_path / "a", meta={})
    models = tmp_path / "a" / "models.parquet"
    models.write_bytes(models.read_bytes()[:100])
    with pytest.raises(SurrogateError, match=r"models\.parquet"):
        SurrogateSet.load(tmp_path / "a")
    fit.save(tmp_path / "b", meta={})
    (tmp_path / "b" / "validation.parquet").unlink()
    with pytest.raises(SurrogateError, match=r"validation\.parquet: missing"):
        SurrogateSet.load(tmp_path / "b")
    fit.save(tmp_path / "c", meta={})
    (tmp_path / "c" / "meta.json").write_text("{not json")
    with pytest.raises(SurrogateError, match=r"meta\.json: unreadable"):
        SurrogateSet.load(tmp_path / "c")
    # A consistent but changed model (one fitted value rewritten, checksum updated) is
    # rejected: rebuilt, it does not reproduce its fitted predictions.
    fit.save(tmp_path / "d", meta={})
    path = tmp_path / "d" / "models.parquet"
    table = pq.read_table(path)
    values = table.column("values").to_pylist()
    row = table.column("array").to_pylist().index("y")
    values[row][0] += 1.0
    pq.write_table(
        table.set_column(3, table.schema.field(3), pa.array(values, table.schema[3].type)), path
    )
    payload = path.read_bytes()
    meta = json.loads((tmp_path / "d" / "meta.json").read_text())
    meta["files"]["models.parquet"] = {
        "bytes": len(payload),
        "sha256": hashlib.sha256(payload).hexdigest(),
    }
    (tmp_path / "d" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(SurrogateError, match=r"does not reproduce its fitted predictions"):
        SurrogateSet.load(tmp_path / "d")


class _Payload:
    """A pickle that, loaded, runs a shell command (writes a file)."""

    def __init__(self, witness):
        self.witness = witness

    def __reduce__(self):
        return (os.system, (f"touch {self.witness}",))


def test_a_pickle_in_a_stored_set_never_runs(fitted, tmp_path):
    """A models.pkl whose loading runs a command, listed with its right digests
    in a marker of the old format (the pickle one) or beside the data of the current one,
    is never unpickled: the load is refused, or rebuilt from the data alone."""
    fit, _ = fitted
    witness = tmp_path / "ran"
    payload = pickle.dumps(_Payload(witness))
    digest = {"bytes": len(payload), "sha256": hashlib.sha256(payload).hexdigest()}
    # The marker of format 2 (models.pkl): refused by its format.
    fit.save(tmp_path / "old", meta={})
    (tmp_path / "old" / "models.parquet").unlink()
    (tmp_path / "old" / "models.pkl").write_bytes(payload)
    meta = json.loads((tmp_path / "old" / "meta.json").read_text())
    del meta["files"]["models.parquet"]
    meta["files"]["models.pkl"] = digest
    meta["format"] = 2
    (tmp_path / "old" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(SurrogateError, match=r"unknown store format 2"):
        SurrogateSet.load(tmp_path / "old")
    # The current format with the pickle listed beside: read from its data only.
    fit.save(tmp_path / "new", meta={})
    (tmp_path / "new" / "models.pkl").write_bytes(payload)
    meta = json.loads((tmp_path / "new" / "meta.json").read_text())
    meta["files"]["models.pkl"] = digest
    (tmp_path / "new" / "meta.json").write_text(json.dumps(meta))
    probe = qmc.scale(qmc.LatinHypercube(d=3, seed=3).random(50), LOWER, UPPER)
    back = SurrogateSet.load(tmp_path / "new")
    np.testing.assert_array_equal(back.feasibility(probe), fit.feasibility(probe))
    # The payload works: loading it (here, deliberately) writes the witness.
    assert not witness.exists()
    pickle.loads(payload)
    assert witness.exists()


def test_stored_tables_have_the_declared_schemas_and_every_file_is_checked(fitted, tmp_path):
    """meta.json lists each file's size and SHA-256; a valid Parquet file with one value
    rewritten, a missing file or an unlisted one is refused naming the file."""
    fit, _ = fitted
    directory = tmp_path / "set"
    written = fit.save(directory, meta={})
    meta = json.loads((directory / "meta.json").read_text())
    assert meta["format"] == 3
    assert set(meta["files"]) == {"models.parquet", "validation.parquet", "predictions.parquet"}
    for name, recorded in meta["files"].items():
        payload = (directory / name).read_bytes()
        assert recorded == {"bytes": len(payload), "sha256": hashlib.sha256(payload).hexdigest()}
        assert written[name].to_json() == recorded
    # The declared schemas, whatever the data: "error" is all null, the classifier
    # metrics are null in the regressor rows.
    assert fit.validation["error"].isna().all()
    assert pq.read_schema(directory / "validation.parquet").equals(STORED_VALIDATION_SCHEMA)
    assert pq.read_schema(directory / "predictions.parquet").equals(PREDICTIONS_SCHEMA)
    # Saving the same set again is a no-op; other content is refused, nothing replaced.
    before = {p.name: p.read_bytes() for p in directory.iterdir()}
    fit.save(directory, meta={})
    with pytest.raises(StoreError, match=r"meta\.json: already stored with other content"):
        fit.save(directory, meta={"run_id": "other"})
    assert {p.name: p.read_bytes() for p in directory.iterdir()} == before
    # One value rewritten in a still valid Parquet file.
    path = directory / "predictions.parquet"
    table = pq.read_table(path)
    column = table.column("y_pred").to_pylist()
    column[0] += 1.0
    pq.write_table(table.set_column(4, "y_pred", pa.array(column)), path)
    with pytest.raises(SurrogateError, match=r"predictions\.parquet: changed since it was stored"):
        SurrogateSet.load(directory)
    path.write_bytes(before["predictions.parquet"])
    SurrogateSet.load(directory)
    # A missing file, and a marker that does not list one.
    (directory / "validation.parquet").unlink()
    with pytest.raises(SurrogateError, match=r"validation\.parquet: missing"):
        SurrogateSet.load(directory)
    (directory / "validation.parquet").write_bytes(before["validation.parquet"])
    del meta["files"]["models.parquet"]
    (directory / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(SurrogateError, match=r"meta\.json: lists no models\.parquet"):
        SurrogateSet.load(directory)


def test_an_interrupted_save_is_completed_by_the_next_one(fitted, tmp_path):
    """Files without meta.json are what an interrupted save left: replaced, not refused."""
    fit, _ = fitted
    directory = tmp_path / "set"
    directory.mkdir()
    (directory / "models.parquet").write_bytes(b"half a table")
    (directory / "validation.parquet").write_bytes(b"not parquet")
    fit.save(directory, meta={})
    back = SurrogateSet.load(directory)
    pd.testing.assert_frame_equal(back.validation, fit.validation)


def test_training_data_hash_tracks_every_value():
    x, outputs, feasible = chain_like(20, seed=1)
    base = training_data_hash(x, outputs, feasible)
    assert len(base) == 16 and int(base, 16) >= 0
    assert training_data_hash(x.copy(), dict(reversed(outputs.items())), feasible) == base
    changed = x.copy()
    changed[3, 1] = np.nextafter(changed[3, 1], np.inf)
    assert training_data_hash(changed, outputs, feasible) != base
    other = {k: v.copy() for k, v in outputs.items()}
    first_feasible = np.flatnonzero(feasible)[0]
    other["dv_mps"][first_feasible] += 1e-9
    assert training_data_hash(x, other, feasible) != base
    flipped = feasible.copy()
    flipped[0] = not flipped[0]
    assert training_data_hash(x, outputs, flipped) != base
    renamed = {"dv": outputs["dv_mps"], "t_h": outputs["t_h"]}
    assert training_data_hash(x, renamed, feasible) != base


def test_fit_is_deterministic(fitted, settings):
    fit, (x, outputs, feasible, ids) = fitted
    again = fit_surrogates(
        x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES, sample_ids=ids
    )
    probe = qmc.scale(qmc.LatinHypercube(d=3, seed=3).random(100), LOWER, UPPER)
    for name in fit.output_names:
        np.testing.assert_array_equal(again.predict(probe)[name], fit.predict(probe)[name])
    np.testing.assert_array_equal(again.feasibility(probe), fit.feasibility(probe))
    pd.testing.assert_frame_equal(
        again.validation.drop(columns="fit_time_s"), fit.validation.drop(columns="fit_time_s")
    )
    pd.testing.assert_frame_equal(again.predictions, fit.predictions)
    assert again.selected == fit.selected and again.data_hash == fit.data_hash


def test_two_fits_of_the_same_data_store_identical_tables(fitted, settings, tmp_path):
    """Timing is kept in meta.json, not in the tables, and comes back on load."""
    fit, (x, outputs, feasible, ids) = fitted
    again = fit_surrogates(
        x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES, sample_ids=ids
    )
    for name, surrogates in (("a", fit), ("b", again)):
        surrogates.save(tmp_path / name, meta={})
    for table in ("validation.parquet", "predictions.parquet"):
        assert (tmp_path / "a" / table).read_bytes() == (tmp_path / "b" / table).read_bytes()
    loaded = SurrogateSet.load(tmp_path / "a")
    pd.testing.assert_series_equal(loaded.validation["fit_time_s"], fit.validation["fit_time_s"])


# -- errors and failing candidates --------------------------------------------------------


def _data(n=30, seed=0):
    u, x = lhs(n, seed)
    return x, {"y": u.sum(axis=1)}, np.ones(n, bool)


def _case(name):
    x, outputs, feasible = _data()
    kwargs = {"input_names": NAMES}
    lower, upper = LOWER, UPPER
    if name == "no samples":
        x, outputs, feasible = np.empty((0, 3)), {"y": np.empty(0)}, np.empty(0, bool)
    elif name == "all infeasible":
        feasible = np.zeros(30, bool)
    elif name == "too few":
        x, outputs, feasible = _data(n=9)  # 2 of 9 held out: 7 < min_training_samples = 8
    elif name == "output shape":
        outputs = {"y": outputs["y"][:-1]}
    elif name == "feasible shape":
        feasible = feasible[:-1]
    elif name == "feasible dtype":
        feasible = feasible.astype(int)
    elif name == "names":
        kwargs["input_names"] = NAMES[:2]
    elif name == "X 1-D":
        x = x[:, 0]
    elif name == "NaN in X":
        x = x.copy()
        x[3, 2] = np.nan
    elif name == "NaN in output":
        outputs = {"y": outputs["y"].copy()}
        outputs["y"][5] = np.nan
    elif name == "bounds":
        lower = UPPER.copy()
    elif name == "bounds size":
        lower, upper = LOWER[:2], UPPER[:2]
    return x, outputs, feasible, lower, upper, kwargs


@pytest.mark.parametrize(
    ("case", "words"),
    [
        ("no samples", r"no samples: X has 0 rows"),
        ("all infeasible", r"all 30 samples are infeasible"),
        (
            "too few",
            r"^7 feasible training samples \(9 feasible of 9, 2 held out\); at least 8 are "
            r"needed \(surrogate\.min_training_samples\): evaluate more samples",
        ),
        ("output shape", r"output 'y': expected shape \(30,\).*got \(29,\)"),
        ("feasible shape", r"feasible: expected a boolean array of shape \(30,\)"),
        ("feasible dtype", r"feasible: expected a boolean array.*dtype int"),
        ("names", r"input_names: 2 names"),
        ("X 1-D", r"X: expected a 2-D array"),
        ("NaN in X", r"X: NaN or infinite inputs at sample_id \[3\]"),
        ("NaN in output", r"output 'y': NaN or infinite values at feasible samples.*\[5\]"),
        ("bounds", r"lower must be < upper"),
        ("bounds size", r"bounds: 2 lower/upper values for X with 3 columns"),
    ],
)
def test_unusable_data_raises(settings, case, words):
    x, outputs, feasible, lower, upper, kwargs = _case(case)
    with pytest.raises(SurrogateError, match=words):
        fit_surrogates(x, outputs, feasible, lower, upper, settings, **kwargs)


def test_nan_at_infeasible_samples_is_accepted(settings):
    x, outputs, feasible = chain_like(40, seed=2)
    assert np.isnan(outputs["t_h"][~feasible]).all() and (~feasible).sum() >= 4
    quick = settings.model_copy(update={"regressors": ["QP"], "classifiers": ["logistic"]})
    fit = fit_surrogates(x, outputs, feasible, LOWER, UPPER, quick, input_names=NAMES)
    assert np.isfinite(fit.predict(x)["t_h"]).all()


def test_the_registry_declares_each_configurable_candidate_once(settings, scenario_data):
    """The config accepts the registry's candidates and no other, naming the field; every
    one builds from the settings, and a name outside the registry is refused by it."""
    from ovtraj.config import scenario_from_dict
    from ovtraj.config.mission import LargeSampleSettings
    from ovtraj.config.surrogate_candidates import CLASSIFIER_NAMES, REGRESSOR_NAMES
    from ovtraj.surrogate.candidates import (
        CLASSIFIERS,
        REGRESSORS,
        CandidateError,
        classifier,
        regressor,
    )

    assert tuple(REGRESSORS) == REGRESSOR_NAMES and tuple(CLASSIFIERS) == CLASSIFIER_NAMES
    assert {c.kind for c in REGRESSORS.values()} == {"regressor"}
    assert {c.kind for c in CLASSIFIERS.values()} == {"classifier"}
    sizes = {"exact_max_samples": 10, "cv_max_samples": 10, "gbt_iterations": 5}
    trees = {"gbt_learning_rate": 0.1, "gbt_leaf_nodes": 4, "gbt_min_samples_leaf": 2}
    large = settings.model_copy(update={"large_samples": LargeSampleSettings(**sizes, **trees)})
    for name in REGRESSOR_NAMES:
        assert hasattr(regressor(name).build(3, large, None), "predict_values")
    flags = np.array([True, False] * 4)
    for name in CLASSIFIER_NAMES:
        assert hasattr(classifier(name).build(flags, settings, None), "fit")
    with pytest.raises(CandidateError, match=r"unknown regressor 'SVR' \(allowed: KRG, KPLS"):
        regressor("SVR")
    with pytest.raises(CandidateError, match=r"unknown classifier 'KRG' \(allowed: svc, gpc"):
        classifier("KRG")
    scenario_data["mission"]["surrogate"]["regressors"] = ["KRG", "SVR"]
    with pytest.raises(ValueError, match=r"surrogate\.regressors\.1"):
        scenario_from_dict(scenario_data, "test")


class BrokenRBF(RBF):
    def _train(self):
        raise np.linalg.LinAlgError("singular matrix (test)")


def test_failing_candidates_are_recorded_not_selected(settings, monkeypatch):
    monkeypatch.setattr(candidates_module, "RBF", BrokenRBF)
    # 14 samples: 10 feasible for training, 8 per CV fold: too few for QP's 10 coefficients.
    x, outputs, feasible = _data(n=14, seed=3)
    feasible[[2, 9]] = False  # two infeasible: one held out, one left for training
    outputs["y"][[2, 9]] = np.nan
    settings = settings.model_copy(update={"classifiers": ["svc", "gpc", "logistic"]})
    fit = fit_surrogates(x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES)
    rows = fit.validation.set_index(["model", "candidate"])
    assert "QP needs at least 10 training samples in 3-D" in rows.loc[("y", "QP"), "error"]
    assert "LinAlgError: singular matrix (test)" in rows.loc[("y", "RBF"), "error"]
    # A single infeasible training sample cannot be Platt-calibrated.
    assert "at least 2 samples of each class" in rows.loc[("feasible", "svc"), "error"]
    for key in [("y", "QP"), ("y", "RBF"), ("feasible", "svc")]:
        assert not rows.loc[key, "selected"]
        assert rows.loc[key, ["cv_rmse", "cv_accuracy", "heldout_r2"]].isna().all()
    assert fit.selected["y"] in {"KRG", "KPLS"} and fit.selected["feasible"] in {"gpc", "logistic"}
    only_broken = settings.model_copy(update={"regressors": ["RBF", "QP"]})
    with pytest.raises(SurrogateError, match="output 'y': no candidate could be fitted"):
        fit_surrogates(x, outputs, feasible, LOWER, UPPER, only_broken, input_names=NAMES)


def _fit_again(fitted, settings, **options):
    """The ``fitted`` fixture's data fitted again with ``options``."""
    _, (x, outputs, feasible, ids) = fitted
    return fit_surrogates(
        x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES, sample_ids=ids, **options
    )


def test_kept_candidates_are_refitted_alone_and_fall_back_when_they_fail(
    fitted, settings, monkeypatch
):
    """``candidates`` (an earlier fit's choice): one row per model, same CV folds."""
    fit, (x, outputs, feasible, _) = fitted
    kept = {"t_h": "RBF", "dv_mps": "QP", "feasible": "logistic"}
    again = _fit_again(fitted, settings, candidates=kept)
    assert again.selected == kept
    assert again.validation.groupby("model")["candidate"].apply(list).to_dict() == {
        name: [choice] for name, choice in kept.items()
    }
    # The same candidate scores the same as in the full comparison (same folds, same seed).
    full = fit.validation.set_index(["model", "candidate"])
    for row in again.validation.itertuples():
        metric = "cv_balanced_accuracy" if row.model == "feasible" else "cv_rmse"
        assert getattr(row, metric) == full.loc[(row.model, row.candidate), metric]
    # A kept candidate that cannot be fitted now: every configured candidate is compared.
    monkeypatch.setattr(candidates_module, "RBF", BrokenRBF)
    fallback = fit_surrogates(
        x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES, candidates=kept
    )
    assert fallback.selected["t_h"] != "RBF"
    assert set(fallback.validation.query("model == 't_h'")["candidate"]) == set(settings.regressors)


def test_a_shortlist_compares_the_first_fits_best_candidates_only(fitted, settings):
    """``selection: shortlist``: each output's two lowest-CV-RMSE candidates of a fit, and
    its classifier; a fit given them compares only those, with the same figures."""
    from ovtraj.surrogate.compared_candidates import shortlist

    fit = fitted[0]
    kept = shortlist(fit.validation, 2)
    for name in ("t_h", "dv_mps"):
        rows = fit.validation.query("model == @name").dropna(subset=["cv_rmse"])
        assert kept[name] == rows.nsmallest(2, "cv_rmse")["candidate"].tolist()
        assert kept[name][0] == fit.selected[name]  # the selection's own criterion first
    assert kept["feasible"] == fit.selected["feasible"]
    again = _fit_again(fitted, settings, candidates=kept)
    compared = again.validation.groupby("model")["candidate"].apply(set).to_dict()
    assert compared == {name: set(k) if isinstance(k, list) else {k} for name, k in kept.items()}
    assert again.selected == fit.selected  # the best of the two is still the best
    full = fit.validation.set_index(["model", "candidate"])["cv_rmse"]
    for row in again.validation.query("kind == 'regressor'").itertuples():
        assert row.cv_rmse == full.loc[(row.model, row.candidate)]


def test_candidates_scored_in_processes_give_the_fit_of_this_process(fitted, settings):
    """On a pool of two spawned processes (the pipeline's ``processes`` runner): the same
    selection, figures and predictions; only the measured fit times differ."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    fit = fitted[0]
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(2, mp_context=spawn) as pool:
        parallel = _fit_again(fitted, settings, executor=pool)
    assert parallel.selected == fit.selected
    figures = [c for c in fit.validation.columns if c != "fit_time_s"]
    pd.testing.assert_frame_equal(parallel.validation[figures], fit.validation[figures])
    pd.testing.assert_frame_equal(parallel.predictions, fit.predictions)
    _, grid = lhs(200, seed=9)
    for name, values in fit.predict(grid).items():
        np.testing.assert_array_equal(parallel.predict(grid)[name], values, err_msg=name)


def test_heldout_r2_is_na_with_one_heldout_feasible_sample(settings):
    x, outputs, feasible = _data(n=10, seed=6)
    quick = settings.model_copy(
        update={"regressors": ["RBF"], "holdout_fraction": 0.1, "min_training_samples": 4}
    )
    fit = fit_surrogates(x, outputs, feasible, LOWER, UPPER, quick, input_names=NAMES)
    row = fit.validation.query("model == 'y'").iloc[0]
    assert row["n_heldout"] == 1
    assert row["heldout_r2"] is pd.NA and row["heldout_rmse"] >= 0


# -- plots ---------------------------------------------------------------------------------


def test_parity_plots_one_png_per_output(fitted, tmp_path):
    fit, _ = fitted
    paths = parity_plots(fit, tmp_path / "plots")
    assert [p.name for p in paths] == ["parity-t_h.png", "parity-dv_mps.png"]
    for path in paths:
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == sorted(p.name for p in paths)


def _recorded_kriging_starts(monkeypatch) -> list[np.ndarray]:
    """Every start of SMT's TNC likelihood maximisation from now on (log10 theta)."""
    seen: list[np.ndarray] = []
    tnc = TNCOptimizer
    original = tnc._minimize

    def recording(self, objective, x0, *args):
        seen.append(np.array(x0))
        return original(self, objective, x0, *args)

    monkeypatch.setattr(tnc, "_minimize", recording)
    return seen


@pytest.mark.parametrize(("random_start", "starts"), [(True, 2), (False, 1)])
def test_kriging_random_start_setting(settings, monkeypatch, random_start, starts):
    # SMT runs theta0 and a seeded random start; without the random one, theta0 alone
    # (SMT's default 0.01 per input, log10 -2 in the optimiser's variables).
    seen = _recorded_kriging_starts(monkeypatch)
    u, _ = lhs(20, 3)
    y = np.sin(3.0 * u[:, 0]) + u[:, 1] ** 2
    chosen = settings.model_copy(update={"kriging_random_start": random_start})
    fit_regressor("KRG", u, y, chosen)
    assert len(seen) == starts
    np.testing.assert_array_equal(seen[0], np.full(u.shape[1], -2.0))


def test_cv_warm_start_keeps_the_models_and_starts_the_folds_from_them(settings, monkeypatch):
    # The whole training part's fit is the model kept: unchanged by the option; each
    # Kriging fold starts from that fit's hyperparameters alone.
    x, outputs, feasible = chain_like(40, seed=9)
    restricted = {name: "KRG" for name in outputs}

    def fit(warm: bool):
        chosen = settings.model_copy(update={"cv_warm_start": warm})
        return fit_surrogates(
            x, outputs, feasible, LOWER, UPPER, chosen, input_names=NAMES, candidates=restricted
        )

    cold = fit(False)
    starts = _recorded_kriging_starts(monkeypatch)
    warm = fit(True)
    grid = lhs(200, 3)[1]
    cold_values, warm_values = cold.predict(grid), warm.predict(grid)
    for name in outputs:
        np.testing.assert_array_equal(warm_values[name], cold_values[name])
        theta = np.log10(warm.regressor(name).model.optimal_theta)
        from_whole = [s for s in starts if np.allclose(s, theta, rtol=0, atol=1e-12)]
        assert len(from_whole) == settings.folds
    # Two starts for each whole fit, one for each fold.
    assert len(starts) == len(outputs) * (2 + settings.folds)
    cv = warm.validation.set_index("model")["cv_rmse"]
    reference = cold.validation.set_index("model")["cv_rmse"]
    for name in outputs:
        assert cv[name] == pytest.approx(reference[name], rel=0.5)


# -- outputs fitted on some of the inputs -------------------------------------------------


def test_an_output_fitted_on_its_own_inputs_ignores_the_others(settings, tmp_path):
    # y depends on the first input alone; z on all three. Repeats of the first input (a
    # bound hit by several designs) must not reach y's Kriging fit.
    u, x = lhs(40, seed=21)
    x[:6, 0] = LOWER[0]
    feasible = np.ones(40, dtype=bool)
    y = 100.0 + 20.0 * np.sin(3.0 * u[:, 0]) + 5.0 * u[:, 0] ** 2
    y[:6] = 100.0  # the value at u0 = 0
    z = 50.0 + 10.0 * u[:, 1] - 4.0 * u[:, 2] + 2.0 * u[:, 0]
    fit = fit_surrogates(
        x,
        {"y": y, "z": z},
        feasible,
        LOWER,
        UPPER,
        settings,
        input_names=NAMES,
        output_inputs={"y": [NAMES[0]]},
    )
    assert fit.output_inputs == {"y": (NAMES[0],)}
    # Designs that differ in the other inputs only: the same y, different z.
    probe = np.column_stack(
        [np.full(9, 300.0), np.linspace(300.0, 380.0, 9), np.linspace(0.0, 24.0, 9)]
    )
    predicted = fit.predict(probe)
    # (to rounding: SMT's batched products may round a row differently by its position)
    np.testing.assert_allclose(predicted["y"], predicted["y"][0], rtol=1e-10)
    assert np.ptp(predicted["z"]) > 1.0
    u0 = (300.0 - LOWER[0]) / (UPPER[0] - LOWER[0])
    exact = 100.0 + 20.0 * np.sin(3.0 * u0) + 5.0 * u0**2
    assert abs(predicted["y"][0] - exact) < 0.5  # 40 samples of a 1-D function
    # y trained on the first of the repeated designs only: its CV rows count them once.
    rows = fit.predictions
    y_cv = rows[(rows["model"] == "y") & (rows["split"] == "cv")]
    z_cv = rows[(rows["model"] == "z") & (rows["split"] == "cv")]
    assert len(z_cv) + int(((rows["model"] == "z") & (rows["split"] == "heldout")).sum()) == 40
    repeats_in_training = int(np.isin(z_cv["sample_id"], np.arange(6)).sum())
    assert repeats_in_training >= 2
    assert len(y_cv) == len(z_cv) - max(repeats_in_training - 1, 0)
    # Stored and read back: the inputs go with the models, and meta.json names them.
    fit.save(tmp_path / "set", meta={})
    meta = json.loads((tmp_path / "set" / "meta.json").read_text())
    assert meta["output_inputs"] == {"y": [NAMES[0]]}
    back = SurrogateSet.load(tmp_path / "set")
    assert back.output_inputs == fit.output_inputs
    for name in ("y", "z"):
        np.testing.assert_array_equal(back.predict(probe)[name], predicted[name])


def test_without_own_inputs_the_fit_is_unchanged(fitted, settings):
    fit, (_, outputs, _, _) = fitted
    again = _fit_again(fitted, settings, output_inputs={name: list(NAMES) for name in outputs})
    # All three inputs and no repeated design: the same training rows, folds and models.
    pd.testing.assert_frame_equal(
        again.validation.drop(columns="fit_time_s"), fit.validation.drop(columns="fit_time_s")
    )
    probe = qmc.scale(qmc.LatinHypercube(d=3, seed=9).random(50), LOWER, UPPER)
    for name in fit.output_names:
        np.testing.assert_array_equal(again.predict(probe)[name], fit.predict(probe)[name])
    assert fit.output_inputs == {} and again.output_inputs == {n: NAMES for n in outputs}


@pytest.mark.parametrize(
    ("output_inputs", "words"),
    [
        ({"nope": [NAMES[0]]}, r"output_inputs: 'nope' is not an output"),
        ({"t_h": ["altitude"]}, r"output_inputs\['t_h'\]: \['altitude'\] must be one or more"),
        ({"t_h": []}, r"output_inputs\['t_h'\]: \[\] must be one or more"),
    ],
)
def test_unknown_own_inputs_are_named(settings, output_inputs, words):
    x, outputs, feasible = chain_like(30, seed=2)
    with pytest.raises(SurrogateError, match=words):
        fit_surrogates(
            x,
            outputs,
            feasible,
            LOWER,
            UPPER,
            settings,
            input_names=NAMES,
            output_inputs=output_inputs,
        )


def test_samples_left_out_of_one_output_reach_only_the_others(settings):
    # y is smooth except on 6 samples of another regime (+40): left out of y's fit, they
    # neither enter its training, folds or hold-out nor bend its predictions, while z
    # (and feasibility) keep every sample.
    u, x = lhs(40, seed=23)
    feasible = np.ones(40, dtype=bool)
    y = 80.0 + 10.0 * u[:, 1] + 2.0 * u[:, 0]
    other = np.zeros(40, dtype=bool)
    other[[3, 9, 14, 22, 30, 37]] = True
    spiked = np.where(other, y + 40.0, y)
    z = 50.0 + 10.0 * u[:, 1] - 4.0 * u[:, 2]
    common = dict(input_names=NAMES)
    kept = fit_surrogates(x, {"y": spiked, "z": z}, feasible, LOWER, UPPER, settings, **common)
    fit = fit_surrogates(
        x,
        {"y": spiked, "z": z},
        feasible,
        LOWER,
        UPPER,
        settings,
        **common,
        left_out={"y": other},
    )
    rows = fit.predictions
    y_rows = rows[rows["model"] == "y"]
    z_rows = rows[rows["model"] == "z"]
    assert not np.isin(y_rows["sample_id"], np.flatnonzero(other)).any()
    assert len(y_rows) == 40 - other.sum() and len(z_rows) == 40
    probe = qmc.scale(qmc.LatinHypercube(d=3, seed=4).random(30), LOWER, UPPER)
    smooth = 80.0 + 10.0 * (probe[:, 1] - LOWER[1]) / 80.0 + 2.0 * (probe[:, 0] - LOWER[0]) / 100.0
    error_without = np.abs(fit.predict(probe)["y"] - smooth).max()
    error_with = np.abs(kept.predict(probe)["y"] - smooth).max()
    assert error_without < 0.5 < 5.0 < error_with
    np.testing.assert_array_equal(fit.predict(probe)["z"], kept.predict(probe)["z"])


@pytest.mark.parametrize(
    ("left_out", "words"),
    [
        ({"nope": np.zeros(30, dtype=bool)}, r"left_out: 'nope' is not an output"),
        ({"t_h": np.zeros(29, dtype=bool)}, r"left_out\['t_h'\]: expected a boolean array"),
        ({"t_h": np.zeros(30)}, r"left_out\['t_h'\]: expected a boolean array"),
        ({"t_h": np.ones(30, dtype=bool)}, r"output 't_h': 0 feasible training samples once"),
    ],
)
def test_unusable_left_out_samples_are_named(settings, left_out, words):
    x, outputs, feasible = chain_like(30, seed=2)
    with pytest.raises(SurrogateError, match=words):
        fit_surrogates(
            x, outputs, feasible, LOWER, UPPER, settings, input_names=NAMES, left_out=left_out
        )
