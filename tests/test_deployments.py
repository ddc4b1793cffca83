"""Scheduled runs against a real Prefect server and a real process worker.

The module starts ``prefect server start`` as a subprocess on a free port of 127.0.0.1,
with its own ``PREFECT_HOME`` in a temporary folder (database, profiles, results), no
UI, no analytics and no ``PREFECT_*`` variable inherited from the caller, creates the
README's work pool and runs ``prefect deploy --all`` from the repository root, as the
README's "Scheduled runs" section does. The first test waits for the server's scheduler
to create the cron deployments' flow runs; the second starts a process worker and runs
the rendezvous deployment, triggered by hand with a parameter, to completion.

The scheduler loops every 5 s here instead of 60 s (the same code path, sooner);
Prefect 3.8 with SQLAlchemy 2.1 failed in it every loop and never created a run.
The ovtraj workspace of the flow runs (``OVTRAJ_HOME``) is a temporary folder too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import yaml

from tests.conftest import REPO, free_port

# Left out of the fast tier (-m "not slow"): it starts a Prefect server, a work pool and a process
# worker.
pytestmark = pytest.mark.slow

PREFECT = Path(sys.executable).with_name("prefect")
POOL = "ovtraj-process"
SERVER_START_TIMEOUT_S = 120.0
SCHEDULE_TIMEOUT_S = 90.0
RUN_TIMEOUT_S = 150.0
# What the scheduler logged when it failed (Prefect 3.8 with SQLAlchemy 2.1).
SCHEDULER_ERRORS = ("Traceback", "InvalidRequestError", "bulk DML", "Unexpected error")
TERMINAL = {"COMPLETED", "FAILED", "CRASHED", "CANCELLED"}


@dataclasses.dataclass(frozen=True)
class Server:
    api: str
    env: dict[str, str]
    log: Path
    root: Path
    deployed_at: float  # time.monotonic() at the end of `prefect deploy --all`

    def post(self, path: str, body: dict[str, Any] | None = None) -> Any:
        response = httpx.post(f"{self.api}{path}", json=body or {}, timeout=30)
        response.raise_for_status()
        return response.json() if response.content else None

    def get(self, path: str) -> Any:
        response = httpx.get(f"{self.api}{path}", timeout=30)
        response.raise_for_status()
        return response.json()

    def prefect(self, *args: str, timeout: float = 120) -> str:
        """Run the ``prefect`` command against this server from the repository root."""
        done = subprocess.run(
            [str(PREFECT), *args],
            cwd=REPO,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        output = done.stdout + done.stderr
        assert done.returncode == 0, f"prefect {' '.join(args)} exited {done.returncode}:\n{output}"
        return output


def _declared() -> list[dict[str, Any]]:
    spec = yaml.safe_load((REPO / "prefect.yaml").read_text(encoding="utf-8"))
    return spec["deployments"]


def _environment(root: Path, api: str) -> dict[str, str]:
    """The caller's environment without any PREFECT_/OVTRAJ_ setting, plus ours."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PREFECT_", "OVTRAJ_"))}
    env.update(
        PREFECT_HOME=str(root / "prefect-home"),
        PREFECT_API_URL=api,
        PREFECT_SERVER_ANALYTICS_ENABLED="false",
        PREFECT_SERVER_UI_ENABLED="false",
        PREFECT_SERVER_SERVICES_SCHEDULER_LOOP_SECONDS="5",
        OVTRAJ_HOME=str(root / "ovtraj-home"),
    )
    return env


def _start(args: list[str], env: dict[str, str], log: Path, cwd: Path) -> subprocess.Popen:
    """A process in its own session: its group id is its pid, children included."""
    with open(log, "wb") as out:
        return subprocess.Popen(
            args, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
        )


def _stop(process: subprocess.Popen, first: int, timeout_s: float = 30.0) -> None:
    """Signal the process group started as ``process`` (its pid), then kill it after a while."""
    for sig in (first, signal.SIGKILL):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass
        try:
            process.wait(timeout=timeout_s)
            return
        except subprocess.TimeoutExpired:
            continue


def _tail(path: Path, lines: int = 40) -> str:
    return "\n".join(path.read_text(encoding="utf-8", errors="replace").splitlines()[-lines:])


@contextlib.contextmanager
def prefect_server(root: Path, **settings: str) -> Iterator[tuple[str, dict[str, str], Path]]:
    """``prefect server start`` on a free port of 127.0.0.1 with its own PREFECT_HOME in
    ``root`` (and ``settings`` in its environment); yields (address, environment, log)
    once its API answers, and stops its process group afterwards."""
    port = free_port()
    address = f"http://127.0.0.1:{port}"
    env = _environment(root, f"{address}/api")
    env.update(settings)
    log = root / "server.log"
    command = [str(PREFECT), "server", "start", "--host", "127.0.0.1", "--port", str(port)]
    process = _start(command, env, log, root)
    try:
        started = time.monotonic()
        while True:
            assert process.poll() is None, f"the server exited {process.returncode}:\n{_tail(log)}"
            try:
                if httpx.get(f"{address}/api/health", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            waited = time.monotonic() - started
            assert waited < SERVER_START_TIMEOUT_S, f"no server after {waited:.0f} s:\n{_tail(log)}"
            time.sleep(0.5)
        print(f"\nserver up in {time.monotonic() - started:.1f} s")
        yield address, env, log
    finally:
        _stop(process, signal.SIGTERM)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A real Prefect server with the work pool and every deployment of prefect.yaml."""
    root = tmp_path_factory.mktemp("prefect-server")
    with prefect_server(root) as (address, env, log):
        running = Server(api=f"{address}/api", env=env, log=log, root=root, deployed_at=0.0)
        running.prefect("work-pool", "create", POOL, "--type", "process")
        running.prefect("--no-prompt", "deploy", "--all")
        yield dataclasses.replace(running, deployed_at=time.monotonic())
    assert (root / "prefect-home" / "prefect.db").is_file()  # its own PREFECT_HOME


def _deployments(server: Server) -> dict[str, dict[str, Any]]:
    return {d["name"]: d for d in server.post("/deployments/filter")}


def test_deploy_all_registers_every_deployment_run_from_the_repository(server):
    deployed = _deployments(server)
    declared = _declared()
    assert set(deployed) == {d["name"] for d in declared}
    for spec in declared:
        deployment = deployed[spec["name"]]
        assert deployment["entrypoint"] == spec["entrypoint"]
        assert deployment["parameters"] == spec.get("parameters", {})
        assert deployment["work_pool_name"] == POOL
        assert [s["schedule"]["cron"] for s in deployment["schedules"]] == [
            s["cron"] for s in spec.get("schedules", [])
        ]
        # The worker's flow run changes to the checkout that was deployed.
        (step,) = deployment["pull_steps"]
        directory = step["prefect.deployments.steps.set_working_directory"]["directory"]
        assert Path(directory).samefile(REPO), deployment["name"]


def test_server_schedules_the_cron_deployments_without_scheduler_errors(server):
    cron = {d["name"]: d for d in _declared() if d.get("schedules")}
    assert {"doe-nightly", "mission-replan"} <= set(cron)
    names = {d["id"]: name for name, d in _deployments(server).items()}
    while True:
        log = server.log.read_text(encoding="utf-8", errors="replace")
        assert not [e for e in SCHEDULER_ERRORS if e in log], _tail(server.log, 60)
        runs = server.post(
            "/flow_runs/filter", {"flow_runs": {"state": {"type": {"any_": ["SCHEDULED"]}}}}
        )
        per_deployment: dict[str, list[dict[str, Any]]] = {}
        for run in runs:
            per_deployment.setdefault(names.get(run["deployment_id"], "?"), []).append(run)
        waited = time.monotonic() - server.deployed_at
        if set(cron) <= set(per_deployment):
            break
        assert waited < SCHEDULE_TIMEOUT_S, (
            f"after {waited:.0f} s, scheduled runs only for {sorted(per_deployment)}; "
            f"server log:\n{_tail(server.log)}"
        )
        time.sleep(2)
    counts = {name: len(found) for name, found in sorted(per_deployment.items())}
    print(f"\nscheduled runs {counts} at most {waited:.1f} s after the deploy")
    assert set(per_deployment) == set(cron)  # only the cron deployments run on their own
    now = datetime.datetime.now(datetime.UTC)
    for name, found in per_deployment.items():
        minute, hour = (int(f) for f in cron[name]["schedules"][0]["cron"].split()[:2])
        for run in found:
            start = datetime.datetime.fromisoformat(run["expected_start_time"])
            assert start > now and (start.hour, start.minute) == (hour, minute), (name, start)
            assert run["auto_scheduled"] is True
            assert run["parameters"] == cron[name].get("parameters", {})
    log = server.log.read_text(encoding="utf-8", errors="replace")
    assert not [e for e in SCHEDULER_ERRORS if e in log], _tail(server.log, 60)


def _flow_run_logs(server: Server, flow_run_id: str, until: str, timeout_s: float = 20) -> str:
    """The flow run's log messages; they reach the API in batches, after its final state."""
    started = time.monotonic()
    while True:
        logs = server.post("/logs/filter", {"logs": {"flow_run_id": {"any_": [flow_run_id]}}})
        messages = "\n".join(entry["message"] for entry in logs)
        if until in messages or time.monotonic() - started > timeout_s:
            return messages
        time.sleep(1)


def test_worker_runs_a_deployment_triggered_by_hand(server):
    # Pause the cron deployments: their runs are next night's, but this worker must only
    # ever pick up the run below, whatever the time of day.
    for deployment in _deployments(server).values():
        if deployment["schedules"]:
            server.post(f"/deployments/{deployment['id']}/pause_deployment")
    workdir = server.root / "worker-cwd"  # not the repository: the pull step moves there
    workdir.mkdir()
    log = server.root / "worker.log"
    # The worker asks for scheduled runs every second, not every 10 s (Prefect's default):
    # the run starts as soon as it is triggered.
    env = server.env | {"PREFECT_WORKER_QUERY_SECONDS": "1"}
    worker = _start([str(PREFECT), "worker", "start", "--pool", POOL], env, log, workdir)
    try:
        started = time.monotonic()
        output = server.prefect(
            "deployment", "run", "rendezvous/rendezvous", "--param", "config=configs/scenario.yaml"
        )
        flow_run_id = re.search(r"UUID: ([0-9a-f-]{36})", output).group(1)
        while True:
            run = server.get(f"/flow_runs/{flow_run_id}")
            waited = time.monotonic() - started
            if run["state_type"] in TERMINAL:
                break
            assert worker.poll() is None, f"the worker exited {worker.returncode}:\n{_tail(log)}"
            assert waited < RUN_TIMEOUT_S, f"{run['state_name']} after {waited:.0f} s\n{_tail(log)}"
            time.sleep(1)
        print(f"\nrendezvous/rendezvous {run['state_name']} {waited:.1f} s after the trigger")
        assert run["state_type"] == "COMPLETED", _tail(log)
        assert run["parameters"] == {"config": "configs/scenario.yaml"}
        messages = _flow_run_logs(server, flow_run_id, until="feasible=True")
        assert "feasible=True" in messages, messages
        others = server.post(
            "/flow_runs/filter", {"flow_runs": {"id": {"not_any_": [flow_run_id]}}}
        )
        assert all(other["state_type"] == "SCHEDULED" for other in others)
    finally:
        _stop(worker, signal.SIGINT)  # as Ctrl-C in the worker's terminal
    assert worker.returncode is not None


def test_a_quick_run_of_each_deployment_is_accepted_or_names_what_it_needs(server):
    """A quick run from the UI: a flow run of the deployment with its own parameters. The
    server (the flow's parameter schema enforced) accepts it when the deployment gives
    every required parameter, else refuses it naming the one missing, which the
    deployment's description asks for (``name=``): never a run that fails on a
    placeholder. The runs made are deleted before any worker could take them."""
    declared = {d["name"]: d for d in _declared()}
    outcomes = {}
    for name, deployment in _deployments(server).items():
        assert deployment["enforce_parameter_schema"] is True, name
        response = httpx.post(
            f"{server.api}/deployments/{deployment['id']}/create_flow_run", json={}, timeout=30
        )
        required = deployment["parameter_openapi_schema"].get("required", [])
        missing = [p for p in required if p not in deployment["parameters"]]
        if missing:
            assert response.status_code == 409, (name, response.text)
            assert all(repr(p) in response.text for p in missing), (name, response.text)
            assert all(f"{p}=" in declared[name]["description"] for p in missing), name
        else:
            assert response.status_code == 201, (name, response.text)
            run = response.json()
            assert run["parameters"] == deployment["parameters"], name
            httpx.delete(f"{server.api}/flow_runs/{run['id']}", timeout=30).raise_for_status()
        outcomes[name] = "refused" if missing else "accepted"
    assert outcomes["plan-monte-carlo"] == "refused" and outcomes["mission-replan"] == "accepted"
