"""DoE flow and run store: parallel batches, cache, resume, corruption, ids."""

from __future__ import annotations

import copy

import pandas as pd
import pytest
import yaml

from ovtraj.mission import STAGES
from ovtraj.runs import RunStore, StoreError, execute, latin_hypercube, run_id
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario, digest

# Left out of the fast tier (-m "not slow"): it runs the DoE flow on the session's Prefect server.
pytestmark = pytest.mark.slow


def _config(tmp_path, **doe) -> str:
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(doe)
    build_scenario(copy.deepcopy(data))
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def eight(prefect_server, tmp_path_factory):
    """The flow on 8 samples, run twice on the same store."""
    from flows.doe import run_doe_flow

    tmp = tmp_path_factory.mktemp("doe")
    config = _config(tmp, samples=8, batch_size=4, store=str(tmp / "runs"))
    before = execute.EVALUATIONS["count"]
    first = run_doe_flow(config=config)
    after_first = execute.EVALUATIONS["count"]
    from prefect.artifacts import Artifact

    artifact = Artifact.get("doe-run")
    store = RunStore(tmp / "runs")
    stored = digest(store.run(first["run_id"]).directory)
    second = run_doe_flow(config=config)
    return {
        "first": first,
        "second": second,
        "evaluations": (after_first - before, execute.EVALUATIONS["count"] - after_first),
        "digest": stored,
        "store": store,
        "artifact": artifact,
    }


def test_flow_stores_one_row_per_sample_and_stage(eight):
    run = eight["store"].run(eight["first"]["run_id"])
    assert run.manifest["status"] == "complete" and eight["first"]["evaluated"] == 8
    totals = run.totals()
    assert list(totals["sample_id"]) == list(range(8))
    assert {"t_total_s", "dv_total_mps", "m_load_kg", "feasible", "failed_stage", "reason"} <= set(
        totals.columns
    )
    reached = {stage: 0 for stage in STAGES}
    for row in totals.itertuples():
        last = STAGES.index(row.failed_stage) if isinstance(row.failed_stage, str) else 4
        for stage in STAGES[: last + 1]:
            reached[stage] += 1
    for stage in STAGES:
        frame = run.stage(stage)
        assert len(frame) == reached[stage] and frame["sample_id"].is_unique
        assert "feasible" in frame.columns
    assert set(run.stage("rendezvous").columns) >= {"dv1_mps", "dv2_mps", "miss_distance_m"}
    assert set(run.stage("reentry").columns) >= {"miss_distance_km", "max_heat_rate_kw_m2"}
    # Trajectory tables in their own files.
    sid = int(totals.loc[totals["feasible"], "sample_id"].iloc[0])
    assert len(run.trajectory("reentry", sid)) > 10


def test_flow_publishes_a_table_artifact_of_the_run(eight):
    artifact = eight["artifact"]
    assert artifact is not None and artifact.type == "table"
    assert eight["first"]["run_id"] in str(artifact.data)


def test_second_identical_run_simulates_nothing_and_changes_nothing(eight):
    assert eight["evaluations"] == (8, 0)
    assert eight["second"]["run_id"] == eight["first"]["run_id"]
    run = eight["store"].run(eight["first"]["run_id"])
    assert digest(run.directory) == eight["digest"]


def test_replay_rederives_the_totals_without_simulation(eight):
    run = eight["store"].run(eight["first"]["run_id"])
    before = execute.EVALUATIONS["count"]
    derived = execute.replay(run)
    assert execute.EVALUATIONS["count"] == before
    stored = run.totals()
    assert list(derived["feasible"]) == list(stored["feasible"])
    for column in ("t_total_s", "dv_total_mps", "m_load_kg"):
        pd.testing.assert_series_equal(derived[column], stored[column], check_names=False)


def test_interrupted_run_resumes_without_recomputing_finished_batches(
    prefect_server, tmp_path, monkeypatch
):
    from flows.doe import run_doe_flow

    config = _config(tmp_path, samples=6, batch_size=2, task_retries=0, store=str(tmp_path / "r"))
    original = execute.evaluate_batch
    failed = {"done": False}

    def flaky(context, batch):
        if 2 in set(batch["sample_id"]) and not failed["done"]:
            failed["done"] = True
            raise ConnectionError("worker lost")
        return original(context, batch)

    monkeypatch.setattr(execute, "evaluate_batch", flaky)
    with pytest.raises(RuntimeError, match="batch 1"):
        run_doe_flow(config=config)
    store = RunStore(tmp_path / "r")
    (run,) = [store.run(r["run_id"]) for r in store.catalog()]
    assert run.done_batches() == {0, 2} and run.manifest["status"] == "incomplete"
    before = execute.EVALUATIONS["count"]
    summary = run_doe_flow(config=config)
    assert execute.EVALUATIONS["count"] - before == 2  # only the failed batch's samples
    assert summary["evaluated"] == 6 and run.manifest["status"] == "complete"


def test_infeasible_deorbit_is_stored_with_its_reason(tmp_path, scenario):
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.runs import prepare_run, run_doe

    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["deorbit"]["horizon_h"] = 12.0  # some samples find no pass in time
    short = build_scenario(data)
    store = RunStore(tmp_path)
    run = prepare_run(short, samples=8, seed=3, code="test", store=store)
    run_doe(short, run, find_launch_fit(scenario), batch_size=4)
    totals = run.totals()
    assert len(totals) == 8
    failed = totals[totals["failed_stage"] == "deorbit"]
    assert len(failed) >= 1 and all("no northbound pass" in r for r in failed["reason"])
    assert totals["feasible"].sum() >= 1
    deorbit = run.stage("deorbit")
    stored = deorbit[deorbit["sample_id"].isin(failed["sample_id"])]
    assert (~stored["feasible"]).all() and stored["reason"].str.contains("horizon").all()


def test_corrupted_parquet_is_named_and_nothing_else_is_overwritten(eight, tmp_path):
    import shutil

    source = eight["store"].run(eight["first"]["run_id"]).directory
    copy_dir = tmp_path / "runs" / source.name
    shutil.copytree(source, copy_dir)
    store = RunStore(tmp_path / "runs")
    run = store.run(source.name)
    victim = copy_dir / "stages" / "deorbit" / "part-00001.parquet"
    victim.write_bytes(victim.read_bytes()[:100])  # truncated
    before = {k: v for k, v in digest(copy_dir).items() if "deorbit/part-00001" not in k}
    with pytest.raises(StoreError, match=r"part-00001\.parquet"):
        run.stage("deorbit")
    with pytest.raises(StoreError, match=r"part-00001\.parquet"):
        execute.replay(run)
    # Writing an already stored batch again is refused: nothing is overwritten.
    assert run.write_batch(1, [], [], trajectory_steps={}) is False
    after = {k: v for k, v in digest(copy_dir).items() if "deorbit/part-00001" not in k}
    assert after == before
    # The catalog reads a run's manifest and totals, not its stage parts: the damaged run is
    # still listed with its summary, not as an unreadable run.
    listed = {row["run_id"]: row for row in store.catalog()}
    assert set(listed) == {source.name}
    assert listed[source.name]["status"] == "complete"
    assert listed[source.name]["evaluated"] == eight["first"]["evaluated"]


def test_run_id_is_a_content_hash(scenario):
    resolved = scenario.resolved()
    bounds = scenario.mission.design_bounds
    eight, nine = latin_hypercube(bounds, 8, 1), latin_hypercube(bounds, 9, 1)
    moved = eight.copy()
    moved.loc[3, "separation_delay_h"] += 1e-9
    assert run_id(resolved, 1, eight, "v1", None) == run_id(
        copy.deepcopy(resolved), 1, eight.copy(), "v1", None
    )
    changed = copy.deepcopy(resolved)
    changed["mission"]["stay_h"] += 1.0
    ids = {
        run_id(resolved, 1, eight, "v1", None),
        run_id(changed, 1, eight, "v1", None),
        run_id(resolved, 2, eight, "v1", None),
        run_id(resolved, 1, nine, "v1", None),
        run_id(resolved, 1, moved, "v1", None),
        run_id(resolved, 1, eight, "v2", None),
        run_id(resolved, 1, eight, "v1", "parent"),
    }
    assert len(ids) == 7
    # How the DoE executes, and what is done with its results, do not change them.
    execution = copy.deepcopy(resolved)
    execution["mission"]["doe"]["workers"] += 3
    execution["mission"]["doe"]["batch_size"] += 1
    execution["mission"]["surrogate"]["folds"] += 1
    execution["mission"]["optimize"]["generations"] += 10
    execution["mission"]["verify"]["budget"] += 1
    assert run_id(execution, 1, eight, "v1", None) == run_id(resolved, 1, eight, "v1", None)


def test_latin_hypercube_is_seeded_stratified_and_inside_the_bounds(scenario):
    bounds = scenario.mission.design_bounds
    a = latin_hypercube(bounds, 10, seed=5)
    assert a.equals(latin_hypercube(bounds, 10, seed=5))
    assert not a.equals(latin_hypercube(bounds, 10, seed=6))
    lo, hi = bounds.parking_altitude_km.lower, bounds.parking_altitude_km.upper
    strata = ((a["parking_altitude_km"] - lo) / (hi - lo) * 10).astype(int)
    assert sorted(strata) == list(range(10))  # one sample per stratum
    more = latin_hypercube(bounds, 4, seed=5, first_id=10)
    assert list(more["sample_id"]) == [10, 11, 12, 13]


def test_flow_runs_on_a_local_dask_cluster(prefect_server, tmp_path):
    from flows.doe import run_doe_flow

    config = _config(
        tmp_path, samples=4, batch_size=2, task_runner="dask", workers=2, store=str(tmp_path / "d")
    )
    summary = run_doe_flow(config=config)
    assert summary["evaluated"] == 4 and summary["status"] == "complete"


def test_append_makes_a_child_run_that_reuses_the_parent_batches(tmp_path, scenario):
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.runs import prepare_run, run_doe

    store = RunStore(tmp_path)
    fit = find_launch_fit(scenario)
    parent = prepare_run(scenario, samples=2, seed=11, code="test", store=store)
    run_doe(scenario, parent, fit, batch_size=2)
    child = prepare_run(scenario, samples=2, seed=11, code="test", store=store, parent=parent)
    assert child.id != parent.id and child.manifest["parent"] == parent.id
    samples = child.samples()
    assert len(samples) == 4 and list(samples["sample_id"]) == [0, 1, 2, 3]
    pd.testing.assert_frame_equal(samples.iloc[:2], parent.samples())
    # The appended samples are new points of the design space.
    assert (
        not samples.iloc[2:][["parking_altitude_km"]]
        .isin(parent.samples()["parking_altitude_km"].tolist())
        .any()
        .any()
    )
    # The parent's stored batch is adopted (whatever the batch size): only the two new
    # samples are simulated, and the parent's rows are the child's, byte for byte.
    assert child.manifest["inherited_batches"] == 1 and child.done_batches() == {0}
    assert [list(b["sample_id"]) for _, b in child.batches(3)] == [[0, 1], [2, 3]]
    before = execute.EVALUATIONS["count"]
    run_doe(scenario, child, fit, batch_size=3)
    assert execute.EVALUATIONS["count"] - before == 2
    assert child.manifest["status"] == "complete"
    pd.testing.assert_frame_equal(child.totals().iloc[:2], parent.totals(), check_dtype=False)
    # Reopening the child adopts nothing twice.
    again = prepare_run(scenario, samples=2, seed=11, code="test", store=store, parent=parent)
    assert again.id == child.id and again.done_batches() == {0, 1}


def test_cli_run_runs_show_and_replay(tmp_path):
    import json
    import re

    from typer.testing import CliRunner

    from ovtraj.cli import app

    runner = CliRunner()
    store = str(tmp_path / "runs")
    done = runner.invoke(
        app, ["run", str(DEFAULT_SCENARIO), "--samples", "2", "--seed", "4", "--store", store]
    )
    assert done.exit_code == 0, done.output
    (rid,) = [p.name for p in (tmp_path / "runs").iterdir()]
    listed = runner.invoke(app, ["runs", "--store", store])
    assert listed.exit_code == 0, listed.output
    (row,) = [line for line in listed.stdout.splitlines() if line.startswith(rid)]
    # one row, every column whole: id, created, scenario, origin, samples, feasible/evaluated
    assert re.search(r"latin hypercube +2 +\d/2 +complete +- +\d+(\.\d+)? KiB$", row), row
    shown = runner.invoke(app, ["show", rid, "--store", store])
    manifest = json.loads(shown.stdout)["manifest"]
    assert manifest["run_id"] == rid and manifest["status"] == "complete"
    assert {"numpy", "heyoka", "prefect"} <= manifest["dependencies"].keys()
    one_line = runner.invoke(app, ["show", rid, "--store", store, "--json"])
    assert one_line.exit_code == 0 and one_line.stdout.count("\n") == 1
    assert json.loads(one_line.stdout)["manifest"] == manifest
    replayed = runner.invoke(app, ["replay", rid, "--store", store])
    assert replayed.exit_code == 0
    assert "largest difference from the stored totals  0" in replayed.stdout
    missing = runner.invoke(app, ["show", "0123456789abcdef", "--store", store])
    assert missing.exit_code == 2 and "no such run" in missing.stderr
    malformed = runner.invoke(app, ["show", "nope", "--store", store])
    assert malformed.exit_code == 2 and "is not an id of this store" in malformed.stderr


def test_a_deleted_run_is_recomputed_although_its_tasks_are_cached(prefect_server, tmp_path):
    import shutil

    from flows.doe import run_doe_flow

    config = _config(tmp_path, samples=4, batch_size=2, store=str(tmp_path / "runs"))
    first = run_doe_flow(config=config)
    shutil.rmtree(tmp_path / "runs" / first["run_id"])
    before = execute.EVALUATIONS["count"]
    second = run_doe_flow(config=config)  # same run id, cached task results, no stored files
    assert second["run_id"] == first["run_id"]
    assert execute.EVALUATIONS["count"] - before == 4
    assert second["evaluated"] == 4 and second["status"] == "complete"


def test_cli_run_names_the_runners_and_refuses_a_stray_address(tmp_path):
    from typer.testing import CliRunner

    from ovtraj.cli import app
    from ovtraj.config.mission import RUNNERS

    assert RUNNERS == ("serial", "threads", "processes", "dask")
    runner = CliRunner()
    store = str(tmp_path / "runs")
    bogus = runner.invoke(app, ["run", str(DEFAULT_SCENARIO), "--runner", "gpu", "--store", store])
    assert bogus.exit_code == 2 and "serial, threads, processes, dask" in bogus.stderr
    stray = runner.invoke(
        app,
        ["run", str(DEFAULT_SCENARIO), "--runner", "threads", "--dask-address", "tcp://x:1"],
    )
    assert stray.exit_code == 2 and "--dask-address needs --runner dask" in stray.stderr
    assert not (tmp_path / "runs").exists()
