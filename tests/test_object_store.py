"""The run store on object storage, against a real S3 API server.

``moto_server -H 127.0.0.1 -p PORT`` (moto's server mode) is started by the module and
stopped by its PID; the ``ovtraj`` command runs in subprocesses with the standard
``AWS_ENDPOINT_URL`` pointing at it. The same commands and the same guarantees as on
a local disk: data first, marker last, checksums; no rename and no hard link (an
object store has neither): create-only writes (``If-None-Match``), leases for locks.
"""

from __future__ import annotations

import copy
import importlib
import json
import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario, free_port

# Left out of the fast tier (-m "not slow"): it starts a moto S3 server and runs the command in
# subprocesses against it.
pytestmark = pytest.mark.slow

BIN = Path(sys.executable).parent
BUCKET = "ovtraj-test"


@pytest.fixture(scope="module")
def s3(tmp_path_factory):
    """A moto S3 server of our own; yields the environment that points clients at it."""
    port = free_port()
    log = tmp_path_factory.mktemp("moto") / "moto.log"
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [str(BIN / "moto_server"), "-H", "127.0.0.1", "-p", str(port)],
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    env = {
        "AWS_ENDPOINT_URL": f"http://127.0.0.1:{port}",
        "AWS_ACCESS_KEY_ID": "test",
        "AWS_SECRET_ACCESS_KEY": "test",
        "AWS_DEFAULT_REGION": "us-east-1",
    }
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=1):
                    break
            except OSError:
                assert server.poll() is None, log.read_text()
                assert time.monotonic() < deadline, "moto_server did not start"
                time.sleep(0.2)
        yield env
    finally:
        server.terminate()
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            server.kill()


@pytest.fixture
def client(s3, monkeypatch):
    """An in-process S3 client on the test server (a fresh bucket per test)."""
    from ovtraj.store import backends as storage

    for key, value in s3.items():
        monkeypatch.setenv(key, value)
    storage._client.cache_clear()
    s3_client = storage._client()
    bucket = f"{BUCKET}-{os.urandom(4).hex()}"
    s3_client.create_bucket(Bucket=bucket)
    yield s3_client, bucket
    storage._client.cache_clear()


def _cli(s3: dict, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AWS_", "OVTRAJ_"))}
    return subprocess.run(
        [str(BIN / "ovtraj"), *args],
        env=env | s3,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def _small_config(directory: Path, **doe) -> Path:
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(doe)
    data["mission"]["surrogate"].update(
        regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3
    )
    data["mission"]["optimize"].update(population=32, generations=40)
    build_scenario(copy.deepcopy(data))
    path = directory / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_run_show_replay_verify_and_refit_on_the_object_store(s3, client, tmp_path):
    s3_client, bucket = client
    store = f"s3://{bucket}/study"
    config = _small_config(tmp_path, batch_size=8)
    done = _cli(s3, "run", str(config), "--samples", "20", "--seed", "4", "--store", store)
    assert done.returncode == 0, done.stderr
    (line,) = [x for x in done.stdout.splitlines() if x.startswith("stored in ")]
    url = line.removeprefix("stored in ")
    assert url.startswith(f"{store}/")
    rid = url.rsplit("/", 1)[1]
    keys = [o["Key"] for o in s3_client.list_objects_v2(Bucket=bucket)["Contents"]]
    assert f"study/{rid}/batches/2.json" in keys and not [k for k in keys if "lock" in k]
    assert not list(tmp_path.glob("**/*.parquet"))  # nothing on the local disk
    shown = json.loads(_cli(s3, "show", rid, "--store", store).stdout)
    assert shown["summary"]["evaluated"] == 20 and shown["summary"]["status"] == "complete"
    replayed = _cli(s3, "replay", rid, "--store", store)
    assert "largest difference from the stored totals  0" in replayed.stdout, replayed.stderr
    fitted = _cli(s3, "optimize", rid, str(config), "--store", store)
    assert fitted.returncode == 0, fitted.stderr
    refit = _cli(s3, "optimize", rid, str(config), "--refit", "--store", store)
    assert re.search(r"identical to the stored front +True", refit.stdout), refit.stderr
    verified = _cli(s3, "verify", rid, "--store", store)
    assert verified.returncode == 0 and "clean" in verified.stdout, verified.stdout
    assert "not covered" not in verified.stdout
    # The same commands again write nothing: a complete run is never rewritten.
    before = {o["Key"]: o["ETag"] for o in s3_client.list_objects_v2(Bucket=bucket)["Contents"]}
    again = _cli(s3, "run", str(config), "--samples", "20", "--seed", "4", "--store", store)
    assert again.returncode == 0, again.stderr
    after = {o["Key"]: o["ETag"] for o in s3_client.list_objects_v2(Bucket=bucket)["Contents"]}
    assert after == before
    # The catalog lives beside the runs on the object store too, and is queried there.
    queried = _cli(
        s3, "runs", "--where", "kind = 'run' AND feasible > 0", "--json", "--store", store
    )
    assert queried.returncode == 0, queried.stderr
    assert [r["id"] for r in json.loads(queried.stdout)["rows"]] == [rid]
    catalogued = _cli(s3, "catalog", "--store", store)
    assert f"{store}/catalog/catalog.parquet" in catalogued.stdout, catalogued.stderr
    # A value rewritten in a stored object is refused, naming it; verify lists it.
    key = f"study/{rid}/totals/part-00001.parquet"
    body = bytearray(s3_client.get_object(Bucket=bucket, Key=key)["Body"].read())
    body[len(body) // 2] ^= 0xFF  # one byte changed (bit rot, a bad copy)
    s3_client.put_object(Bucket=bucket, Key=key, Body=bytes(body))
    refused = _cli(s3, "replay", rid, "--store", store)
    assert refused.returncode == 2 and f"s3://{bucket}/{key}" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    listed = _cli(s3, "verify", rid, "--store", store)
    assert listed.returncode == 1 and f"s3://{bucket}/{key}" in listed.stdout


def test_objects_are_created_once_and_checked_when_read(client):
    from ovtraj.store.backends import S3Path
    from ovtraj.store.files import Digest, StoreError, read_bytes, write_bytes

    _, bucket = client
    path = S3Path(bucket, "a/b.bin")
    digest = write_bytes(path, b"first")
    assert write_bytes(path, b"first") == digest  # the same content: nothing to do
    with pytest.raises(StoreError, match="already stored with other content"):
        write_bytes(path, b"second")
    assert read_bytes(path, digest) == b"first"
    with pytest.raises(StoreError, match="changed since it was stored"):
        read_bytes(path, Digest.of(b"other"))
    with pytest.raises(StoreError, match=r"s3://.*/a/missing\.bin: missing"):
        read_bytes(S3Path(bucket, "a/missing.bin"))
    assert write_bytes(path, b"index", replace=True) == Digest.of(b"index")


def test_a_lease_excludes_others_until_released_or_stale(client):
    from ovtraj.store import locks
    from ovtraj.store.backends import S3Path
    from ovtraj.store.files import StoreError

    _, bucket = client
    path = S3Path(bucket, "run/locks/batch-0.lock")
    with locks.hold(path) as mine:
        assert mine and locks.held(path)
        with locks.hold(path) as other:  # another holder (its own lease attempt)
            assert not other
        with pytest.raises(StoreError, match=r"still held by .* pid"):
            with locks.hold(path, wait_s=0.5):
                pass
    assert not locks.held(path)
    # A lease whose holder died (not renewed): stale after its expiry, then taken over.
    stale = {"owner": "lost-host pid 1", "expires_unix_s": time.time() - 1.0}
    path.put(json.dumps(stale).encode())
    assert not locks.held(path)
    with locks.hold(path) as taken:
        assert taken
    # Shared holders (the run lock) exclude an exclusive one, not each other.
    run_lock = S3Path(bucket, "run/locks/run.lock")
    with locks.hold(run_lock, shared=True), locks.hold(run_lock, shared=True) as second:
        assert second and locks.held(run_lock)
        with locks.hold(run_lock) as alone:
            assert not alone
    assert not locks.held(run_lock)


def test_two_processes_on_one_run_in_the_object_store_compute_each_batch_once(s3, client, tmp_path):
    _, bucket = client
    store = f"s3://{bucket}/shared"
    config = _small_config(tmp_path, batch_size=1)
    args = [str(BIN / "ovtraj"), "run", str(config), "--samples", "6", "--seed", "8"]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AWS_", "OVTRAJ_"))} | s3
    procs = [
        subprocess.Popen(
            [*args, "--store", store], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        for _ in range(2)
    ]
    outputs = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1] for o in outputs]
    stored = [
        int(line.split()[1].split("/")[0])
        for out, _ in outputs
        for line in out.decode().splitlines()
        if re.match(r"batch \d+/\d+: \d+ samples, ", line) and "already stored" not in line
    ]
    assert sorted(stored) == [1, 2, 3, 4, 5, 6], stored
    (url,) = {
        line.split()[-1]
        for out, _ in outputs
        for line in out.decode().splitlines()
        if line.startswith("stored in")
    }
    rid = url.rsplit("/", 1)[1]
    verified = _cli(s3, "verify", rid, "--store", store)
    assert verified.returncode == 0, verified.stdout


def test_task_results_on_the_object_store_serve_the_cache(prefect_server, client, monkeypatch):
    """configs/orchestration.yaml ``results.storage`` as an ``s3://`` URL (here through
    ``OVTRAJ_PREFECT_RESULTS``): the task's result is an object there, and a second flow run
    with the same inputs and code is served from it without solving again."""
    from collections import Counter

    import tasks.rendezvous
    from flows.rendezvous import rendezvous_flow
    from ovtraj.config.orchestration import RESULTS_ENV

    s3_client, bucket = client
    monkeypatch.setenv(RESULTS_ENV, f"s3://{bucket}/prefect-results")
    calls: Counter = Counter()
    real = tasks.rendezvous.solve_rendezvous

    def counted(*args, **kwargs):
        calls["solve"] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(tasks.rendezvous, "solve_rendezvous", counted)
    monkeypatch.setattr(importlib.import_module("ovtraj.version"), "code_version", lambda: BUCKET)
    first = rendezvous_flow(str(DEFAULT_SCENARIO))
    listed = s3_client.list_objects_v2(Bucket=bucket, Prefix="prefect-results/")
    keys = [item["Key"] for item in listed.get("Contents", [])]
    assert keys, "no task result in the object store"
    again = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert calls["solve"] == 1 and again == first  # the second run read the stored result
