"""``flows/pipeline.py:mission_flow`` under a temporary Prefect server.

A 12-sample DoE, two verification rounds of 3 front points, the plan: the verified
front's values must be the real chain's and the artifacts published. (That a second
run simulates nothing is tested on the library pipeline, tests/test_pipeline.py, and
on the DoE flow, tests/test_doe.py.) Its loop cannot converge (no promise tolerance, an
error tolerance of 1e-6): the flow run ends Failed, or Completed named "Not converged",
with the verdict ``ovtraj pipeline --json`` gives; a loop that converges ends Completed,
the command exit 0.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, evaluate
from ovtraj.mission.fly import fly_plan
from ovtraj.mission.plan_store import read_plan
from ovtraj.runs import RunStore, execute
from ovtraj.store.files import read_parquet
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario

OVTRAJ = Path(sys.executable).with_name("ovtraj")


def _small(store: Path, **verify) -> dict:
    """The default scenario with a 12-sample DoE, two regressors and a short NSGA-II, the
    verification settings ``verify``, the store ``store``."""
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(samples=12, batch_size=6, store=str(store))
    data["mission"]["verify"].update(verify)
    data["mission"]["surrogate"].update(
        regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3
    )
    data["mission"]["optimize"].update(population=32, generations=40, warm_start_generations=10)
    return data


def _flow_run_state(state):
    """The flow run's final state as the Prefect server holds it."""
    from prefect.client.orchestration import get_client

    with get_client(sync_client=True) as client:
        return client.read_flow_run(state.state_details.flow_run_id).state


def _flow_result(state) -> dict:
    """What the flow returned: the state's result, or the result a Failed one carries."""
    from flows.verdict import NotConverged

    value = state.result(raise_on_failure=False)
    return value.result if isinstance(value, NotConverged) else value


def _command_json(config: Path, store: Path) -> tuple[int, dict]:
    """``ovtraj pipeline CONFIG --store STORE --json`` in its own process: exit code, JSON."""
    done = subprocess.run(
        [str(OVTRAJ), "pipeline", str(config), "--store", str(store), "--json"],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode in (0, 1), done.stderr[-3000:]
    return done.returncode, json.loads(done.stdout)


def _same_code(*runs: tuple[Path, str]) -> None:
    """The (store, DoE run) pairs were computed by the same code, else the comparison is
    not this test's: a checkout edited while the test ran gives
    the command in its own process other code than this process imported."""
    versions = {RunStore(root).run(run_id).manifest["code_version"] for root, run_id in runs}
    if len(versions) > 1:
        pytest.skip(f"the checkout changed during the test: code versions {sorted(versions)}")


@pytest.fixture(scope="module")
def flown(prefect_server, tmp_path_factory):
    from flows.pipeline import mission_flow

    tmp = tmp_path_factory.mktemp("mission-flow")
    # Two rounds, the second's NSGA-II warm from the first's front (through the front task);
    # judged by the error on the front (no promise tolerance: a fit after each round only),
    # with a tolerance no round meets: the loop stops on its rounds, not converged.
    data = _small(
        tmp / "runs",
        points_per_iteration=3,
        max_iterations=2,
        budget=6,
        promise_tolerance=None,
        tolerance=1e-6,
        hypervolume_tolerance=None,
    )
    config = tmp / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    before = execute.EVALUATIONS["count"]
    state = mission_flow(config=str(config), return_state=True)
    middle = execute.EVALUATIONS["count"]
    # The same pipeline through the command line, into a store of its own.
    from ovtraj.cli import run_command

    cli_store = tmp / "cli-runs"
    cli_exit = run_command(["pipeline", str(config), "--store", str(cli_store), "--json"])
    from prefect.artifacts import Artifact

    artifacts = {key: Artifact.get(key) for key in ("verified-front", "surrogate-validation")}
    return {
        "first": _flow_result(state),
        "failed": state.result(raise_on_failure=False),  # NotConverged, the result in it
        "state": _flow_run_state(state),
        "evaluations": (middle - before,),
        "artifacts": artifacts,
        "scenario": build_scenario(data),
        "store": RunStore(tmp / "runs"),
        "config": config,
        "cli_exit": cli_exit,
        "cli_store": cli_store,
    }


def test_flow_verifies_the_front_with_the_real_chain(flown):
    first = flown["first"]
    assert flown["evaluations"][0] == 12 + first["real_evaluations"]["infill"]
    assert first["real_evaluations"] == {"doe": 12, "infill": 6}
    front = read_parquet(first["front"])
    totals = flown["store"].run(first["final_run"]).totals().set_index("sample_id")
    scenario = flown["scenario"]
    context = MissionContext(scenario, find_launch_fit(scenario))
    for row in front.head(3).itertuples(index=False):
        assert row.t_total_s == totals.loc[row.sample_id, "t_total_s"]
        record = evaluate(context, MissionDesign(*(getattr(row, n) for n in DESIGN_NAMES)))
        assert record.feasible
        assert record.dv_total_mps == pytest.approx(row.dv_total_mps, rel=1e-9)
        assert record.t_total_s == pytest.approx(row.t_total_s, rel=1e-9)
    assert all(artifact is not None for artifact in flown["artifacts"].values())


def test_the_flows_plan_lands_within_its_stated_miss(flown):
    report = fly_plan(read_plan(flown["first"]["plan_json"]))
    assert report.landed_within_stated_miss


def test_the_flows_second_round_starts_from_the_first_rounds_front(flown):
    """optimize.warm_start_generations through the Prefect front task: the second round's
    front names the first's as its warm start and ran the warm generations."""
    import json

    root = flown["store"].root
    markers = [json.loads(p.read_text()) for p in sorted(root.glob("*/fronts/*/meta.json"))]
    by_id = {m["front_id"]: m for m in markers}
    warm = [m for m in markers if m.get("warm_from")]
    assert len(warm) == 1 and len(markers) == 2
    assert warm[0]["warm_from"] in by_id
    assert warm[0]["nsga2"]["generations"] < by_id[warm[0]["warm_from"]]["nsga2"]["generations"]


def _stored_files(root) -> dict[str, object]:
    """Every file of a store: its bytes, or for a JSON marker its content without the
    host data a store holds: creation times, the timing of batches and fits, and the
    environment that computed them."""
    import json

    def timeless(value, key=""):
        if isinstance(value, dict):
            return {
                k: timeless(v, k)
                for k, v in value.items()
                if k not in ("created_utc", "timing", "environment")
                # a marker's digest of a nested marker: that one is compared without its times
                and not (key == "files" and k.endswith(".json"))
            }
        if isinstance(value, list):
            return [timeless(v) for v in value]
        return value

    files: dict[str, object] = {}
    for path in sorted(root.rglob("*")):
        if path.is_file() and not path.name.endswith(".lock"):
            name = str(path.relative_to(root))
            data = path.read_bytes()
            if name.startswith("catalog/history/") or name == "catalog/stamps.json":
                # the trend the flow draws for its artifact (ovtraj history's view); the
                # catalog's cache of its documents' sizes, times and inodes (host data)
                continue
            if name.startswith("catalog/"):
                files[name] = _catalog_content(path)
                continue
            files[name] = timeless(json.loads(data)) if path.suffix == ".json" else data
    return files


def _catalog_content(path):
    """The store's catalog without the creation times (its rows are derived from the
    stored documents, each row's ``source_sha256`` from a manifest that holds one)."""
    import json

    import pyarrow.parquet as pq

    if path.name == "catalog.json":
        return json.loads(path.read_bytes())["rows"]
    if path.suffix == ".parquet":
        table = pq.read_table(path).drop_columns(["created_utc", "source_sha256"])
        # Rows follow their creation times (timing): compared in the order of their source.
        return sorted(table.to_pylist(), key=lambda row: (row["kind"], row["source"]))
    return path.read_bytes()


def test_the_flow_and_the_command_line_store_the_same_pipeline(flown):
    """``mission_flow`` and ``ovtraj pipeline`` are adapters of one driver
    (``ovtraj.pipeline.drive``): the same inputs give the same stored files, byte for byte
    (JSON markers without their creation times and timing): runs, batches, fits, fronts, the
    verified front, the plan, its plots and report. Not converged: the command exits 1,
    everything stored all the same."""
    assert flown["cli_exit"] == 1
    flow_files = _stored_files(flown["store"].root)
    cli_files = _stored_files(flown["cli_store"])
    assert sorted(flow_files) == sorted(cli_files)
    assert any(name.endswith("report.html") for name in flow_files)
    differing = [name for name in flow_files if flow_files[name] != cli_files[name]]
    assert differing == []
    # Identical inputs, so `ovtraj diff` of the two plans (and of the two DoE runs) is empty,
    # while the plan's own figures are all there (--all).
    from ovtraj.cli import run_command

    plan = Path(flown["first"]["plan_json"])
    twin = flown["cli_store"] / plan.relative_to(flown["store"].root)
    assert twin.is_file() and twin != plan
    for a, b in ((plan, twin), (plan.parents[3], twin.parents[3])):
        found = _diff_json(run_command, [str(a), str(b), "--store", str(flown["cli_store"])])
        assert found["changed"] == 0 and found["fields"] == []
    everything = _diff_json(run_command, [str(plan), str(twin), "--all"])
    assert len(everything["fields"]) > 100 and not any(f["changed"] for f in everything["fields"])


def test_the_flow_takes_the_commands_options_and_builds_its_request(flown, monkeypatch):
    """The flow's parameters are ``ovtraj pipeline``'s options by name: the same run,
    refit, pick weights and limits (binding: the point picked by default is excluded)
    give the driver the same request from both, and the same plan. Both run the real
    driver on the command's store (its runs reused); each call's request is recorded on
    its way in."""
    import inspect

    import typer

    import flows.pipeline
    from flows.pipeline import mission_flow
    from ovtraj.cli import app, run_command
    from ovtraj.optimize import Normalisation
    from ovtraj.pipeline import drive
    from ovtraj.pipeline.pick import Pick, pick_front_point

    # Every option of the command is a parameter of the flow, its name the option's in
    # snake case; but --json (a flow returns its result) and --allow-unconverged, which
    # the flow's require_converged turns around.
    command = typer.main.get_command(app).commands["pipeline"]
    options = {p.opts[0].lstrip("-").replace("-", "_") for p in command.params}
    accepted = set(inspect.signature(mission_flow.fn).parameters)
    assert options - {"json", "allow_unconverged"} | {"require_converged"} == accepted
    store, doe_run = flown["cli_store"], flown["first"]["doe_run"]
    front = read_parquet(flown["first"]["front"])
    # Limits every point meets, then one moved past the point the weights pick without
    # limits, halfway to the next point that is better in that objective.
    weights = [1.0, 2.0, 0.5]
    normalisation = Normalisation.mission(flown["scenario"].mission.optimize)
    unlimited = pick_front_point(front, normalisation, Pick(weights=tuple(weights)))
    limits = {
        "max_time_h": float(front["t_total_s"].max()) / 3600.0,
        "max_dv_mps": float(front["dv_total_mps"].max()),
        "min_payload_kg": float(front["m_load_kg"].min()),
    }
    for name, column, scale, sense in (
        ("max_dv_mps", "dv_total_mps", 1.0, -1),
        ("max_time_h", "t_total_s", 1 / 3600.0, -1),
        ("min_payload_kg", "m_load_kg", 1.0, 1),
    ):
        value = unlimited[column]
        better = front[column][(front[column] - value) * sense > 0]
        if len(better):
            nearest = better.min() if sense > 0 else better.max()
            limits[name] = float((value + nearest) / 2.0 * scale)
            break
    assert len(front) > 1 and limits != {
        "max_time_h": float(front["t_total_s"].max()) / 3600.0,
        "max_dv_mps": float(front["dv_total_mps"].max()),
        "min_payload_kg": float(front["m_load_kg"].min()),
    }
    requests = []

    def recorded(real):
        def driver(*args, **kwargs):
            requests.append(args[5])
            return real(*args, **kwargs)

        return driver

    monkeypatch.setattr(drive, "drive_pipeline", recorded(drive.drive_pipeline))
    monkeypatch.setattr(flows.pipeline, "drive_pipeline", recorded(flows.pipeline.drive_pipeline))
    args = ["pipeline", str(flown["config"]), "--store", str(store), "--run", doe_run, "--refit"]
    args += ["--weights", ",".join(f"{w:g}" for w in weights)]
    args += [f"--{name.replace('_', '-')}={value!r}" for name, value in limits.items()]
    out = _command_output(run_command, [*args, "--json", "--allow-unconverged"])
    state = mission_flow(
        config=str(flown["config"]),
        store=str(store),
        run=doe_run,
        refit=True,
        weights=weights,
        **limits,
        require_converged=False,
        return_state=True,
    )
    flow = state.result()
    command_request, flow_request = requests
    assert command_request == flow_request
    assert flow_request.refit is True and flow_request.from_run == doe_run
    assert (flow_request.pick.weights, flow_request.pick.max_dv_total_mps) == (
        tuple(weights),
        limits["max_dv_mps"],
    )
    assert (flow["pick"], flow["plan_json"]) == (out["pick"], out["plan_json"])
    assert flow["doe_run"] == out["doe_run"] == doe_run
    chosen = read_plan(flow["plan_json"]).source["front_index"]
    assert chosen != unlimited["front_index"]  # the limit moved the pick


def _command_output(run_command, args):
    import contextlib
    import io
    import json

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert run_command(args) == 0
    return json.loads(out.getvalue())


def _diff_json(run_command, args):
    import contextlib
    import io
    import json

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert run_command(["diff", *args, "--json"]) == 0
    return json.loads(out.getvalue())


@pytest.mark.slow
def test_an_unconverged_flow_run_is_failed_with_the_commands_verdict(flown):
    """The loop that did not converge: the flow run Failed on the server, the verdict its
    message, the flow's result (stored, published) carried by the state; ``ovtraj pipeline
    --json`` in its own process gives the same flag and verdict, exit 1 (the store is the
    command's own: a second run, its results reused)."""
    from prefect.client.schemas.objects import StateType

    first, state = flown["first"], flown["state"]
    assert first["converged"] is False and first["verdict"].startswith("not converged: ")
    assert state.type == StateType.FAILED and state.message == first["verdict"]
    assert str(flown["failed"]) == first["verdict"]
    assert Path(first["plan_json"]).is_file() and Path(first["report"]).is_file()
    code, printed = _command_json(flown["config"], flown["cli_store"])
    _same_code((flown["store"].root, first["doe_run"]), (flown["cli_store"], printed["doe_run"]))
    assert code == 1
    assert (printed["converged"], printed["verdict"]) == (first["converged"], first["verdict"])
    assert printed["stop_reason"] == first["stop_reason"] == "max_iterations"


def test_an_unconverged_flow_run_allowed_is_completed_and_named(flown):
    """``require_converged=False``: Completed, named "Not converged", the verdict its
    message; the flow returns its result (everything served by the store)."""
    from prefect.client.schemas.objects import StateType

    from flows.pipeline import mission_flow
    from flows.verdict import NOT_CONVERGED

    before = execute.EVALUATIONS["count"]
    state = mission_flow(config=str(flown["config"]), require_converged=False, return_state=True)
    assert execute.EVALUATIONS["count"] == before
    again = state.result()
    assert again == flown["first"]
    stored = _flow_run_state(state)
    assert stored.type == StateType.COMPLETED and stored.name == NOT_CONVERGED
    assert stored.message == again["verdict"]


@pytest.mark.slow
def test_a_converged_loop_is_a_completed_flow_run_and_exit_0(prefect_server, tmp_path):
    """One round, then converged by promise (the shipped criterion) once the surrogates
    promise less than the verified front's whole hypervolume again: ``ovtraj pipeline
    --json`` exits 0, converged; ``mission_flow`` on the command's store (its results
    reused) says the same verdict, and its run is Completed, the plain state."""
    from prefect.client.schemas.objects import StateType

    from flows.pipeline import mission_flow

    store = tmp_path / "runs"
    data = _small(store, points_per_iteration=2, max_iterations=1, budget=2, promise_tolerance=1.0)
    config = tmp_path / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    code, printed = _command_json(config, store)
    assert (code, printed["converged"]) == (0, True), printed["verdict"]
    state = mission_flow(config=str(config), store=str(store), return_state=True)
    flow = _flow_result(state)
    _same_code((store, flow["doe_run"]), (store, printed["doe_run"]))
    assert (flow["converged"], flow["verdict"]) == (printed["converged"], printed["verdict"])
    assert Path(flow["plan_json"]).resolve() == Path(printed["plan_json"])
    stored = _flow_run_state(state)
    assert stored.type == StateType.COMPLETED and stored.name == "Completed"
