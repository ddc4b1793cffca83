"""The Prefect layer runs on the pinned stack (temporary local server, no network)."""

from __future__ import annotations

from tests.conftest import DEFAULT_SCENARIO, REPO


def test_rendezvous_flow_end_to_end(prefect_server):
    from flows.rendezvous import rendezvous_flow

    row = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert row["feasible"] is True
    assert row["miss_distance_m"] <= 10.0
    assert row["dv1_mps"] > 0 and row["dv2_mps"] > 0


def test_every_deployment_entrypoint_is_a_flow_taking_its_parameters():
    import importlib
    import inspect

    import yaml
    from prefect import Flow

    from tests.conftest import REPO

    spec = yaml.safe_load((REPO / "prefect.yaml").read_text(encoding="utf-8"))
    names = [d["name"] for d in spec["deployments"]]
    assert {"rendezvous", "launch-fit"} <= set(names)
    for deployment in spec["deployments"]:
        path, attribute = deployment["entrypoint"].split(":")
        module = importlib.import_module(path.removesuffix(".py").replace("/", "."))
        flow_object = getattr(module, attribute)
        assert isinstance(flow_object, Flow), deployment["entrypoint"]
        accepted = inspect.signature(flow_object.fn).parameters
        assert set(deployment.get("parameters", {})) <= set(accepted), deployment["name"]
        for value in deployment.get("parameters", {}).values():
            if isinstance(value, str) and value.startswith("configs/"):
                assert (REPO / value).is_file(), value


def test_every_deployments_defaults_are_a_run_its_flow_accepts():
    """What a quick run from the UI sends: the deployment's parameters, checked as the
    server checks a new flow run's (the flow's parameter schema, as `prefect deploy`
    registers it) and as the flow binds them. A parameter the deployment leaves to the
    caller is a required one its description names (``name=``), never a placeholder
    value; a file a default names exists in the repository."""
    import importlib

    import yaml
    from prefect.utilities.callables import parameter_schema
    from prefect.utilities.schema_tools.validation import validate

    from tests.conftest import REPO

    spec = yaml.safe_load((REPO / "prefect.yaml").read_text(encoding="utf-8"))
    for deployment in spec["deployments"]:
        name, given = deployment["name"], deployment.get("parameters", {})
        path, attribute = deployment["entrypoint"].split(":")
        flow_object = getattr(importlib.import_module(path[:-3].replace("/", ".")), attribute)
        schema = parameter_schema(flow_object).model_dump_for_openapi()
        problems = validate(given, schema)
        missing = {p for p in schema.get("required", []) if p not in given}
        assert [e.message for e in problems if e.validator != "required"] == [], name
        assert all(f"{p}=" in deployment["description"] for p in missing), (name, missing)
        if not missing:
            flow_object.validate_parameters(given)  # binds as a flow run does
        for value in given.values():
            if isinstance(value, str) and value.endswith((".yaml", ".yml", ".json")):
                assert (REPO / value).is_file(), (name, value)


# -- one vocabulary: a flow's parameters are its command's options -------------------------------
# Each flow with a command and the names it takes that the command has not, each with why.
# Every other parameter is one of the command's options in snake case (``--max-dv-mps``:
# ``max_dv_mps``) or its argument (``config``, ``run_id``).
_EXECUTION = "where the flow's tasks run (ovtraj run's options); the command works in its process"
_MONTE_CARLO = {
    "runs": "the count --monte-carlo N gives: the flow is the Monte Carlo only",
    "store": "--store of the other commands; the command stores in the config's store",
    "batch_size": "runs per task; the command flies the config's batches in its process",
    "workers": _EXECUTION,
    "runner": _EXECUTION,
    "dask_address": _EXECUTION,
}
FLOW_COMMANDS = {
    ("flows.rendezvous", "rendezvous_flow"): ("rendezvous", {}),
    ("flows.launch_fit", "launch_fit_flow"): (
        "launch-fit",
        {"runner": _EXECUTION, "dask_address": _EXECUTION},
    ),
    ("flows.doe", "doe_flow"): ("run", {}),
    ("flows.surrogate", "surrogate_flow"): ("optimize", {}),  # its fit, without NSGA-II
    ("flows.optimize", "optimize_flow"): ("optimize", {}),
    ("flows.pipeline", "mission_flow"): (
        "pipeline",
        {"require_converged": "--allow-unconverged turned around (a flow run's state)"},
    ),
    ("flows.window", "window_flow"): (
        "window",
        {"require_converged": "--allow-unconverged turned around (a flow run's state)"},
    ),
    ("flows.mission_monte_carlo", "plan_monte_carlo_flow"): (
        "fly",
        {"plan": "fly's PLAN_FILE argument (a required parameter, named by the deployment)"}
        | _MONTE_CARLO,
    ),
    ("flows.deorbit_monte_carlo", "deorbit_monte_carlo_flow"): (
        "deorbit-burn",
        {
            "strategies": "--strategy's values, several flown side by side",
            "seed": "the config's monte_carlo.seed, which the command always takes",
        }
        | _MONTE_CARLO,
    ),
}


def test_every_flows_parameters_are_its_commands_options_by_name():
    """A flow's parameter is its command's option of the same name in snake case, else
    one of the few the command has not, listed with why: exactly those (a listed name the
    flow no longer takes, or one the command has, fails too)."""
    import importlib
    import inspect

    import typer

    from ovtraj.cli import app

    commands = typer.main.get_command(app).commands
    modules = {p.stem for p in (REPO / "flows").glob("*.py")}
    covered = {module.split(".")[1] for module, _ in FLOW_COMMANDS}
    # every module defining a flow is listed (the helpers have none)
    assert modules - covered == {"__init__", "common", "monte_carlo_tasks", "runners", "verdict"}
    for (module, name), (command, extra) in FLOW_COMMANDS.items():
        flow_object = getattr(importlib.import_module(module), name)
        accepted = set(inspect.signature(flow_object.fn).parameters)
        options = {p.opts[0].lstrip("-").replace("-", "_") for p in commands[command].params}
        assert accepted - options == set(extra), (name, command, accepted - options)


# -- operability: names and tags, one flow run per run, event loops, limits ---------------------
def _doe_config(tmp_path, **doe) -> str:
    import copy

    import yaml

    from tests.conftest import REPO, build_scenario

    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(store=str(tmp_path / "runs"), task_runner="serial", **doe)
    build_scenario(copy.deepcopy(data))
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


def _doe_state(**parameters):
    """The DoE flow run's final state (its id and result), from synchronous code."""
    from flows.common import run_to_completion
    from flows.doe import doe_flow

    return run_to_completion(lambda: doe_flow(**parameters, return_state=True))


def _task_runs(flow_run_id, at_least: int = 0, wait_s: float = 30.0) -> list:
    """The flow run's task runs (the server records them from events: wait for them)."""
    import time

    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import FlowRunFilter, FlowRunFilterId

    deadline = time.monotonic() + wait_s
    with get_client(sync_client=True) as client:
        while True:
            found = client.read_task_runs(
                flow_run_filter=FlowRunFilter(id=FlowRunFilterId(any_=[flow_run_id]))
            )
            if len(found) >= at_least or time.monotonic() > deadline:
                return found
            time.sleep(0.2)


def test_flow_runs_are_named_and_tagged_and_task_runs_named_by_scenario_run_and_batch(
    prefect_server, tmp_path
):
    from prefect.client.orchestration import get_client

    state = _doe_state(config=_doe_config(tmp_path, samples=2, batch_size=2))
    summary = state.result()
    flow_run_id = state.state_details.flow_run_id
    with get_client(sync_client=True) as client:
        flow_run = client.read_flow_run(flow_run_id)
    run_id, scenario = summary["run_id"], summary["scenario"]
    assert flow_run.name == f"doe {scenario} {run_id}"
    assert {"ovtraj", "doe", f"scenario:{scenario}", f"run:{run_id}"} <= set(flow_run.tags)
    (task_run,) = _task_runs(flow_run_id, at_least=1)
    assert task_run.name == f"{scenario}/{run_id}/batch-0x2"
    # No tags on batch task runs: each tagged task run asks the server for tag concurrency
    # slots (tasks.common.BATCH_TAGS); their names say what tags would.
    assert task_run.tags == []


def test_two_flow_runs_of_one_run_never_evaluate_it_at_once(prefect_server, tmp_path):
    """The run's concurrency slot: the second flow run waits, then finds the run complete
    and submits nothing (the store's claims alone would let it submit every batch)."""
    import contextvars
    import threading

    from prefect.client.orchestration import get_client

    from ovtraj.runs import execute

    config = _doe_config(tmp_path, samples=4, batch_size=1)
    states = []

    def one() -> None:
        states.append(_doe_state(config=config))

    threads = [threading.Thread(target=contextvars.copy_context().run, args=(one,)) for _ in "ab"]
    before = execute.EVALUATIONS["count"]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=300)
    assert execute.EVALUATIONS["count"] - before == 4
    summaries = [state.result() for state in states]
    assert {s["run_id"] for s in summaries} == {summaries[0]["run_id"]}
    assert all(s["status"] == "complete" for s in summaries)
    ids = [state.state_details.flow_run_id for state in states]
    first = len(_task_runs(ids[0], at_least=1, wait_s=5))
    evaluated_by, waited = (ids[0], ids[1]) if first else (ids[1], ids[0])
    assert len(_task_runs(evaluated_by, at_least=4)) == 4
    assert len(_task_runs(waited)) == 0
    with get_client(sync_client=True) as client:
        limit = client.read_global_concurrency_limit_by_name(f"ovtraj-run-{summaries[0]['run_id']}")
    assert limit.limit == 1 and limit.active_slots == 0


def test_run_doe_flow_works_inside_a_running_event_loop(prefect_server, tmp_path):
    import asyncio

    from flows.common import call_flow
    from flows.doe import run_doe_flow
    from flows.rendezvous import rendezvous_flow

    config = _doe_config(tmp_path, samples=1, batch_size=1)

    async def notebook() -> tuple:  # a cell of a notebook: its loop is running
        return run_doe_flow(config=config), call_flow(rendezvous_flow, config=config)

    summary, row = asyncio.run(notebook())
    assert summary["status"] == "complete" and summary["evaluated"] == 1
    assert row["feasible"] is True


def test_a_doe_past_its_time_limit_fails_and_its_manifest_says_so(
    prefect_server, tmp_path, monkeypatch
):
    """The flow's wall-time limit (configs/orchestration.yaml flows.doe_s, made 1 s here):
    the batches not started are cancelled, the flow fails naming the limit and the
    manifest ends ``failed``, never ``running``; a later flow run completes the run."""
    import pytest

    import flows.doe
    from flows.common import FlowDeadline
    from flows.doe import run_doe_flow
    from ovtraj.runs import RunStore

    # Enough samples that they cannot all finish within the 1 s limit (the chain takes
    # ~0.08 s a sample: six did, once).
    samples = 30
    config = _doe_config(tmp_path, samples=samples, batch_size=1)
    short = flows.doe.FLOW_TIMEOUTS.model_copy(update={"doe_s": 1.0})
    monkeypatch.setattr(flows.doe, "FLOW_TIMEOUTS", short)
    with pytest.raises(FlowDeadline, match=r"flows\.doe_s"):
        run_doe_flow(config=config)
    store = RunStore(tmp_path / "runs")
    (row,) = store.catalog()
    run = store.run(row["run_id"])
    assert run.manifest["status"] == "failed" and "FlowDeadline" in run.manifest["failure"]
    assert run.status() == "failed" and len(run.done_batches()) < samples
    monkeypatch.undo()
    assert run_doe_flow(config=config)["status"] == "complete"
