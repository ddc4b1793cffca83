"""The DoE on an existing Dask cluster of real processes.

A ``dask scheduler`` and two ``dask worker`` processes are started by this module on
127.0.0.1, each in a folder of its own, without the checkout on their path (the
workers import the installed package only; ``tasks``/``flows`` travel by value). Each
is a process group of its own, stopped by its PID. The DoE runs through ``ovtraj run
--runner dask --dask-address`` (the CLI in this process, against the session's Prefect
server, which the workers reach through the settings the tasks carry).

1. a config with a relative store: every sample lands in the store the command names,
   none in the workers' folders, and no evaluation in this process; ``ovtraj pipeline``
   fits its surrogates' candidates and draws its plots there too, and stores the files of
   the same pipeline run serially;
2. a worker killed (SIGKILL, its whole process group) after the first stored batch:
   its batch is run again on the other worker, the run completes with every sample and
   each batch stored once;
3. a worker that cannot import ovtraj (a venv holding distributed and Prefect but not
   the project) joins: the flow fails within the configured bound, naming the worker and
   the cause, and the run's manifest ends ``failed``.
"""

from __future__ import annotations

import copy
import os
import re
import signal
import subprocess
import sys
import sysconfig
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from ovtraj.config.orchestration import RESULTS_ENV
from ovtraj.environment import CORETYPE_ENV, pin
from ovtraj.runs import RunStore
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario, free_port, held_claim

# Left out of the fast tier (-m "not slow"): it starts a Dask scheduler and workers and runs DoEs
# on them.
pytestmark = pytest.mark.slow

DASK = Path(sys.executable).with_name("dask")
OVTRAJ = Path(sys.executable).with_name("ovtraj")
START_TIMEOUT_S = 90.0
RUN_TIMEOUT_S = 300.0


def _environment() -> dict[str, str]:
    """This environment without the checkout on the path, nor ovtraj or Prefect settings;
    OpenBLAS on ovtraj's pinned kernel, as docs/mission.md starts a `dask worker` (which
    loads numpy before it imports ovtraj)."""
    drop = ("PYTHONPATH", "OVTRAJ_", "PREFECT_")
    env = {k: v for k, v in os.environ.items() if not k.startswith(drop)}
    env["PREFECT_SERVER_ANALYTICS_ENABLED"] = "false"
    if pin().kernel is not None:
        env[CORETYPE_ENV] = pin().kernel
    return env


class Cluster:
    """A scheduler and workers as process groups, each in its own folder."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.port = free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.processes: dict[str, subprocess.Popen] = {}
        self.folders: dict[str, Path] = {}

    def start(
        self, name: str, command: list[str], env: dict[str, str] | None = None
    ) -> subprocess.Popen:
        """``command`` in a folder and a process group of its own, in :func:`_environment`
        updated by ``env``."""
        folder = self.root / name
        folder.mkdir()
        logs = self.root / "logs"
        logs.mkdir(exist_ok=True)
        with open(logs / f"{name}.log", "wb") as out:
            process = subprocess.Popen(
                command,
                cwd=folder,
                env=_environment() | (env or {}),
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # its own group: the worker's nanny and process
            )
        self.processes[name], self.folders[name] = process, folder
        return process

    def worker(
        self, name: str, python: Path | None = None, env: dict[str, str] | None = None
    ) -> subprocess.Popen:
        """``dask worker`` (of ``python``'s environment when given), one thread."""
        if python is None:
            command = [str(DASK), "worker", self.address]
        else:
            command = [str(python), "-m", "distributed.cli.dask_worker", self.address]
        options = ["--nthreads", "1", "--name", name, "--no-dashboard"]
        return self.start(name, [*command, *options], env)

    def replace_lost_workers(self, names: list[str]) -> None:
        """Start again each of ``names`` that has exited (a previous test killed it)."""
        for name in names:
            if self.processes[name].poll() is not None:
                del self.processes[name]
                self.worker(f"{name}-{len(self.processes)}")
        self.wait_for_workers(len(names))

    def log(self, name: str) -> str:
        return (self.root / "logs" / f"{name}.log").read_text(encoding="utf-8", errors="replace")

    def workers(self) -> int:
        from distributed import Client

        with Client(self.address, timeout=30) as client:
            return len(client.scheduler_info(n_workers=-1)["workers"])

    def wait_for_workers(self, count: int) -> None:
        started = time.monotonic()
        while self.workers() != count:
            assert time.monotonic() - started < START_TIMEOUT_S, self.log("scheduler")
            time.sleep(0.5)

    def kill(self, name: str, sig: int = signal.SIGKILL) -> None:
        process = self.processes[name]
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=30)

    def stop(self) -> None:
        for name in reversed(list(self.processes)):
            if self.processes[name].poll() is None:
                self.kill(name, signal.SIGTERM)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    cluster = Cluster(tmp_path_factory.mktemp("dask-cluster"))
    try:
        cluster.start(
            "scheduler",
            [
                str(DASK),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(cluster.port),
                "--no-dashboard",
            ],
        )
        cluster.worker("worker-1")
        cluster.worker("worker-2")
        cluster.wait_for_workers(2)
        yield cluster
    finally:
        cluster.stop()


def _config(folder: Path, **doe: Any) -> Path:
    """A scenario file whose store is relative (``runs``, beside the file)."""
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(store="runs", task_retries=0, **doe)
    build_scenario(copy.deepcopy(data))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


VIAS = ["cli", "flow"]


def _run(
    config: Path, address: str, server: dict[str, Any], via: str
) -> subprocess.CompletedProcess:
    """The DoE of ``config`` on the cluster at ``address``, a process of its own:

    - ``cli``: ``ovtraj run CONFIG --runner dask --dask-address ADDRESS`` started in the
      config's folder (the library's pool, no Prefect);
    - ``flow``: ``run_doe_flow(config, runner="dask", dask_address=ADDRESS)`` of this
      checkout against the session's Prefect server (the workers run Prefect tasks).
    """
    from prefect.settings import PREFECT_API_URL

    env = _environment()
    if via == "cli":
        command = [str(OVTRAJ), "run", str(config), "--runner", "dask", "--dask-address", address]
        cwd = config.parent
    else:
        env |= {
            "PREFECT_API_URL": PREFECT_API_URL.value(),
            "PREFECT_HOME": str(server["home"]),
            RESULTS_ENV: str(server["results"]),
        }
        script = (
            "import json, sys\n"
            "from flows.doe import run_doe_flow\n"
            "from ovtraj.target_sources import load_scenario\n"
            "from ovtraj.runs import RunStore\n"
            "summary = run_doe_flow(config=sys.argv[1], runner='dask', dask_address=sys.argv[2])\n"
            "store = RunStore.for_scenario(load_scenario(sys.argv[1]), sys.argv[1], None)\n"
            "print('stored in', store.run(summary['run_id']).url)\n"
        )
        command = [sys.executable, "-c", script, str(config), address]
        cwd = REPO
    return subprocess.run(
        command, cwd=cwd, env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT_S
    )


def _stored_in(output: str) -> Path:
    match = re.search(r"^stored in (.+)$", output, flags=re.MULTILINE)
    assert match, output
    return Path(match.group(1))


def _files(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.is_file()]


@pytest.mark.parametrize("via", VIAS)
def test_every_sample_lands_in_the_store_the_command_names(prefect_server, cluster, tmp_path, via):
    config = _config(tmp_path / "project", samples=4, batch_size=2)
    done = _run(config, cluster.address, prefect_server, via)
    assert done.returncode == 0, done.stdout + done.stderr
    stored = _stored_in(done.stdout)
    assert stored.parent == tmp_path / "project" / "runs"
    run = RunStore(stored.parent).run(stored.name)
    assert run.manifest["status"] == "complete"
    assert list(run.totals()["sample_id"]) == [0, 1, 2, 3]
    assert run.verify().clean
    for name in ("worker-1", "worker-2"):
        assert not _files(cluster.folders[name]), name  # no store, no runs/ beside a worker
    if via == "flow":
        workers_log = cluster.log("worker-1") + cluster.log("worker-2")
        assert f"{run.id}/batch-" in workers_log  # the batches ran there (task run names)
    else:
        assert "batch 1/2" in done.stdout and "batch 2/2" in done.stdout


def _pipeline_config(folder: Path) -> Path:
    """A small pipeline (12-sample DoE, one round of 2 infill points), store ``runs``."""
    config = _config(folder, batch_size=6)
    data = yaml.safe_load(config.read_text(encoding="utf-8"))
    data["mission"]["verify"].update(
        points_per_iteration=2, max_iterations=1, budget=2, hypervolume_tolerance=None
    )
    data["mission"]["surrogate"].update(
        regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3
    )
    data["mission"]["optimize"].update(population=32, generations=40)
    build_scenario(copy.deepcopy(data))
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    return config


def _loaded_on_workers(address: str, module: str) -> list[bool]:
    from distributed import Client

    with Client(address, timeout=30) as client:
        return list(client.run(lambda: module in sys.modules).values())


def test_the_pipeline_fits_and_draws_on_the_cluster_the_files_of_a_serial_run(cluster, tmp_path):
    """``ovtraj pipeline --runner dask`` (the scheduler in ``OVTRAJ_DASK_ADDRESS``): the
    DoE and infill batches, the surrogate candidates' CV fits and the final plots run on
    the cluster's workers; this process writes every file, byte for byte those of the same
    pipeline run serially."""
    cluster.wait_for_workers(2)  # before any test stops one
    assert not any(_loaded_on_workers(cluster.address, "ovtraj.plots.front"))
    stored = {}
    for runner in ("dask", "serial"):
        config = _pipeline_config(tmp_path / runner)
        command = [str(OVTRAJ), "pipeline", str(config), "--samples", "12", "--runner", runner]
        command.append("--allow-unconverged")  # one round of 2 points: the files, not the verdict
        environment = _environment()
        if runner == "dask":  # named by the environment, never by the scenario (a shared file)
            environment["OVTRAJ_DASK_ADDRESS"] = cluster.address
        done = subprocess.run(
            command,
            cwd=config.parent,
            env=environment,
            capture_output=True,
            text=True,
            timeout=RUN_TIMEOUT_S,
        )
        assert done.returncode == 0, done.stdout + done.stderr
        line = next(x for x in done.stdout.splitlines() if x.startswith("front: "))
        front = Path(line.split(": ", 1)[1])
        assert front.is_absolute() and front.is_relative_to(tmp_path / runner / "runs")
        stored[runner] = {
            p.name: p.read_bytes()
            for p in front.parent.iterdir()
            if p.is_file() and p.name != "pipeline.json"  # it holds the creation time
        }
    names = set(stored["serial"])
    assert {"front.parquet", "verification.parquet", "front.png", "surrogate-front.png"} <= names
    assert any(name.startswith("parity-") for name in names)
    assert stored["dask"] == stored["serial"]
    # The fits and the plots ran there (the DoE batches import neither), and no file did.
    assert any(_loaded_on_workers(cluster.address, "ovtraj.surrogate.regressor_selection"))
    assert any(_loaded_on_workers(cluster.address, "ovtraj.plots.front"))
    for name, folder in cluster.folders.items():
        if name != "scheduler":
            assert not _files(folder), name


@pytest.mark.parametrize("via", VIAS)
def test_a_lost_worker_has_its_batch_run_again_on_the_other(prefect_server, cluster, tmp_path, via):
    cluster.replace_lost_workers(["worker-1", "worker-2"])
    config = _config(tmp_path / "project", samples=6, batch_size=2)
    store = tmp_path / "project" / "runs"
    killed: dict[str, Any] = {}
    seen: list[Any] = []
    finished = threading.Event()

    def kill_a_busy_worker() -> None:
        while not finished.is_set():
            runs = [d for d in store.glob("*") if (d / "batches").is_dir()]
            if runs and any((runs[0] / "batches").glob("*.json")):
                held = held_claim(runs[0])
                seen.append(held)
                if held is not None:
                    batch, pid = held
                    group = os.getpgid(pid)
                    name = next(n for n, p in cluster.processes.items() if p.pid == group)
                    cluster.kill(name)  # SIGKILL: the nanny and the worker, mid-batch
                    killed.update(batch=batch, worker=name, pid=pid)
                    return
            time.sleep(0.01)

    killer = threading.Thread(target=kill_a_busy_worker, daemon=True)
    killer.start()
    try:
        done = _run(config, cluster.address, prefect_server, via)
    finally:
        finished.set()
        killer.join(timeout=RUN_TIMEOUT_S)
    assert done.returncode == 0, done.stdout + done.stderr
    assert killed, f"no worker was caught computing a batch: {seen[-20:]}"
    assert cluster.processes[killed["worker"]].poll() is not None
    run = RunStore(store).run(_stored_in(done.stdout).name)
    assert run.manifest["status"] == "complete" and run.manifest["evaluated"] == 6
    markers = run.markers()
    assert sorted(markers) == [0, 1, 2] and killed["batch"] in markers
    ids = sorted(i for marker in markers.values() for i in marker["sample_ids"])
    assert ids == list(range(6))  # every sample, each batch stored once
    assert run.verify().clean and not run.verify().uncovered
    assert cluster.workers() == 1


def _venv_without_ovtraj(folder: Path) -> Path:
    """A venv whose path holds this venv's packages (distributed, Prefect...) but not the
    project: its editable install is a ``.pth`` hook that only this venv runs."""
    base = (
        Path(sys.base_prefix) / "bin" / f"python{sys.version_info.major}.{sys.version_info.minor}"
    )
    subprocess.run([str(base), "-m", "venv", "--without-pip", str(folder)], check=True)
    purelib = Path(
        sysconfig.get_path("purelib", vars={"base": str(folder), "platbase": str(folder)})
    )
    (purelib / "main-venv.pth").write_text(sysconfig.get_path("purelib") + "\n", encoding="utf-8")
    python = folder / "bin" / "python"
    check = subprocess.run(
        [str(python), "-c", "import distributed, prefect; import ovtraj"],
        cwd=folder,
        env=_environment(),
        capture_output=True,
        text=True,
    )
    assert "No module named 'ovtraj'" in check.stderr, check.stderr
    return python


@pytest.mark.parametrize("via", VIAS)
def test_a_worker_without_the_project_fails_the_flow_naming_it(
    prefect_server, cluster, tmp_path_factory, via
):
    from tasks.common import ORCHESTRATION

    if "worker-without-ovtraj" not in cluster.processes:
        python = _venv_without_ovtraj(tmp_path_factory.mktemp("venv"))
        cluster.worker("worker-without-ovtraj", python=python)
    cluster.wait_for_workers(2)  # the survivor of the previous test and this one
    project = tmp_path_factory.mktemp("project")
    config = _config(project, samples=2, batch_size=1)
    started = time.monotonic()
    done = _run(config, cluster.address, prefect_server, via)
    elapsed = time.monotonic() - started
    # the CLI: one line, exit 2; the flow's process fails with the flow's error
    assert done.returncode == (2 if via == "cli" else 1), done.stdout + done.stderr
    assert elapsed < ORCHESTRATION.dask.connect_timeout_s + 60.0
    # the CLI's one line; the flow's error among its logs
    line = done.stderr.strip().splitlines()[-1] if via == "cli" else done.stderr
    assert "cannot import the project" in line and "No module named 'ovtraj'" in line, line
    assert cluster.address in line and "install ovtraj" in line
    store = RunStore(project / "runs")
    (run,) = [store.run(row["run_id"]) for row in store.catalog()]
    assert run.manifest["status"] == "failed" and "ClusterError" in run.manifest["failure"]
    assert run.status() == "failed"
