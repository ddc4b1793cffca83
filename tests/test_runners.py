"""The one runner option of ``ovtraj run``: the library's pools, no Prefect.

1. ``serial``, ``threads``, ``processes`` and ``dask`` (a local cluster) store
   byte-identical files for the same config and seed: each batch is evaluated with one
   BLAS thread wherever it runs (``ovtraj.parallel.EVALUATION_BLAS_THREADS``);
2. a process of the ``processes`` pool killed (SIGKILL) mid-batch: the command fails with
   one line naming the batches, exit 2, the manifest says ``incomplete`` with their
   errors, nothing stored is lost, and the same command completes the run computing only
   the missing batches.
"""

from __future__ import annotations

import copy
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from ovtraj.runs import RunStore
from tests.cli_runner import run_cli
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario, digest, held_claim

# Left out of the fast tier (-m "not slow"): it runs DoEs on every runner: threads, processes and
# a Dask cluster.
pytestmark = pytest.mark.slow

OVTRAJ = Path(sys.executable).with_name("ovtraj")


def _config(folder: Path, **doe) -> Path:
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(store="runs", **doe)
    build_scenario(copy.deepcopy(data))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _ovtraj(*args: str, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    """``ovtraj ARGS`` as a process of its own, no ``PREFECT_``/``OVTRAJ_`` variable set."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PREFECT_", "OVTRAJ_"))}
    return subprocess.run(
        [str(OVTRAJ), *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
    )


def _ovtraj_here(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """:func:`_ovtraj` in this process (tests/cli_runner.py: the entry point's body)."""
    unset = {k: None for k in os.environ if k.startswith(("PREFECT_", "OVTRAJ_"))}
    return run_cli(*args, env=unset, cwd=cwd)


def _stored_in(output: str) -> Path:
    match = re.search(r"^stored in (.+)$", output, flags=re.MULTILINE)
    assert match, output
    return Path(match.group(1))


@pytest.mark.parametrize("runner", ["threads", "processes", "dask"])
def test_every_runner_stores_the_files_the_serial_one_does(tmp_path, runner):
    serial = _config(tmp_path / "serial", samples=4, batch_size=2, workers=2)
    other = _config(tmp_path / runner, samples=4, batch_size=2, workers=2)
    # The serial reference in this process, the other runner in a process of its own: the
    # same files from two processes.
    reference = _ovtraj_here("run", str(serial), "--runner", "serial", cwd=tmp_path)
    assert reference.returncode == 0, reference.stderr
    done = _ovtraj("run", str(other), "--runner", runner, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    first, second = _stored_in(reference.stdout), _stored_in(done.stdout)
    assert first.name == second.name  # the runner is not part of the run
    assert second.parent == tmp_path / runner / "runs"  # the config's relative store
    digests = digest(second)
    assert len(digests) >= 8 and digests == digest(first)
    run = RunStore(second.parent).run(second.name)
    assert run.manifest["status"] == "complete" and run.verify().clean


def test_runs_in_a_row_share_the_started_pool_they_are_given(tmp_path):
    """The pipeline's DoE and infill runs on one pool: a run leaves a pool it did not
    start running, and stores what the serial runner stores."""
    from ovtraj.config.orchestration import load_orchestration
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.runs import prepare_run, run_doe
    from ovtraj.runs.execute import EVALUATIONS
    from ovtraj.runs.runners import batch_pool
    from ovtraj.target_sources import load_scenario

    scenario = load_scenario(_config(tmp_path, samples=2, batch_size=1, workers=2))
    fit = find_launch_fit(scenario)
    stored = {}
    for runner in ("processes", "serial"):
        store = RunStore(tmp_path / runner)
        before = EVALUATIONS["count"]
        with batch_pool(runner, 2, None, load_orchestration().dask) as pool:
            doe = prepare_run(scenario, samples=2, seed=3, code="test", store=store)
            run_doe(scenario, doe, fit, batch_size=1, pool=pool)
            child = prepare_run(scenario, samples=2, seed=3, code="test", store=store, parent=doe)
            run_doe(scenario, child, fit, batch_size=1, pool=pool)
            if runner == "processes":  # still running after both runs
                assert pool.executor.submit(os.getpid).result(timeout=60) != os.getpid()
        assert child.manifest["status"] == "complete" and child.manifest["evaluated"] == 4
        # run_doe's own runner is serial (in this process): the pool given ran the samples
        in_process = EVALUATIONS["count"] - before
        assert in_process == (0 if runner == "processes" else 4)
        stored[runner] = (child.id, digest(child.directory))
    assert stored["processes"] == stored["serial"] and len(stored["serial"][1]) >= 8


def test_a_killed_pool_process_fails_the_command_and_the_run_resumes(tmp_path):
    config = _config(tmp_path / "project", samples=8, batch_size=2, workers=2)
    store = tmp_path / "project" / "runs"
    killed: dict[str, int] = {}
    finished = threading.Event()

    def kill_a_busy_process() -> None:
        while not finished.is_set():
            for run_dir in store.glob("*"):
                held = held_claim(run_dir) if (run_dir / "locks").is_dir() else None
                if held is not None and held[1] != os.getpid():
                    os.kill(held[1], signal.SIGKILL)
                    killed.update(batch=held[0], pid=held[1])
                    return
            time.sleep(0.005)

    killer = threading.Thread(target=kill_a_busy_process, daemon=True)
    killer.start()
    try:
        broken = _ovtraj("run", str(config), "--runner", "processes", cwd=tmp_path)
    finally:
        finished.set()
        killer.join(timeout=60)
    assert killed, broken.stdout + broken.stderr
    assert broken.returncode == 2, broken.stdout + broken.stderr
    (line,) = broken.stderr.strip().splitlines()
    assert "incomplete" in line and f"batch {killed['batch']}:" in line, line
    (run_dir,) = store.iterdir()
    run = RunStore(store).run(run_dir.name)
    assert run.manifest["status"] == "incomplete" and run.manifest["failures"]
    kept = run.markers()
    assert killed["batch"] not in kept and run.verify().clean
    digests = {k: m["files"] for k, m in kept.items()}

    resumed = _ovtraj("run", str(config), "--runner", "processes", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert _stored_in(resumed.stdout) == run_dir
    run = RunStore(store).run(run_dir.name)
    assert run.manifest["status"] == "complete" and run.manifest["evaluated"] == 8
    assert run.verify().clean and not run.verify().uncovered
    markers = run.markers()
    assert sorted(markers) == [0, 1, 2, 3]
    assert all(markers[k]["files"] == files for k, files in digests.items())  # kept as stored
    computed = len(re.findall(r"^batch \d+/4: ", resumed.stdout, flags=re.MULTILINE))
    assert computed == 4 - len(kept)  # only the missing batches
