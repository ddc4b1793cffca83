"""The surrogate pipeline on the real mission chain.

A 20-sample DoE of the default scenario, then surrogates, NSGA-II, verification of
front points with the real chain and infill; the plan of a front point and its replay.
The references are the real chain itself (run again, outside the store) and the
stored totals; replay must simulate nothing and give the same front.
"""

from __future__ import annotations

import copy
import hashlib
import html
import json
import re
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.config import scenario_from_dict
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, MissionRecord, evaluate
from ovtraj.optimize import Normalisation
from ovtraj.pipeline import (
    PipelineError,
    PipelineSteps,
    fit_step,
    front_step,
    run_pipeline,
    training_data,
)
from ovtraj.pipeline.loop import load_pipeline
from ovtraj.runs import RunStore, StoreError, execute, prepare_run, run_doe
from ovtraj.surrogate import SurrogateError
from ovtraj.version import code_version
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario, digest, prefect_record

OBJECTIVES = ("t_total_s", "dv_total_mps", "m_load_kg")


def _data(**verify) -> dict:
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    # The loop runs its rounds to the budget here (its stops are tested on their own,
    # below): a promise tolerance no surrogate front meets.
    data["mission"]["verify"]["promise_tolerance"] = 1e-12
    data["mission"]["verify"].update(verify)
    # Two regressors, one classifier, 3 folds: the candidates' mechanics are tested in
    # test_surrogate.py; here the pipeline around them (keeps the suite in budget).
    data["mission"]["surrogate"].update(
        regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3
    )
    data["mission"]["optimize"].update(population=32, generations=40)
    return data


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pipeline")
    data = _data(points_per_iteration=3, max_iterations=2, budget=6)
    config = tmp / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    scenario = build_scenario(copy.deepcopy(data))
    store = RunStore(tmp / "runs")
    fit = find_launch_fit(scenario)

    def evaluate_run(run):
        return run_doe(scenario, run, fit, batch_size=scenario.mission.doe.batch_size)

    # The CLI's code version, so that `ovtraj optimize --refit` finds these stored fits.
    code = code_version()
    doe = prepare_run(scenario, samples=20, seed=2026, code=code, store=store)
    evaluate_run(doe)
    before = execute.EVALUATIONS["count"]
    result = run_pipeline(
        scenario, doe, store=store, code=code, steps=PipelineSteps(evaluate=evaluate_run)
    )
    return {
        "scenario": scenario,
        "config": config,
        "store": store,
        "fit": fit,
        "doe": doe,
        "result": result,
        "infill_evaluations": execute.EVALUATIONS["count"] - before,
        "evaluate_run": evaluate_run,
        "code": code,
    }


def test_front_points_are_verified_with_the_real_chain(small):
    result, store = small["result"], small["store"]
    final = store.run(result.final_run)
    spent = result.summary["real_evaluations"]
    assert spent == {"doe": 20, "infill": small["infill_evaluations"]}
    assert 1 <= spent["infill"] <= 6 and len(result.verification) == spent["infill"]
    # Every front value is the stored real value of its sample.
    totals = final.totals().set_index("sample_id")
    front = result.front
    assert len(front) >= 2 and set(front["origin"]) <= {"doe", "infill 1", "infill 2"}
    for name in OBJECTIVES:
        assert np.array_equal(
            front[name].to_numpy(), totals.loc[front["sample_id"], name].to_numpy(dtype=float)
        )
    # The chain run again, outside the store, gives the verified points' real values.
    context = MissionContext(small["scenario"], small["fit"])
    for row in result.verification.head(2).itertuples(index=False):
        record = evaluate(context, MissionDesign(*(getattr(row, n) for n in DESIGN_NAMES)))
        assert record.feasible == row.real_feasible
        if record.feasible:
            assert record.t_total_s == pytest.approx(row.real_t_total_s, rel=1e-9)
            assert record.dv_total_mps == pytest.approx(row.real_dv_total_mps, rel=1e-9)
            assert record.m_load_kg == pytest.approx(row.real_m_load_kg, rel=1e-12)
    # The errors are the predicted-to-real differences over the ideal-to-reference span.
    span = Normalisation.mission(small["scenario"].mission.optimize).span()
    feasible = result.verification[result.verification["real_feasible"]]
    for k, name in enumerate(OBJECTIVES):
        expected = (feasible[f"predicted_{name}"] - feasible[f"real_{name}"]).abs() / span[k]
        assert np.allclose(feasible[f"error_{name}"], expected)
    # Non-dominated, and it holds the best feasible value of each objective.
    values = front[list(OBJECTIVES)].to_numpy() * np.array([1, 1, -1])
    for i in range(len(values)):
        dominated = np.all(values <= values[i], axis=1) & np.any(values < values[i], axis=1)
        assert not dominated.any()
    feasible_totals = totals[totals["feasible"].astype(bool)]
    assert front["t_total_s"].min() == feasible_totals["t_total_s"].min()
    assert front["dv_total_mps"].min() == feasible_totals["dv_total_mps"].min()
    assert front["m_load_kg"].max() == feasible_totals["m_load_kg"].max()
    stored = json.loads((result.directory / "pipeline.json").read_text())
    assert (
        stored["final_run"] == result.final_run and (result.directory / "front.png").stat().st_size
    )


def _verify_changed(scenario, **update):
    verify = scenario.mission.verify.model_copy(update=update)
    changed = scenario.model_copy(
        update={"mission": scenario.mission.model_copy(update={"verify": verify})}
    )
    return changed, verify


def test_the_loop_converges_once_the_surrogates_promise_nothing_more(small, tmp_path):
    from ovtraj.optimize import non_dominated
    from ovtraj.optimize.infill import promised_gain
    from ovtraj.pipeline.report import stop_explanation
    from ovtraj.pipeline.steps import load_front, unit_designs

    scenario, store = small["scenario"], _copied_store(small, tmp_path)
    rounds = small["result"].summary["iterations"]
    # Every round records what its surrogate front promised beyond the real front of the
    # samples it was fitted on; the last check follows the last verification (budget spent).
    assert len(rounds) == 3 and small["result"].summary["stop_reason"] in (
        "budget",
        "max_iterations",
    )
    assert small["result"].summary["converged"] is False
    normalisation = Normalisation.mission(scenario.mission.optimize)
    for record in rounds:
        run = store.run(record["run_id"])
        data = training_data(run)
        front = load_front(run.directory / "fronts" / record["front_id"], normalisation)
        real = normalisation.normalise(
            np.column_stack([data.outputs[n] for n in normalisation.names])[data.feasible]
        )
        expected = promised_gain(
            front.normalised,
            unit_designs(scenario, front.designs.to_numpy()),
            unit_designs(scenario, data.designs),
            real[non_dominated(real)],
            scenario.mission.verify.min_distance,
        )
        assert record["promised_gain"] == pytest.approx(expected, rel=1e-9)
    text = stop_explanation(small["result"].summary, scenario.mission.verify)
    assert text.startswith("not converged") and f"{rounds[-1]['promised_gain']:.2%}" in text
    # A tolerance above the second check's promise: converged there, after one round of
    # verification, the stored child run reused (nothing simulated).
    tolerance = rounds[1]["promised_gain"] * 1.01
    converging, verify = _verify_changed(scenario, promise_tolerance=tolerance)
    before = execute.EVALUATIONS["count"]
    result = run_pipeline(
        converging,
        store.run(small["doe"].id),
        store=store,
        code=small["code"],
        steps=PipelineSteps(evaluate=small["evaluate_run"]),
    )
    assert execute.EVALUATIONS["count"] == before
    summary = result.summary
    assert summary["stop_reason"] == "converged" and summary["converged"] is True
    assert len(summary["iterations"]) == 2 and summary["final_run"] == rounds[0]["infill_run"]
    text = stop_explanation(summary, verify)
    assert text.startswith("converged") and f"{tolerance:.2%}" in text
    assert f"{rounds[1]['promised_gain']:.2%}" in text


def test_the_direct_reference_is_reported_for_its_own_scenario_only(small):
    from ovtraj.pipeline.reference_front import load, reference_for

    reference = load()
    assert reference is not None and reference.matches(small["scenario"])
    summary = small["result"].summary
    assert summary["reference_hypervolume"] == reference.hypervolume
    assert summary["reference_ratio"] == pytest.approx(
        summary["hypervolume"] / reference.hypervolume, rel=1e-12
    )
    # Another chain (a longer stay) is not the scenario the reference was made for.
    data = _data()
    data["mission"]["stay_h"] = 30.0
    assert reference_for(build_scenario(data)) is None


def test_the_loop_stops_when_a_round_no_longer_improves_the_real_front(small, tmp_path):
    from ovtraj.pipeline.loop import real_hypervolume
    from ovtraj.pipeline.report import stop_explanation

    # A copy: the pipeline below stores a result of its own, which the other tests of the
    # shared fixture must not see.
    scenario, store = small["scenario"], _copied_store(small, tmp_path)
    normalisation = Normalisation.mission(scenario.mission.optimize)
    rounds = small["result"].summary["iterations"]
    # Each verified round records the real front's hypervolume and its relative gain.
    doe = store.run(small["doe"].id)
    parent = doe
    verified = [record for record in rounds if "infill_run" in record]
    assert len(verified) == len(rounds) - 1  # the last check verifies nothing
    for record in verified:
        child = store.run(record["infill_run"])
        before = real_hypervolume(parent, normalisation)
        after = real_hypervolume(child, normalisation)
        assert record["real_hypervolume"] == pytest.approx(after, rel=1e-12)
        assert record["hypervolume_gain"] == pytest.approx((after - before) / before, rel=1e-9)
        parent = child
    first_gain = rounds[0]["hypervolume_gain"]
    assert first_gain >= 0.0
    # Without a promise tolerance (the configs stored before it), a hypervolume tolerance
    # above the first round's gain stops the loop there, converged: the same picks, so the
    # stored child run is reused and nothing is simulated.
    stable, verify = _verify_changed(
        scenario, hypervolume_tolerance=1.0, promise_tolerance=None, tolerance=1e-6
    )
    before = execute.EVALUATIONS["count"]
    result = run_pipeline(
        stable,
        doe,
        store=store,
        code=small["code"],
        steps=PipelineSteps(evaluate=small["evaluate_run"]),
    )
    assert execute.EVALUATIONS["count"] == before
    summary = result.summary
    assert summary["stop_reason"] == "front stable" and summary["converged"] is True
    assert len(summary["iterations"]) == 1 and summary["final_run"] == rounds[0]["infill_run"]
    text = stop_explanation(summary, verify)
    assert text.startswith("converged") and f"{first_gain:.2%}" in text and "100.00%" in text
    # With a promise tolerance the promise decides: a stable round is no stop of its own.
    assert small["result"].summary["stop_reason"] != "front stable"


def test_replay_refits_and_reoptimises_without_simulation_and_gives_the_same_front(small):
    result = small["result"]
    before = execute.EVALUATIONS["count"]
    steps = PipelineSteps(
        evaluate=small["evaluate_run"],
        fit=partial(fit_step, refit=True),
        front=partial(front_step, refit=True),
    )
    again = run_pipeline(
        small["scenario"], small["doe"], store=small["store"], code=small["code"], steps=steps
    )
    assert execute.EVALUATIONS["count"] == before
    pd.testing.assert_frame_equal(again.front, result.front)
    assert again.final_run == result.final_run
    # Refitting the DoE run's surrogates reproduces its stored front exactly (the rounds
    # store them without views).
    doe, scenario, code = small["doe"], small["scenario"], small["code"]
    fitted = fit_step(doe, training_data(doe), scenario, code, refit=True, views=False)
    assert not fitted.reused
    refront = front_step(doe, fitted, scenario, code, refit=True, views=False)
    assert refront.matches_stored is True
    assert not list(refront.directory.glob("*.png")) and not list(fitted.directory.glob("*.png"))
    # The pipeline drew the last round's views once, in its own directory.
    drawn = sorted(p.name for p in result.directory.glob("*.png"))
    assert "surrogate-front.png" in drawn and "front.png" in drawn
    assert any(name.startswith("parity-dv_rendezvous_mps") for name in drawn)
    files = json.loads((result.directory / "pipeline.json").read_text())["files"]
    assert set(drawn) <= set(files)


def test_parity_plots_begun_on_a_pool_during_the_rounds_give_the_same_files(small, tmp_path):
    """Each round's parity plots begun on a process pool while NSGA-II runs (as the CLI and
    the benchmark do): the same pipeline files, byte for byte, as drawn at the end."""
    import multiprocessing
    import shutil
    from concurrent.futures import ProcessPoolExecutor

    from ovtraj.pipeline import start_drawing

    result, doe = small["result"], small["doe"]
    copy_root = tmp_path / "runs"
    shutil.copytree(small["store"].root, copy_root)
    relative = result.directory.relative_to(small["store"].root)
    shutil.rmtree(copy_root / relative)  # the pipeline's own directory: drawn again
    store = RunStore(copy_root)
    begun = []
    before = execute.EVALUATIONS["count"]
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:

        def predraw(views):
            begun.append([view.file for view in views])
            return start_drawing(views, pool)

        again = run_pipeline(
            small["scenario"],
            store.run(doe.id),
            store=store,
            code=small["code"],
            steps=PipelineSteps(evaluate=small["evaluate_run"], predraw=predraw),
        )
    assert execute.EVALUATIONS["count"] == before  # every round's child run reused
    # Only a round that is surely the last begins its parity plots on the pool (the
    # others' would be thrown away); a round that stops early has them drawn at the end.
    rounds, verify = result.summary["iterations"], small["scenario"].mission.verify
    # (with a promise tolerance the fit after the last round's verification is a round)
    last = verify.max_iterations + (verify.promise_tolerance is not None)
    surely_last = len(rounds) == last or result.summary["stop_reason"] == "budget"
    assert len(begun) == (1 if surely_last else 0)
    assert all(name.startswith("parity-") for names in begun for name in names)
    drawn, stored = digest(again.directory, "*"), digest(result.directory, "*")
    assert {k: v for k, v in drawn.items() if k != "pipeline.json"} == {
        k: v for k, v in stored.items() if k != "pipeline.json"
    }
    assert any(name.startswith("parity-") for name in drawn)
    assert all(set(names) < set(drawn) for names in begun)
    markers = [
        json.loads((d / "pipeline.json").read_text()) for d in (again.directory, result.directory)
    ]
    for marker in markers:
        marker.pop("created_utc")
    assert markers[0] == markers[1]


def _fake_run(store, scenario, feasible: bool | None):
    """A run whose batch holds made-up records (no simulation), or none at all."""
    from ovtraj.runs import latin_hypercube

    samples = latin_hypercube(scenario.mission.design_bounds, 12, 5)
    run = store.create(resolved=scenario.resolved(), samples=samples, seed=5, code="fake")
    if feasible is not None:
        records = [
            MissionRecord(
                design=MissionDesign(*(getattr(r, n) for n in DESIGN_NAMES)),
                feasible=False,
                failed_stage="rendezvous",
                reason="made up",
            )
            for r in samples.itertuples(index=False)
        ]
        steps = execute.trajectory_steps(scenario)
        run.write_batch(0, records, samples["sample_id"].tolist(), trajectory_steps=steps)
    return run


def test_empty_and_all_infeasible_runs_are_refused_and_nothing_is_written(tmp_path, scenario):
    store = RunStore(tmp_path)
    steps = PipelineSteps(evaluate=lambda run: run)
    empty = _fake_run(store, scenario, None)
    before = digest(empty.directory, "*")
    with pytest.raises(StoreError, match="no evaluated samples"):
        run_pipeline(scenario, empty, store=store, code="fake", steps=steps)
    assert digest(empty.directory, "*") == before
    infeasible = _fake_run(RunStore(tmp_path / "other"), scenario, False)
    before = digest(infeasible.directory, "*")
    with pytest.raises(SurrogateError, match="all 12 samples are infeasible"):
        run_pipeline(scenario, infeasible, store=store, code="fake", steps=steps)
    assert digest(infeasible.directory, "*") == before


def test_cli_optimize_plan_and_fly(small, tmp_path):
    runner = CliRunner()
    root = str(small["store"].root)
    doe = small["doe"].id
    # Optimising the stored samples, then again with --refit: no simulation, the stored
    # front again. (The pipeline's rounds stored theirs without plots: another product.)
    before = execute.EVALUATIONS["count"]
    first = runner.invoke(app, ["optimize", doe, "--store", root])
    assert first.exit_code == 0, first.output
    done = runner.invoke(app, ["optimize", doe, "--refit", "--store", root])
    assert done.exit_code == 0, done.output
    assert re.search(r"identical to the stored front +True", done.output)
    assert execute.EVALUATIONS["count"] == before
    # Every output's model is listed, T_total's pass model too (it has no CV row).
    assert re.search(r"t_total_s model +pass model", done.output)
    listed = json.loads(runner.invoke(app, ["optimize", doe, "--store", root, "--json"]).output)
    assert {"model": "t_total_s", "candidate": "pass model"} in listed["models"]
    # A plan of the first front point, then its replay through the dynamics.
    done = runner.invoke(app, ["plan", doe, "--pick", "0", "--store", root])
    assert done.exit_code == 0, done.output
    plan_json = next(
        line.split(": ", 1)[1] for line in done.output.splitlines() if line.endswith(".json")
    )
    flown = runner.invoke(app, ["fly", plan_json, "--json"])
    assert flown.exit_code == 0, flown.output
    report = json.loads(flown.stdout)
    assert report["landed_within_stated_miss"] is True
    # Every file of the plan is listed with its digest, the flight fly stored beside it
    # too; the paths printed are absolute.
    plan_path = Path(plan_json)
    assert plan_path.is_absolute()
    marker = json.loads(plan_path.with_name(f"{plan_path.stem}.files.json").read_text())
    written = {
        Path(line.split(": ", 1)[1]).name
        for line in done.output.splitlines()
        if line.startswith(("plan: ", "plot: ", "report: "))
    }
    stored = flown.stderr.splitlines()[0].split(": ", 1)[1]
    assert stored == str(plan_path.with_name(f"{plan_path.stem}-flight-j2.json"))
    assert set(marker["files"]) == written | {Path(stored).name} and len(written) >= 5
    # Planning the point again writes the same report, the stored flight in it.
    flown_report = plan_path.with_name(f"{plan_path.stem}-report.html").read_bytes()
    again = runner.invoke(app, ["plan", doe, "--pick", "0", "--store", root])
    assert again.exit_code == 0, again.output
    assert plan_path.with_name(f"{plan_path.stem}-report.html").read_bytes() == flown_report
    assert json.loads(plan_path.with_name(f"{plan_path.stem}.files.json").read_text()) == marker
    assert done.output.startswith("picked front point 0 (") and "--pick 0" in done.output
    checked = small["doe"].verify()
    assert checked.clean and not checked.uncovered, (checked.problems, checked.uncovered)
    # Bad inputs: clear errors, nothing written.
    plans = small["result"].directory / "plans"
    before = digest(plans, "*")
    done = runner.invoke(app, ["plan", doe, "--pick", "99", "--store", root])
    assert done.exit_code == 2 and "outside the front" in done.output
    done = runner.invoke(app, ["plan", "0123456789abcdef", "--store", root])
    assert done.exit_code == 2 and "no such run" in done.output
    done = runner.invoke(app, ["optimize", "0123456789abcdef", "--store", root])
    assert done.exit_code == 2 and "no such run" in done.output
    assert digest(plans, "*") == before


def _rewrite_value(path, column: str, delta: float) -> None:
    """One value of a stored Parquet file changed; the file stays valid Parquet."""
    table = pq.read_table(path)
    values = table.column(column).to_pylist()
    values[0] += delta
    index = table.schema.get_field_index(column)
    pq.write_table(
        table.set_column(index, column, pa.array(values, table.schema.field(column).type)), path
    )


def test_pipeline_refuses_a_changed_or_different_result_for_the_same_inputs(small):
    """A stored pipeline result is checked on every read and never overwritten."""
    result = small["result"]
    before = digest(result.directory, "*")
    front_file, marker = result.directory / "front.parquet", result.directory / "pipeline.json"
    stored = {path: path.read_bytes() for path in (front_file, marker)}

    def again():
        return run_pipeline(
            small["scenario"],
            small["doe"],
            store=small["store"],
            code=small["code"],
            steps=PipelineSteps(evaluate=small["evaluate_run"]),
        )

    try:
        _rewrite_value(front_file, "dv_total_mps", 1.0)
        with pytest.raises(StoreError, match=r"front\.parquet: changed since it was stored"):
            again()
        with pytest.raises(StoreError, match=r"front\.parquet: changed since it was stored"):
            load_pipeline(result.directory)
        # As if the stored result came from other code: consistent, but different.
        summary = json.loads(stored[marker])
        payload = front_file.read_bytes()
        summary["files"]["front.parquet"] = {
            "bytes": len(payload),
            "sha256": hashlib.sha256(payload).hexdigest(),
        }
        marker.write_text(json.dumps(summary))
        assert load_pipeline(result.directory).front.loc[0, "dv_total_mps"] == pytest.approx(
            result.front.loc[0, "dv_total_mps"] + 1.0
        )
        with pytest.raises(PipelineError, match="differs"):
            again()
        after = digest(result.directory, "*")
        changed = {"front.parquet", "pipeline.json"}
        assert {k: v for k, v in after.items() if k not in changed} == {
            k: v for k, v in before.items() if k not in changed
        }
    finally:
        for path, payload in stored.items():
            path.write_bytes(payload)
    (result.directory / "verification.parquet").rename(result.directory / "moved.parquet")
    try:
        with pytest.raises(StoreError, match=r"verification\.parquet: missing"):
            load_pipeline(result.directory)
    finally:
        (result.directory / "moved.parquet").rename(result.directory / "verification.parquet")
    assert digest(result.directory, "*") == before


def test_stored_pipeline_products_list_every_file_with_the_declared_schemas(small):
    """pipeline.json, each fit's and each front's meta.json list every file of their
    directory (size, SHA-256), plots included; the tables have the declared schemas."""
    from ovtraj.pipeline.loop import FRONT_SCHEMA as VERIFIED_FRONT_SCHEMA
    from ovtraj.pipeline.loop import VERIFICATION_SCHEMA
    from ovtraj.pipeline.steps import FRONT_SCHEMA

    result, doe = small["result"], small["doe"]
    schemas = {
        ("pipeline", "front.parquet"): VERIFIED_FRONT_SCHEMA,
        ("pipeline", "verification.parquet"): VERIFICATION_SCHEMA,
        ("fronts", "front.parquet"): FRONT_SCHEMA,
    }
    for folder, marker_name in (
        ("surrogates", "meta.json"),
        ("fronts", "meta.json"),
        ("pipeline", "pipeline.json"),
    ):
        markers = sorted((doe.directory / folder).glob(f"*/{marker_name}"))
        assert markers, folder
        for marker in markers:
            listed = json.loads(marker.read_text())["files"]
            files = {
                str(p.relative_to(marker.parent))
                for p in marker.parent.rglob("*")
                if p.is_file() and p != marker and "plans" not in p.parts
            }
            assert set(listed) == files
            for name, recorded in listed.items():
                payload = (marker.parent / name).read_bytes()
                assert recorded == {
                    "bytes": len(payload),
                    "sha256": hashlib.sha256(payload).hexdigest(),
                }
                if (folder, name) in schemas:
                    assert pq.read_schema(marker.parent / name).equals(schemas[folder, name])
    report = doe.verify()
    assert report.clean, report.problems
    assert not report.uncovered, report.uncovered
    assert load_pipeline(result.directory).front.equals(result.front)


def test_every_marker_of_a_pipeline_records_the_environment_that_wrote_it(small):
    """The DoE run's manifest and batch markers, each fit's and front's meta.json and
    pipeline.json carry the declared environment block (ovtraj.store.environment_block)
    of the process that wrote them: this one, on the pinned OpenBLAS kernel."""
    from ovtraj.environment import environment
    from ovtraj.store.environment_block import EnvironmentBlock

    doe, here = small["doe"].directory, environment()
    documents = [
        doe / "manifest.json",
        *sorted(doe.glob("batches/*.json")),
        *sorted(doe.glob("surrogates/*/meta.json")),
        *sorted(doe.glob("fronts/*/meta.json")),
        *sorted(doe.glob("pipeline/*/pipeline.json")),
    ]
    names = {p.name for p in documents}
    assert {"manifest.json", "0.json", "meta.json", "pipeline.json"} <= names
    for path in documents:
        block = json.loads(path.read_text())["environment"]
        EnvironmentBlock.model_validate(block)
        assert block["blas_pin"] == here["blas_pin"] and block["cpu"] == here["cpu"], path


def test_a_changed_surrogate_set_or_front_is_refused_naming_the_file(small):
    from ovtraj.pipeline.features import load_surrogates

    doe, scenario, code = small["doe"], small["scenario"], small["code"]
    # Stored by an earlier test of the shared store, or now (the tests run in any order).
    front_step(doe, fit_step(doe, training_data(doe), scenario, code), scenario, code)
    fitted = fit_step(doe, training_data(doe), scenario, code)
    front = front_step(doe, fitted, scenario, code)
    assert fitted.reused and front.reused
    path = fitted.directory / "main" / "predictions.parquet"
    original = path.read_bytes()
    try:
        _rewrite_value(path, "y_pred", 1.0)
        with pytest.raises(SurrogateError, match=r"main/predictions\.parquet: changed"):
            load_surrogates(fitted.directory)
        with pytest.raises(SurrogateError, match=r"main/predictions\.parquet: changed"):
            fit_step(doe, training_data(doe), scenario, code)
        path.unlink()
        with pytest.raises(SurrogateError, match=r"main/predictions\.parquet: missing"):
            load_surrogates(fitted.directory)
    finally:
        path.write_bytes(original)
    path = front.directory / "front.parquet"
    original = path.read_bytes()
    try:
        _rewrite_value(path, "dv_total_mps", 1.0)
        with pytest.raises(StoreError, match=r"front\.parquet: changed since it was stored"):
            front_step(doe, fitted, scenario, code)
        path.unlink()
        with pytest.raises(StoreError, match=r"front\.parquet: missing"):
            front_step(doe, fitted, scenario, code)
    finally:
        path.write_bytes(original)
    assert fit_step(doe, training_data(doe), scenario, code).reused
    assert front_step(doe, fitted, scenario, code).reused
    # The optimize flow's artifact reads the stored front through the same check.
    from flows.optimize import front_table
    from ovtraj.pipeline.steps import front_frame

    assert len(front_table(front_frame(front.directory))) == len(front.front)


def test_any_verification_or_front_is_stored_with_the_declared_schema(tmp_path):
    """NaN (a real value the chain did not reach) and all-null columns are nulls of the
    declared type; no verified point at all is an empty table of the declared schema."""
    from ovtraj.pipeline import loop
    from ovtraj.store.records import table_from_frame

    designs = {name: [300.0, 310.0] for name in DESIGN_NAMES}
    front = pd.DataFrame(
        {
            "front_index": [0, 1],
            "sample_id": [4, 9],
            **designs,
            **{name: [1.0, 2.0] for name in OBJECTIVES},
            "origin": ["doe", "infill 1"],
        }
    )
    verification = pd.DataFrame(
        {
            "iteration": [1, 1],
            "sample_id": [20, 21],
            **designs,
            "real_feasible": [False, False],
            "failed_stage": [None, None],
            "front_index": [0, 3],
            "p_feasible": [0.5, np.nan],
            **{
                f"{kind}_{name}": [np.nan, np.nan]
                for name in OBJECTIVES
                for kind in ("predicted", "real")
            },
            **{f"error_{name}": [1.0, 1.0] for name in OBJECTIVES},
            "max_error": [1.0, 1.0],
        }
    )
    summary = {"pipeline_id": "p", "doe_run": "d", "final_run": "f"}

    for name, rows in (("some", verification), ("none", verification.iloc[:0])):
        directory = tmp_path / name

        def views(directory=directory):
            path = directory / "front.png"
            path.write_bytes(b"not really a plot")
            return [path]

        loop._store(
            directory,
            table_from_frame(front, loop.FRONT_SCHEMA, "front"),
            table_from_frame(rows, loop.VERIFICATION_SCHEMA, "verification"),
            summary,
            views,
        )
        assert pq.read_schema(directory / "front.parquet").equals(loop.FRONT_SCHEMA)
        stored = pq.read_table(directory / "verification.parquet")
        assert stored.schema.equals(loop.VERIFICATION_SCHEMA) and stored.num_rows == len(rows)
        back = load_pipeline(directory)
        assert back.verification["real_dv_total_mps"].isna().all()
        assert back.verification["real_dv_total_mps"].dtype == np.float64
        assert json.loads((directory / "pipeline.json").read_text())["files"]["front.png"]


def test_target_draconic_period_against_the_propagated_orbit(scenario):
    """The argument of latitude's mean rate, measured on a J2 propagation (second method)."""
    from ovtraj.astro.propagation import OrbitPropagator
    from ovtraj.pipeline.features import target_draconic_period
    from ovtraj.target_state import target_state

    state = target_state(scenario.target.orbit, scenario)
    propagator = OrbitPropagator(scenario.earth, tol=1e-12)
    times = np.linspace(0.0, 86400.0, 400)
    u = []
    for t in times:
        r, v = np.split(propagator.propagate(state, 0.0, t).state, 2)
        h = np.cross(r, v)
        node = np.cross([0.0, 0.0, 1.0], h)
        cos_u = node @ r / (np.linalg.norm(node) * np.linalg.norm(r))
        sin_u = (
            np.cross(node, r) @ h / (np.linalg.norm(node) * np.linalg.norm(r) * np.linalg.norm(h))
        )
        u.append(np.arctan2(sin_u, cos_u))
    rate = np.polyfit(times, np.unwrap(u), 1)[0]
    # Short-period J2 terms average out over 15 revolutions: agreement to 0.02 %.
    assert target_draconic_period(scenario) == pytest.approx(2 * np.pi / rate, rel=2e-4)


def _with_surrogate(scenario, **settings):
    """``scenario`` with these ``mission.surrogate`` settings replaced."""
    surrogate = scenario.mission.surrogate.model_copy(update=settings)
    mission = scenario.mission.model_copy(update={"surrogate": surrogate})
    return scenario.model_copy(update={"mission": mission})


def test_phase_surrogates_compose_the_parts_and_round_trip(small):
    from ovtraj.pipeline.features import (
        DV_PARTS,
        WAIT,
        MissionSurrogates,
        above,
        load_surrogates,
    )

    doe, scenario = small["doe"], small["scenario"]
    data = training_data(doe)
    # The parts are the stage rows' values; feasible samples add up to dV_total.
    ok = data.feasible
    total = sum(data.components[name][ok] for name in DV_PARTS)
    assert np.allclose(total, data.outputs["dv_total_mps"][ok], rtol=1e-12)
    fitted = fit_step(doe, data, scenario, small["code"])
    surrogates = fitted.surrogates
    assert isinstance(surrogates, MissionSurrogates) and WAIT in surrogates.selected
    designs = data.designs[:7]
    features = surrogates.features(designs)
    wait = surrogates.wait.predict(designs[:, :1])[WAIT]
    # The phase input: the wait's phase in the target's period (surrogate.burn_phase false
    # with the plane aimed at the rendezvous: the rendezvous part is fitted on H_P0 alone and
    # no part takes it; the burn's phase is tested below).
    assert surrogates.burn_phase is None
    period_phase = 2 * np.pi * np.mod(wait, surrogates.period_s) / surrogates.period_s
    assert np.allclose(
        features[:, 3:5], np.column_stack([np.sin(period_phase), np.cos(period_phase)])
    )
    assert surrogates.main.input_names[3:5] == ("sin_wait_phase", "cos_wait_phase")
    # The departure phase (surrogate.departure_phase): where on the target's orbit the OV
    # leaves it, from the pass model's separation time with the wait model's wait.
    departure = surrogates.pass_model.departure_phase_rad(designs, wait)
    assert np.allclose(features[:, 5:], np.column_stack([np.sin(departure), np.cos(departure)]))
    assert surrogates.main.input_names[5:] == ("sin_departure_phase", "cos_departure_phase")
    raw = surrogates.main.predict(features)
    floors = surrogates.floors(designs)
    parts = {name: above(floors[name], raw[name], surrogates.softness_mps) for name in DV_PARTS}
    predicted = surrogates.predict(designs)
    assert np.allclose(predicted["dv_total_mps"], sum(parts[name] for name in DV_PARTS))
    time_floor = 3600.0 * (scenario.mission.stay_h + designs[:, 2])
    # T_total is the pass model's (surrogate.pass_forecast), not a regressor's.
    assert surrogates.selected["t_total_s"] == "pass model" and "t_total_s" not in raw
    low_fidelity = surrogates.pass_model.t_total_s(designs, wait)
    assert np.allclose(
        predicted["t_total_s"], above(time_floor, low_fidelity, surrogates.softness_s)
    )
    # M_load is the launch fit's payload itself: the run's values exactly.
    known = np.isfinite(data.outputs["m_load_kg"][:7])
    assert np.allclose(
        predicted["m_load_kg"][known], data.outputs["m_load_kg"][:7][known], rtol=0, atol=1e-9
    )
    again = load_surrogates(fitted.directory)
    assert again.departure_phase and again.phase_inputs == surrogates.phase_inputs
    for name, values in surrogates.predict(designs).items():
        assert np.array_equal(again.predict(designs)[name], values)
    assert np.array_equal(again.feasibility(designs), surrogates.feasibility(designs))
    # Each dV part on its own inputs (surrogate.part_inputs): the rendezvous is over before
    # H_dp and t_dsp act, so designs that differ in those alone share its prediction.
    own = {k: tuple(v) for k, v in scenario.mission.surrogate.part_inputs.items()}
    assert own["dv_rendezvous_mps"] == ("parking_altitude_km",)
    assert surrogates.main.output_inputs == own == again.main.output_inputs
    later = designs.copy()
    later[:, 1], later[:, 2] = designs[::-1, 1], designs[::-1, 2]
    before, after = surrogates.predict_parts(designs), surrogates.predict_parts(later)
    np.testing.assert_allclose(after["dv_rendezvous_mps"], before["dv_rendezvous_mps"], rtol=1e-10)
    assert not np.allclose(after["dv_transfer_mps"], before["dv_transfer_mps"], rtol=1e-3)
    # Every part on every input: another fit, whose rendezvous part moves with them.
    shared = fit_step(doe, data, _with_surrogate(scenario, part_inputs={}), small["code"])
    assert shared.fit_id != fitted.fit_id and shared.surrogates.main.output_inputs == {}
    moved = shared.surrogates.predict_parts(later)["dv_rendezvous_mps"]
    assert not np.allclose(
        moved, shared.surrogates.predict_parts(designs)["dv_rendezvous_mps"], rtol=1e-6
    )
    # With the burn's phase (surrogate.burn_phase, the chain with the plane at insertion): twice the
    # first burn's argument of latitude, in closed form from H_P0.
    burned = _with_surrogate(
        scenario,
        burn_phase=True,
        part_inputs={
            **scenario.mission.surrogate.part_inputs,
            "dv_rendezvous_mps": ["parking_altitude_km", "sin_2u_burn", "cos_2u_burn"],
        },
    )
    with_burn = fit_step(doe, data, burned, small["code"]).surrogates
    burn = 2.0 * with_burn.burn_phase.burn(designs[:, 0])[1]
    assert np.allclose(
        with_burn.features(designs)[:, 3:5], np.column_stack([np.sin(burn), np.cos(burn)])
    )
    assert with_burn.main.input_names[3:5] == ("sin_2u_burn", "cos_2u_burn")
    # Without the phase input: one plain set of the three objectives.
    plain = _with_surrogate(scenario, phase_input=False)
    direct = fit_step(doe, data, plain, small["code"]).surrogates
    assert set(direct.output_names) == set(OBJECTIVES) and not hasattr(direct, "wait")
    # Without the pass model and the burn phase: T_total regressed like the other outputs,
    # on the phase of the wait model's wait in the target's period.
    # (part_inputs names the burn's phase inputs, absent without it)
    regressed = _with_surrogate(
        scenario, pass_forecast=None, burn_phase=False, departure_phase=False, part_inputs={}
    )
    whole = fit_step(doe, data, regressed, small["code"]).surrogates
    assert whole.pass_model is None and whole.selected["t_total_s"] != "pass model"
    assert whole.burn_phase is None
    phase = 2 * np.pi * np.mod(wait, whole.period_s) / whole.period_s
    features = whole.features(designs)
    assert np.allclose(features[:, 3:], np.column_stack([np.sin(phase), np.cos(phase)]))
    assert whole.main.input_names[3:] == ("sin_wait_phase", "cos_wait_phase")
    raw = whole.main.predict(whole.features(designs))
    assert np.allclose(
        whole.predict(designs)["t_total_s"], above(time_floor, raw["t_total_s"], whole.softness_s)
    )


def test_pinned_deorbit_burns_stay_out_of_the_deorbit_part_alone(small):
    import dataclasses

    from ovtraj.mission import reference
    from ovtraj.mission.design_space import bounds_arrays
    from ovtraj.pipeline.features import DEORBIT_WAIT
    from ovtraj.pipeline.mission_fit import fit_mission_surrogates, pinned_deorbit_burns

    # The regime: without deorbit.solver.pass_cost_margin_mps a burn the deorbit's
    # correction pinned at the preparation orbit's start (its wait 0) pays for reaching the
    # pass, one after a wait costs the minimum impulse; with the margin (shipped) the
    # pinned pass is passed over for the next one at the minimum impulse.
    scenario = small["scenario"]
    context = reference.context(reference.load_settings())  # the default scenario's chain
    resolved = context.scenario.resolved()
    resolved["deorbit"]["solver"]["pass_cost_margin_mps"] = None
    unbounded = MissionContext(scenario_from_dict(resolved, "no pass bound"), context.fit)
    pinned = evaluate(unbounded, MissionDesign(319.09, 379.75, 10.28)).stages["deorbit"]
    waited = evaluate(unbounded, MissionDesign(308.65, 328.7, 12.04)).stages["deorbit"]
    assert pinned["wait_time_s"] == 0.0 and pinned["dv_mps"] > 100.0
    assert waited["wait_time_s"] > 600.0 and waited["dv_mps"] < 90.0
    bounded = evaluate(context, MissionDesign(319.09, 379.75, 10.28)).stages["deorbit"]
    assert bounded["wait_time_s"] > 600.0 and bounded["dv_mps"] < 90.0
    # Two feasible samples of the DoE marked as pinned: out of the deorbit part's rows
    # (training, folds, hold-out), in the transfer part's; with the setting off, in both.
    data = training_data(small["doe"])
    marked = np.flatnonzero(data.feasible)[[1, 4]]
    waits = data.components[DEORBIT_WAIT].copy()
    waits[marked] = 0.0
    data = dataclasses.replace(data, components={**data.components, DEORBIT_WAIT: waits})
    assert np.array_equal(np.flatnonzero(pinned_deorbit_burns(data)), marked)
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    for skip in (True, False):
        chosen = _with_surrogate(scenario, skip_pinned_deorbit_burns=skip)
        rows = fit_mission_surrogates(data, chosen, lower, upper).main.predictions
        ids = data.sample_ids[marked]
        deorbit = rows[rows["model"] == "dv_deorbit_mps"]["sample_id"]
        transfer = rows[rows["model"] == "dv_transfer_mps"]["sample_id"]
        assert np.isin(ids, transfer).all()
        assert np.isin(ids, deorbit).all() != skip
        assert len(deorbit) == len(transfer) - (2 if skip else 0)


def test_no_prediction_leaves_its_physical_range_on_a_dense_grid(small):
    """T_total above the stay + t_dsp it contains, M_load inside the launch fit's
    range, each dV part above its two-body floor, on a 31 x 21 x 13 grid (8463 designs)."""
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.mission.design_space import bounds_arrays
    from ovtraj.pipeline.features import DV_PARTS

    doe, scenario = small["doe"], small["scenario"]
    surrogates = fit_step(doe, training_data(doe), scenario, small["code"]).surrogates
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    axes = [np.linspace(lo, hi, n) for lo, hi, n in zip(lower, upper, (31, 21, 13), strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    predicted = surrogates.predict(grid)
    parts = surrogates.predict_parts(grid)
    floors = surrogates.floors(grid)
    time_floor = 3600.0 * (scenario.mission.stay_h + grid[:, 2])
    assert (
        np.isfinite(predicted["t_total_s"]).all() and (predicted["t_total_s"] >= time_floor).all()
    )
    for name in DV_PARTS:
        assert (parts[name] >= floors[name]).all(), name
    assert (predicted["dv_total_mps"] >= sum(floors.values())).all()
    launch = find_launch_fit(scenario)
    solved = launch.grid["payload_kg"].to_numpy()
    slack = launch.series["payload_kg"].loo_max_error
    m_load = predicted["m_load_kg"]
    assert (m_load >= solved.min() - slack).all() and (m_load <= solved.max() + slack).all()
    # The floors are bounds of the real chain too: every feasible DoE sample is above them.
    data = training_data(doe)
    real = surrogates.floors(data.designs)
    for name in DV_PARTS:
        ok = data.feasible
        assert (data.components[name][ok] > real[name][ok]).all(), name


def test_softplus_bound_is_above_its_floor_and_the_value_far_above_it():
    from ovtraj.pipeline.features import above

    floor = np.array([10.0, 10.0, 10.0, 10.0, 10.0])
    value = np.array([-1e6, 0.0, 10.0, 20.0, 1e6])
    got = above(floor, value, 1.0)
    # Never below the floor; above it except where the softplus underflows (far below).
    assert (got >= floor).all() and (got[1:] > floor[1:]).all() and np.isfinite(got).all()
    assert got[2] == pytest.approx(10.0 + np.log(2.0), rel=1e-15)
    # 10 softness units above the floor: the value within softness * exp(-10).
    assert got[3] == pytest.approx(20.0, abs=np.exp(-10.0))
    assert got[4] == 1e6


def test_dv_floors_are_the_two_body_limits(scenario):
    """Rendezvous and transfer: Hohmann; deorbit: the tangential burn as gamma_e -> 0-."""
    from ovtraj.deorbit.estimate import tangential_deorbit
    from ovtraj.pipeline.features import DvFloors
    from ovtraj.rendezvous import hohmann

    floors = DvFloors.of(scenario)
    design = np.array([[300.0, 350.0, 5.0]])
    got = {name: float(v[0]) for name, v in floors(design).items()}
    r_park = floors.earth_radius_m + 300e3
    r_prep = floors.earth_radius_m + 350e3
    mu = floors.mu
    assert (
        got["dv_rendezvous_mps"] == hohmann(r_park, floors.target_perigee_radius_m, mu).total_dv_mps
    )
    assert (
        got["dv_transfer_mps"] == hohmann(floors.target_perigee_radius_m, r_prep, mu).total_dv_mps
    )
    grazing = tangential_deorbit(r_prep, floors.entry_radius_m, -1e-9, mu)
    assert got["dv_deorbit_mps"] == pytest.approx(grazing.dv_mps, abs=1e-6)
    steeper = tangential_deorbit(r_prep, floors.entry_radius_m, np.radians(-0.9), mu)
    assert steeper.dv_mps > got["dv_deorbit_mps"]


def test_nsga2_stopped_by_its_time_limit_stores_no_front_and_exits_1(small, tmp_path):
    """A front cut short by mission.optimize.time_limit_s is unconverged: not stored."""
    from typer.testing import CliRunner

    from ovtraj.cli import app
    from ovtraj.pipeline import OptimiserStopped, fit_step, front_step, training_data

    data = _data(points_per_iteration=3, max_iterations=2, budget=6)
    data["mission"]["optimize"].update(generations=100000, time_limit_s=1e-6)
    scenario = build_scenario(copy.deepcopy(data))
    doe = small["doe"]
    fronts = {p.name for p in (doe.directory / "fronts").iterdir()}
    fitted = fit_step(doe, training_data(doe), scenario, small["code"])
    with pytest.raises(OptimiserStopped, match=r"mission\.optimize\.time_limit_s = 1e-06 s"):
        front_step(doe, fitted, scenario, small["code"])
    assert {p.name for p in (doe.directory / "fronts").iterdir()} == fronts
    config = tmp_path / "stopped.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    store = str(small["store"].root)
    done = CliRunner().invoke(app, ["optimize", doe.id, str(config), "--store", store])
    assert done.exit_code == 1 and "no front stored" in done.stderr


def test_the_pipeline_command_runs_the_doe_and_infill_on_one_pool(tmp_path):
    """``ovtraj pipeline`` end to end (the entry point's body in this process,
    tests/cli_runner.py), on the process runner: the DoE and the infill run on one pool,
    every path printed is absolute, and the same command again reuses every stored run and
    result (no batch evaluated). Its loop does not converge
    (a promise tolerance no round meets): exit 1, everything stored and printed, the
    verdict saying why; exit 0 with ``--allow-unconverged``."""
    from tests.cli_runner import run_cli

    data = _data(points_per_iteration=2, max_iterations=1, budget=2)
    data["mission"]["doe"].update(store=str(tmp_path / "runs"), batch_size=6, workers=2)
    config = tmp_path / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    command = ["pipeline", str(config), "--samples", "12", "--runner", "processes"]
    done = run_cli(*command, cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    lines = done.stdout.splitlines()
    assert re.search(r"^DoE run \w+: 12 samples$", done.stdout, flags=re.MULTILINE)
    batches = [line for line in lines if re.match(r"batch \d+/\d+: ", line)]
    assert len(batches) == 2 + 1  # the DoE's two batches, the infill's one
    written = [
        Path(line.split(": ", 1)[1]) for line in lines if line.startswith(("front:", "plan:"))
    ]
    assert len(written) == 3 and all(p.is_absolute() and p.is_file() for p in written)
    # The plots it drew, once: the verified front, the last round's parity plots and its
    # surrogate front, each printed with its absolute path.
    plots = [Path(line.split(": ", 1)[1]) for line in lines if line.startswith("plot:")]
    names = {p.name for p in plots if p.parent == written[0].parent}
    assert {"front.png", "surrogate-front.png", "parity-dv_rendezvous_mps.png"} <= names
    assert all(p.is_absolute() and p.is_file() for p in plots)
    # It says that the loop did not converge and why it stopped (one infill round of 2
    # points: the round limit ends it, the promise tolerance unmet).
    verdict = next(line for line in lines if re.match(r"(not )?converged: ", line))
    assert verdict.startswith("not converged: ") and "Traceback" not in done.stderr
    report = Path(next(line for line in lines if line.startswith("report: ")).split(": ", 1)[1])
    assert report.is_absolute() and report.is_file()
    page = report.read_text(encoding="utf-8")
    assert verdict in html.unescape(page) and page.count("src='data:image/png;base64,") >= 5
    # T_total is the pass model's: the report says so instead of CV figures.
    assert "t_total_s: pass model, not a regressor" in page
    runs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert len(runs) == 3 and "catalog" in runs  # the DoE, its infill child, the catalog
    # Again, as JSON, unconverged allowed: nothing evaluated, one object on stdout, the
    # same verdict and report, exit 0.
    again = run_cli(*command, "--json", "--allow-unconverged", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert not re.search(r"^batch \d+/", again.stdout + again.stderr, flags=re.MULTILINE)
    summary = json.loads(again.stdout)
    assert summary["verdict"] == verdict and summary["converged"] == (not verdict.startswith("not"))
    assert summary["report"] == str(report) and report.read_text(encoding="utf-8") == page
    assert {Path(p).name for p in summary["views"]} == names - {"front.png"}
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == runs


def _copied_store(small, tmp_path) -> RunStore:
    import shutil

    shutil.copytree(small["store"].root, tmp_path / "runs")
    return RunStore(tmp_path / "runs")


def test_runs_lists_families_and_plan_takes_any_run_of_one(small, tmp_path):
    """``ovtraj runs`` groups the infill runs under their DoE run, with its pipeline result;
    ``ovtraj plan`` accepts any run of the family; the report is the same bytes again."""
    store = _copied_store(small, tmp_path)
    result, doe = small["result"], small["doe"].id
    runner = CliRunner()
    listed = runner.invoke(app, ["runs", "--store", str(store.root), "--json"])
    assert listed.exit_code == 0, listed.output
    entries = json.loads(listed.stdout)["runs"]
    assert entries[0]["run_id"] == doe and entries[0]["depth"] == 0
    assert entries[0]["pipelines"] == [result.pipeline_id]
    children = entries[1:]
    infill = {i["infill_run"] for i in result.summary["iterations"] if "infill_run" in i}
    assert {e["run_id"] for e in children} == infill and result.final_run in infill
    assert all(e["family"] == doe and e["depth"] >= 1 for e in children)
    assert all(e["origin"].startswith("infill ") and e["size_bytes"] > 0 for e in children)
    table = runner.invoke(app, ["runs", "--store", str(store.root)])
    assert table.exit_code == 0 and "pipeline results" in table.stdout
    assert f"└ {result.final_run}" in table.stdout and result.pipeline_id in table.stdout
    pages = []
    for rid in (result.final_run, doe):
        done = runner.invoke(app, ["plan", rid, "--pick", "0", "--store", str(store.root)])
        assert done.exit_code == 0, done.output
        report = Path(done.stdout.split("report: ", 1)[1].strip())
        pages.append(report.read_bytes())
    assert pages[0] == pages[1] and b"Verification rounds" in pages[0]


def test_prune_removes_superseded_runs_and_stale_fits_and_keeps_every_result(small, tmp_path):
    from ovtraj.pipeline.planning import find_pipeline
    from ovtraj.pipeline.prune import prunable, remove

    store = _copied_store(small, tmp_path)
    result = small["result"]
    runner = CliRunner()
    rounds = [i["infill_run"] for i in result.summary["iterations"] if "infill_run" in i]
    superseded = set(rounds) - {result.final_run}
    assert superseded, "the fixture's loop ran one round only: nothing superseded"
    listed = runner.invoke(
        app, ["prune", "--store", str(store.root), "--only", "children", "--json"]
    )
    assert listed.exit_code == 0, listed.output
    items = json.loads(listed.stdout)["items"]
    assert {Path(i["path"]).name for i in items} == superseded
    assert all((store.root / rid).is_dir() for rid in superseded)  # a dry run by default
    stopped = store.root / ".pruned-0123456789abcdef"  # what a prune killed mid-way leaves
    (stopped / "totals").mkdir(parents=True)
    (stopped / "totals" / "part-00000.parquet").write_bytes(b"x" * 100)
    (stopped / "manifest.json").write_bytes((small["doe"].directory / "manifest.json").read_bytes())
    assert stopped.name not in {r["run_id"] for r in store.catalog()}  # not a run any more
    done = runner.invoke(app, ["prune", "--store", str(store.root), "--only", "children", "--yes"])
    assert done.exit_code == 0, done.output
    assert "left by a stopped prune" in done.output
    assert all(not (store.root / rid).exists() for rid in superseded)
    assert not [p for p in store.root.iterdir() if p.name.startswith(".pruned-")]
    for rid in (small["doe"].id, result.final_run):
        checked = store.run(rid).verify()
        assert checked.clean and not checked.uncovered, (checked.problems, checked.uncovered)
    # a removed run's id still leads to its family's result
    pruned = sorted(superseded)[0]
    planned = runner.invoke(app, ["plan", pruned, "--pick", "0", "--store", str(store.root)])
    assert planned.exit_code == 0, planned.output
    # Fits and fronts of this code are kept; of another code version they are stale.
    assert prunable(store, small["code"], kinds=("fits",)) == []
    stale = prunable(store, "another-code-version", kinds=("fits",))
    kinds = {item.path.parent.name for item in stale}
    assert kinds == {"surrogates", "fronts"} and all(remove(item) for item in stale)
    again = find_pipeline(store.run(small["doe"].id))
    assert again.front.equals(result.front)
    # Prefect's local results: a cache, listed and removed record by record; a file that
    # is not a result record is not Prefect's, and stays.
    results = tmp_path / "prefect-results"
    results.mkdir()
    record = prefect_record(results, "a")
    (results / "b").write_bytes(b"x" * 10)
    cached = prunable(store, small["code"], kinds=("prefect-results",), prefect_results=results)
    assert [(i.path.name, i.size_bytes) for i in cached] == [("a", record.stat().st_size)]
    assert remove(cached[0]) and not record.exists() and (results / "b").is_file()
    refused = runner.invoke(app, ["prune", "--store", str(store.root), "--only", "everything"])
    assert refused.exit_code == 2 and "--only" in refused.output


def test_warm_started_fronts_hold_the_previous_front_and_replay(small, tmp_path):
    """optimize.warm_start_generations: a later round's NSGA-II runs that many generations
    from the previous round's front as well; the warm start is part of the front's identity
    and a refit reproduces it; off, the previous front changes nothing."""
    import shutil

    from ovtraj.pipeline.steps import load_front

    doe, code = small["doe"], small["code"]
    data = _data(points_per_iteration=3, max_iterations=2, budget=6)
    data["mission"]["optimize"]["warm_start_generations"] = 7
    warm = build_scenario(copy.deepcopy(data))
    fitted = fit_step(doe, training_data(doe), small["scenario"], code, views=False)
    cold = front_step(doe, fitted, small["scenario"], code, views=False)
    ignored = front_step(doe, fitted, small["scenario"], code, views=False, previous=cold)
    assert ignored.front_id == cold.front_id and ignored.reused
    first = front_step(doe, fitted, warm, code, views=False)
    second = front_step(doe, fitted, warm, code, views=False, previous=first)
    assert second.front_id != first.front_id and not second.reused
    meta = json.loads((second.directory / "meta.json").read_text())
    assert meta["warm_from"] == first.front_id
    assert second.front.info["generations"] < first.front.info["generations"]
    again = front_step(doe, fitted, warm, code, views=False, refit=True, previous=first)
    assert again.matches_stored is True
    # The previous front as the Prefect task loads it: the same warm start.
    normalisation = Normalisation.mission(warm.mission.optimize)
    loaded = type(first)(
        load_front(first.directory, normalisation), first.directory, first.front_id, True
    )
    reloaded = front_step(doe, fitted, warm, code, views=False, refit=True, previous=loaded)
    assert reloaded.matches_stored is True
    # The whole loop: every round after the first warm from the one before.
    copy_root = tmp_path / "runs"
    shutil.copytree(small["store"].root, copy_root)
    store = RunStore(copy_root)
    fit = small["fit"]
    result = run_pipeline(
        warm,
        store.run(doe.id),
        store=store,
        code=code,
        steps=PipelineSteps(
            evaluate=lambda run: run_doe(warm, run, fit, batch_size=warm.mission.doe.batch_size)
        ),
    )
    rounds = result.summary["iterations"]
    assert len(rounds) >= 2
    fronts = {
        p.name: json.loads((p / "meta.json").read_text()) for p in copy_root.rglob("fronts/*")
    }
    warm_from = [m["warm_from"] for m in fronts.values()]
    assert warm_from.count(None) >= 1 and sum(w is not None for w in warm_from) >= len(rounds) - 1


def test_every_front_point_is_planned_as_promised(small, tmp_path):
    """The plan of each verified front point (its launch solved to the chain's
    insertion) flies its front values within ``mission.plan.front_tolerance``."""
    from ovtraj.mission.plan_build import plan_and_record

    scenario = small["scenario"]
    context = MissionContext(scenario, small["fit"])
    tolerance = scenario.mission.plan.front_tolerance
    front = small["result"].front
    assert len(front) >= 2
    for row in front.to_dict("records"):
        design = MissionDesign(**{name: float(row[name]) for name in DESIGN_NAMES})
        _, record = plan_and_record(context, design, source={}, launch_cache=tmp_path)
        assert record.results.launch.source == "solved launch"
        assert abs(record.dv_total_mps - row["dv_total_mps"]) <= tolerance.dv_total_mps
        assert abs(record.t_total_s - row["t_total_s"]) <= tolerance.t_total_s
        assert abs(record.m_load_kg - row["m_load_kg"]) <= tolerance.m_load_kg


def test_a_plan_off_its_front_point_exits_1_and_writes_nothing(small, tmp_path, monkeypatch):
    """The replayed pipeline with a tolerance its plan cannot meet (M_load within 1e-12 kg:
    the launch flown to the chain's insertion carries its own payload optimum, grams from
    the launch fit's): one message with the difference and its cause, exit 1, no plan."""
    monkeypatch.setenv("OVTRAJ_HOME", str(tmp_path / "home"))
    store = _copied_store(small, tmp_path)
    data = yaml.safe_load(small["config"].read_text(encoding="utf-8"))
    data["mission"]["plan"]["front_tolerance"]["m_load_kg"] = 1e-12
    tight = tmp_path / "tight.yaml"
    tight.write_text(yaml.safe_dump(data), encoding="utf-8")
    plans = store.root / small["doe"].id / "pipeline" / small["result"].pipeline_id / "plans"
    before = sorted(p.name for p in plans.iterdir()) if plans.is_dir() else []
    done = CliRunner().invoke(
        app, ["pipeline", str(tight), "--run", small["doe"].id, "--store", str(store.root)]
    )
    assert done.exit_code == 1, done.output
    message = done.stderr.strip().splitlines()[-1]
    assert "does not fly its front values: M_load" in message
    assert "launch payload" in message and "Traceback" not in done.output
    after = sorted(p.name for p in plans.iterdir()) if plans.is_dir() else []
    assert after == before
