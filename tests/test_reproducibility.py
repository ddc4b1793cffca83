"""The same run id stores the same bytes on every machine (ovtraj/environment.py).

OpenBLAS picks its kernel when it loads; ovtraj pins it (Haswell where the CPU has AVX2 and
FMA) before numpy is imported, refuses to compute stored content on another kernel, and
records the environment beside every result. Tested as a user runs it: ``ovtraj run`` in
processes of their own under other ``OPENBLAS_CORETYPE`` and thread counts, a process that
loaded numpy first, a ``dask worker`` started by hand on another kernel, the environment
blocks of the store, and ``ovtraj verify --recompute`` on a clean and on a changed run.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ovtraj.cli import run_command
from ovtraj.environment import (
    CORETYPE_ENV,
    KERNEL_ENV,
    PINNED_KERNEL,
    blas_libraries,
    environment,
    pin,
)
from ovtraj.runs import RunStore
from ovtraj.store.environment_block import EnvironmentBlock
from ovtraj.store.files import Digest, StoreError, parquet_bytes
from ovtraj.store.seals import STORE_KEY_ENV
from tests.conftest import DEFAULT_SCENARIO, REPO

OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))
OTHER_KERNEL = "Sandybridge"  # AVX without FMA: other last bits than Haswell's (measured)
SAMPLES = "2"  # one batch; every stage reached, and already other bytes on another kernel

pytestmark = pytest.mark.skipif(
    pin().kernel != PINNED_KERNEL, reason=f"this machine cannot run OpenBLAS's {PINNED_KERNEL}"
)


def _environment(**variables: str) -> dict[str, str]:
    """This environment without ovtraj's or OpenBLAS's settings (the pin set
    OPENBLAS_CORETYPE in this process), plus ``variables``."""
    drop = ("OVTRAJ_", "OPENBLAS_", "PREFECT_")
    return {k: v for k, v in os.environ.items() if not k.startswith(drop)} | variables


def _doe(home: Path, runner: str, **variables: str) -> dict:
    """``ovtraj run`` of the shipped scenario on ``runner``, a process of its own with a
    workspace of its own; its JSON summary."""
    args = ["run", str(DEFAULT_SCENARIO), "--samples", SAMPLES, "--runner", runner, "--json"]
    done = subprocess.run(
        [OVTRAJ, "-q", *args],
        env=_environment(OVTRAJ_HOME=str(home), **variables),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


@pytest.fixture(scope="module")
def kernels(tmp_path_factory):
    """The same DoE three times at once: under OPENBLAS_CORETYPE=Haswell with one BLAS
    thread, under OPENBLAS_CORETYPE=Sandybridge with two and its batches in a process pool
    (both pinned by ovtraj, the pool's processes by the environment they inherit), and with
    the pin overridden to Sandybridge."""
    tmp = tmp_path_factory.mktemp("kernels")
    variants = {
        "haswell": ("serial", {CORETYPE_ENV: PINNED_KERNEL, "OPENBLAS_NUM_THREADS": "1"}),
        "sandybridge": ("processes", {CORETYPE_ENV: OTHER_KERNEL, "OPENBLAS_NUM_THREADS": "2"}),
        "override": ("serial", {KERNEL_ENV: OTHER_KERNEL}),
    }
    with ThreadPoolExecutor(len(variants)) as pool:
        futures = {k: pool.submit(_doe, tmp / k, r, **v) for k, (r, v) in variants.items()}
        return {k: Path(future.result()["stored_in"]) for k, future in futures.items()}


def _parquet_files(run_dir: Path) -> dict[str, bytes]:
    return {str(p.relative_to(run_dir)): p.read_bytes() for p in run_dir.rglob("*.parquet")}


def _manifest(run_dir: Path) -> dict:
    return json.loads((run_dir / "manifest.json").read_text())


@pytest.mark.slow
def test_other_kernels_and_thread_counts_store_the_same_bytes_under_the_pin(kernels):
    haswell, sandybridge = kernels["haswell"], kernels["sandybridge"]
    assert haswell.name == sandybridge.name  # the same run id
    files = _parquet_files(haswell)
    assert any(name.startswith("trajectories/deorbit/") for name in files)
    assert {name.split("/")[1] for name in files if name.startswith("stages/")} == {
        "launch",
        "rendezvous",
        "transfer",
        "deorbit",
        "reentry",
    }
    assert files == _parquet_files(sandybridge)
    # what each process asked for, and what it ran: the pin, over the requested kernel
    pinned = _manifest(sandybridge)["environment"]["blas_pin"]
    assert pinned["requested"] == OTHER_KERNEL and pinned["kernel"] == PINNED_KERNEL
    assert pinned["held"] is True and pinned["blas_loaded_before"] is False
    # the batch computed in a pool process: pinned through the environment it inherited
    marker = json.loads((sandybridge / "batches" / "0.json").read_text())["environment"]
    assert {lib["architecture"] for lib in marker["blas"]} == {PINNED_KERNEL}
    assert marker["blas_pin"]["requested"] == PINNED_KERNEL


@pytest.mark.slow
def test_the_pin_overridden_to_another_kernel_stores_other_bytes(kernels):
    haswell, other = kernels["haswell"], kernels["override"]
    assert haswell.name == other.name  # an override does not change what the id names
    pinned, overridden = _parquet_files(haswell), _parquet_files(other)
    assert sorted(pinned) == sorted(overridden)
    differing = [name for name in pinned if pinned[name] != overridden[name]]
    assert any(name.startswith("totals/") for name in differing), differing
    block = _manifest(other)["environment"]["blas_pin"]
    assert block["override"] == OTHER_KERNEL and block["kernel"] == OTHER_KERNEL
    assert block["held"] is True


@pytest.mark.slow
def test_recompute_bounds_what_another_kernel_changes(kernels, tmp_path, capsys):
    """The run stored under the overridden kernel, recomputed in this (pinned) process:
    other last bits, every column within its declared tolerance."""
    store = tmp_path / "runs"
    shutil.copytree(kernels["override"], store / kernels["override"].name)
    code = run_command(
        ["verify", kernels["override"].name, "--store", str(store), "--recompute", SAMPLES]
    )
    assert code == 0, capsys.readouterr()
    out = capsys.readouterr().out
    assert "all within their tolerances" in out
    assert "stages/deorbit.dv_mps" in out


def test_a_process_that_loaded_numpy_on_another_kernel_is_refused(tmp_path):
    """numpy imported before ovtraj, on another kernel: the pin comes too late, and
    ``ovtraj run`` (and any batch evaluation) refuses in one line naming the fix."""
    script = (
        "import numpy, sys\n"  # OpenBLAS loads here, on OPENBLAS_CORETYPE's kernel
        "from ovtraj.cli import run_command\n"
        "code = run_command(sys.argv[1:])\n"
        "from ovtraj.environment import BlasKernelError, pin\n"
        "from ovtraj.runs import evaluate_batch\n"
        "try:\n"  # refused before it reads its arguments
        "    evaluate_batch(None, None)\n"
        "except BlasKernelError as err:\n"
        "    print(err)\n"
        "print(pin().blas_loaded_before)\n"
        "sys.exit(code)\n"
    )
    store = tmp_path / "runs"
    args = ["run", str(DEFAULT_SCENARIO), "--samples", "1", "--store", str(store)]
    done = subprocess.run(
        [sys.executable, "-c", script, *args],
        env=_environment(**{CORETYPE_ENV: OTHER_KERNEL}),
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=REPO,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    (line,) = done.stderr.strip().splitlines()
    expected = f"OpenBLAS runs the {OTHER_KERNEL} kernel in this process (libscipy_openblas"
    assert line.startswith(expected), line
    assert line.endswith(
        f"not {PINNED_KERNEL}: start it with {CORETYPE_ENV}={PINNED_KERNEL} or import ovtraj "
        "before numpy"
    ), line
    refused, loaded_before = done.stdout.strip().splitlines()
    assert refused == line and loaded_before == "True"
    (run,) = [RunStore(store).run(p.name) for p in store.iterdir()]
    assert run.done_batches() == set() and run.manifest["status"] == "created"


def test_an_override_this_cpu_cannot_run_is_refused_not_forced(tmp_path):
    """OpenBLAS forced onto SkylakeX dies of SIGILL on a CPU without AVX-512: ovtraj does not
    set it, and refuses to compute, naming the missing flags."""
    from ovtraj.environment import cpu_flags

    if "avx512f" in cpu_flags():
        pytest.skip("this CPU runs SkylakeX")
    script = (
        "import os, ovtraj\n"
        "from ovtraj.environment import check\n"
        "print(os.environ.get('OPENBLAS_CORETYPE'))\n"
        "import numpy\n"
        "print(check())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script],
        env=_environment(**{KERNEL_ENV: "skylakex"}),
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    unset, problem = done.stdout.strip().splitlines()
    assert unset == "None"
    assert problem.startswith("this CPU lacks avx512f") and "SkylakeX" in problem
    assert problem.endswith(f"unset {KERNEL_ENV} to use ovtraj's pin ({PINNED_KERNEL})")


# --- the environment blocks of a run ----------------------------------------------------------


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A 2-sample DoE of the shipped scenario, stored by this process (pinned)."""
    store = tmp_path_factory.mktemp("stored") / "runs"
    args = ["-q", "run", str(DEFAULT_SCENARIO), "--samples", SAMPLES, "--store", str(store)]
    assert run_command(args) == 0
    (run_dir,) = store.iterdir()
    return run_dir


def _copy(run_dir: Path, tmp_path: Path) -> tuple[Path, Path]:
    store = tmp_path / "runs"
    shutil.copytree(run_dir, store / run_dir.name)
    return store, store / run_dir.name


def test_the_manifest_and_every_batch_marker_record_the_declared_environment(stored):
    here = environment()
    documents = [stored / "manifest.json", *sorted((stored / "batches").glob("*.json"))]
    assert len(documents) >= 2
    for path in documents:
        block = json.loads(path.read_text())["environment"]
        EnvironmentBlock.model_validate(block)
        assert block["blas_pin"]["kernel"] == PINNED_KERNEL and block["blas_pin"]["held"]
        assert block["cpu"] == here["cpu"] and block["packages"] == here["packages"]
        assert {lib["package"] for lib in block["blas"]} >= {"numpy"}
        assert "created" not in json.dumps(block) and "utc" not in json.dumps(block)
    # never in what the run id hashes nor in a data file
    for path in stored.rglob("*.parquet"):
        assert b"blas_pin" not in path.read_bytes() and b"Haswell" not in path.read_bytes()


@pytest.mark.parametrize(
    ("where", "block", "named"),
    [
        ("manifest.json", {"python": {"version": "3", "implementation": "x" * 20_000}}, "bytes"),
        ("manifest.json", "nested", "cpu.model"),
        ("batches/0.json", "extra", "<a key>"),
        ("batches/0.json", [1, 2], "the block"),
    ],
)
def test_a_hostile_environment_block_is_refused_naming_the_file(
    stored, tmp_path, where, block, named
):
    store, run_dir = _copy(stored, tmp_path)
    path = run_dir / where
    document = json.loads(path.read_text())
    if block == "nested":
        deep = "x"
        for _ in range(40):  # within the JSON reader's depth: the block's own check refuses it
            deep = [deep]
        block = document["environment"] | {"cpu": {"model": deep, "flags": []}}
    elif block == "extra":
        block = document["environment"] | {"a\nforged line": 1}
    document["environment"] = block
    path.write_text(json.dumps(document))
    run = RunStore(store).run(run_dir.name)
    with pytest.raises(StoreError) as caught:
        run.manifest if where == "manifest.json" else run.markers()
    message = str(caught.value)
    assert message.startswith(f"{path}: environment block refused (") and named in message
    assert "\n" not in message and len(message) < 400
    report = run.verify()
    assert any(p.startswith(f"{path}: environment block refused") for p in report.problems)


def test_a_run_stored_before_the_environment_block_still_reads(stored, tmp_path):
    store, run_dir = _copy(stored, tmp_path)
    for path in [run_dir / "manifest.json", *(run_dir / "batches").glob("*.json")]:
        document = json.loads(path.read_text())
        del document["environment"]
        path.write_text(json.dumps(document))
    run = RunStore(store).run(run_dir.name)
    assert len(run.totals()) == int(SAMPLES) and run.verify().clean


def test_a_marker_written_again_keeps_the_environment_that_stored_it(tmp_path):
    """A product stored once; the same product finished again by a process whose
    environment differs (here its BLAS threads): the marker is not rewritten."""
    from threadpoolctl import threadpool_limits

    from ovtraj.store.products import Product

    product = Product(tmp_path / "product", "meta.json")
    with product.writing() as out:
        out.write_json("values.json", {"a": 1})
        out.finish({"kind": "test"})
    before = product.marker_path.read_bytes()
    threads = {lib["threads"] for lib in blas_libraries()}
    with threadpool_limits(limits=1 if max(threads) > 1 else 2, user_api="blas"):
        assert environment()["blas"] != json.loads(before)["environment"]["blas"]
        with product.writing() as out:
            out.write_json("values.json", {"a": 1})
            out.finish({"kind": "test"})
    assert product.marker_path.read_bytes() == before
    with product.writing() as out, pytest.raises(StoreError, match="other content"):
        out.finish({"kind": "another"})


# --- ovtraj verify --recompute ----------------------------------------------------------------


def test_recompute_of_a_clean_run_is_exact_here(stored, tmp_path, monkeypatch, capsys):
    monkeypatch.delenv(STORE_KEY_ENV, raising=False)
    store, run_dir = _copy(stored, tmp_path)
    args = ["verify", run_dir.name, "--store", str(store), "--recompute", SAMPLES, "--json"]
    assert run_command(args) == 0
    found = json.loads(capsys.readouterr().out)
    again = found["recompute"]
    assert found["clean"] and again["ok"] and again["samples"] == [0, 1]
    bounded = [c for c in again["columns"] if c["tolerance"] is not None]
    assert {c["largest_difference"] for c in bounded} == {0.0}  # the same kernel: the same bits
    compared = {f"{c['dataset']}.{c['column']}" for c in again["columns"]}
    assert {"totals.dv_total_mps", "totals.feasible", "totals.failed_stage"} <= compared
    assert "stages/reentry.miss_distance_km" in compared


def test_recompute_flags_a_stored_value_changed_past_its_tolerance(
    stored, tmp_path, monkeypatch, capsys
):
    """One dV of a totals file changed by 1 m/s and its digest updated in the batch
    marker: the checksums pass (no store key), the recompute names the column, exit 1."""
    monkeypatch.delenv(STORE_KEY_ENV, raising=False)
    store, run_dir = _copy(stored, tmp_path)
    part = run_dir / "totals" / "part-00000.parquet"
    table = pq.read_table(part)
    frame = table.to_pandas()
    assert frame["feasible"].any()
    feasible = frame.index[frame["feasible"]][0]
    frame.loc[feasible, "dv_total_mps"] += 1.0
    payload = parquet_bytes(pa.Table.from_pandas(frame, schema=table.schema, preserve_index=False))
    part.chmod(0o644)
    part.unlink()
    part.write_bytes(payload)
    marker_path = run_dir / "batches" / "0.json"
    marker = json.loads(marker_path.read_text())
    marker["files"]["totals/part-00000.parquet"] = Digest.of(payload).to_json()
    marker_path.write_text(json.dumps(marker))
    assert run_command(["verify", run_dir.name, "--store", str(store)]) == 0
    capsys.readouterr()
    code = run_command(["verify", run_dir.name, "--store", str(store), "--recompute", SAMPLES])
    out = capsys.readouterr().out
    assert code == 1, out
    (line,) = [row for row in out.splitlines() if row.strip().startswith("totals.dv_total_mps")]
    assert line.split()[1:] == ["1", "m/s", "0.001", "m/s", "beyond"]
    assert out.splitlines()[-1].endswith("1 beyond their tolerance (totals.dv_total_mps)")


@pytest.mark.parametrize("past", [False, True])
def test_a_recompute_count_out_of_bounds_is_one_line(stored, past, capsys):
    from ovtraj.config.reproducibility import load_reproducibility

    count = str(load_reproducibility().recompute.max_samples + 1) if past else "-1"
    code = run_command(["verify", stored.name, "--store", str(stored.parent), "--recompute", count])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--recompute" in err, err


def test_a_dask_worker_started_on_another_kernel_is_refused_naming_it(tmp_path):
    """``dask worker`` imports numpy before it can import ovtraj: started with another
    OPENBLAS_CORETYPE it runs that kernel, and the cluster check refuses it by name."""
    from ovtraj.config.orchestration import load_orchestration
    from ovtraj.runs.runners import ClusterError, connect
    from tests.test_dask_cluster import DASK, Cluster

    cluster = Cluster(tmp_path)
    try:
        scheduler = [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(cluster.port)]
        cluster.start("scheduler", [*scheduler, "--no-dashboard"])
        cluster.worker("worker-sandybridge", env={CORETYPE_ENV: OTHER_KERNEL})
        cluster.wait_for_workers(1)
        with pytest.raises(ClusterError) as caught:
            connect(cluster.address, 1, load_orchestration().dask)
    finally:
        cluster.stop()
    message = str(caught.value)
    assert message.startswith(f"Dask cluster at {cluster.address}: 1 of 1 worker(s) would store")
    assert f"OpenBLAS runs the {OTHER_KERNEL} kernel, not {PINNED_KERNEL}" in message
    assert "tcp://127.0.0.1:" in message and "(worker-sandybridge): OpenBLAS runs" in message
    assert f"start each `dask worker` with {CORETYPE_ENV}={PINNED_KERNEL}" in message
