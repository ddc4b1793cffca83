"""Run store integrity: declared schemas, checksums, determinism, faults, claims.

The store is used as a user uses it: the ``ovtraj`` command, real file systems (a tmpfs
made full or read-only when this machine allows mounting), real concurrent processes and
a real ``kill -9``. A command whose answer and files are all a test checks runs in this
process (tests/cli_runner.py: the entry point's body, its exit code, stdout and stderr);
the command runs in a subprocess where a process is the point: killed, sent SIGTERM, two
racing on one run, and the tmpfs cases (a full and a read-only disk, and a configuration
folder of their own, which a process reads once).
"""

from __future__ import annotations

import copy
import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import duckdb
import numpy as np
import pandas as pd
import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest
import yaml

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import MissionContext
from ovtraj.runs import RunStore, execute, latin_hypercube
from ovtraj.runs.schemas import DATASETS
from ovtraj.store.files import Digest, StoreError, read_bytes, write_bytes
from ovtraj.store.records import SchemaError, plain, record_schema, table_from_rows
from tests.cli_runner import run_cli as _cli
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario

OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))


def _short_data() -> dict:
    """The default scenario with a 12 h deorbit horizon: some samples find no pass."""
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["deorbit"]["horizon_h"] = 12.0
    return data


def _write_config(directory: Path, data: dict) -> Path:
    build_scenario(copy.deepcopy(data))
    path = directory / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _process(
    *args: str, timeout: float = 600, cwd: Path | None = None, env: dict | None = None
) -> subprocess.CompletedProcess:
    """``ovtraj ARGS`` as a process of its own."""
    return subprocess.run(
        [OVTRAJ, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=cwd,
        check=False,
        env=None if env is None else os.environ | env,
    )


def _one_line_error(done: subprocess.CompletedProcess, code: int = 2) -> str:
    assert done.returncode == code, (done.stdout, done.stderr)
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    return lines[0]


def _parquet_bytes(directory: Path) -> dict[str, bytes]:
    return {str(p.relative_to(directory)): p.read_bytes() for p in directory.rglob("*.parquet")}


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """A run whose first batch starts with a sample that fails at the deorbit.

    The samples are evaluated once; the run stores them in batches of 3 with a
    failing sample first, so the first deorbit row of batch 0 is infeasible.
    """
    scenario = build_scenario(_short_data())
    fit = find_launch_fit(scenario)
    probe = latin_hypercube(scenario.mission.design_bounds, 8, seed=3)
    records = execute.evaluate_batch(MissionContext(scenario, fit), probe)
    failing = [k for k, r in enumerate(records) if r.failed_stage == "deorbit"]
    feasible = [k for k, r in enumerate(records) if r.feasible]
    assert failing and feasible, "the short horizon must give both kinds of sample"
    order = [failing[0], *feasible]
    order += [k for k in range(len(records)) if k not in order]
    samples = probe.iloc[order].reset_index(drop=True)
    store = RunStore(tmp_path_factory.mktemp("mixed") / "runs")
    run = store.create(resolved=scenario.resolved(), samples=samples, seed=3, code="test")
    steps = execute.trajectory_steps(scenario)
    for k, batch in run.batches(3):
        ids = [int(i) for i in batch["sample_id"]]
        with run.claim(k) as claimed:
            assert claimed
            run.write_batch(k, [records[i] for i in ids], ids, trajectory_steps=steps)
    execute.finish(run)
    return {"run": run, "records": records, "failing": failing, "scenario": scenario}


def test_every_part_of_every_dataset_has_the_declared_schema(mixed):
    run = mixed["run"]
    assert pq.read_schema(run.directory / "samples.parquet").equals(
        DATASETS["samples"], check_metadata=False
    )
    parts = 0
    for name, schema in DATASETS.items():
        for path in sorted((run.directory / name).glob("part-*.parquet")):
            assert pq.read_schema(path).equals(schema, check_metadata=False), path
            parts += 1
    assert parts == sum(len(m["files"]) for m in run.markers().values())
    columns = set().union(*(schema.names for schema in DATASETS.values()))
    assert "wall_time_s" not in columns  # timing is in the markers, not in the results


def test_a_batch_whose_first_row_is_infeasible_keeps_every_column(mixed):
    run = mixed["run"]
    first = pq.read_table(run.directory / "stages" / "deorbit" / "part-00000.parquet").to_pandas()
    assert not first["feasible"].iloc[0] and first["feasible"].iloc[1:].any()
    constraints = [c for c in DATASETS["stages/deorbit"].names if c.startswith("constraint_")]
    assert len(constraints) == 8 and set(constraints) <= set(first.columns)
    stored = first[first["feasible"]]
    assert np.isfinite(stored[constraints].to_numpy(dtype=float)).all()
    # The same values as the evaluated records, read back through the checked reader.
    deorbit = run.stage("deorbit").set_index("sample_id")
    for sid in stored["sample_id"]:
        expected = mixed["records"][int(sid)].stages["deorbit"]
        for column in constraints:
            assert deorbit.loc[sid, column] == pytest.approx(expected[column], abs=0)


def test_every_dataset_reads_in_one_line_with_pandas_pyarrow_and_duckdb(mixed):
    run = mixed["run"]
    for name in DATASETS:
        if name == "samples":
            continue
        folder = run.directory / name
        expected = len(run._dataset(name))
        assert len(pd.read_parquet(folder)) == expected, name
        assert ds.dataset(folder).to_table().num_rows == expected, name
        query = f"select count(*) from read_parquet('{folder}/*.parquet')"
        assert duckdb.sql(query).fetchall()[0][0] == expected, name
    totals = pd.read_parquet(run.directory / "totals")
    assert totals["reason"].notna().sum() == (~totals["feasible"]).sum() >= len(mixed["failing"])


def test_stage_rows_have_exactly_the_declared_columns_feasible_or_not(mixed):
    from ovtraj.astro.epoch import Epoch
    from ovtraj.deorbit.result import DeorbitResult
    from ovtraj.mission.chain import LAUNCH_ROW_SCHEMA
    from ovtraj.reentry.result import ReentryResult
    from ovtraj.rendezvous.result import RendezvousResult

    epoch = Epoch.from_iso("2026-12-01T00:00:00Z")
    declared = {
        "launch": LAUNCH_ROW_SCHEMA,
        "rendezvous": DATASETS["stages/rendezvous"],
        "transfer": DATASETS["stages/transfer"],
        "deorbit": DATASETS["stages/deorbit"],
        "reentry": DATASETS["stages/reentry"],
    }
    feasible = next(r for r in mixed["records"] if r.feasible)
    for stage, schema in declared.items():
        names = set(schema.names) - {"sample_id"}
        assert set(feasible.stages[stage]) - {"wall_time_s"} == names, stage
    infeasible = {
        "rendezvous": RendezvousResult("rendezvous", False, "x", epoch, 0.0),
        "deorbit": DeorbitResult(False, "x", epoch),
        "reentry": ReentryResult(False, "x", epoch),
    }
    for stage, result in infeasible.items():
        row = result.to_row()
        assert set(row) - {"wall_time_s"} == set(declared[stage].names) - {"sample_id"}, stage
        assert all(v is None or isinstance(v, (str, bool, int, float)) for v in row.values())


def test_records_refuse_an_undeclared_column_and_store_nan_as_null():
    schema = record_schema([("a", DATASETS["samples"].field("sample_id").type)])
    with pytest.raises(SchemaError, match="b"):
        table_from_rows([{"a": 1, "b": 2}], schema, "demo")
    assert plain({"x": np.float64("nan"), "y": [np.int64(2), float("inf")]}) == {
        "x": None,
        "y": [2, None],
    }


def test_two_stores_of_one_config_and_seed_are_byte_identical(tmp_path):
    config = _write_config(tmp_path, _short_data())
    # Seed 5: samples failing at the rendezvous and the deorbit, and two that land. One
    # store is written in this process, the other by a process of its own (nothing the
    # first computed is reused by the second).
    args = ("run", str(config), "--samples", "4", "--seed", "5", "--store")
    done = [_cli(*args, str(tmp_path / "a")), _process(*args, str(tmp_path / "b"))]
    assert all(d.returncode == 0 for d in done), [d.stderr for d in done]
    (a,) = (tmp_path / "a").iterdir()
    (b,) = (tmp_path / "b").iterdir()
    assert a.name == b.name
    first, second = _parquet_bytes(a), _parquet_bytes(b)
    assert len(first) >= 11 and first.keys() == second.keys()
    assert all(first[k] == second[k] for k in first)
    markers = [json.loads((d / "batches" / "0.json").read_text()) for d in (a, b)]
    assert markers[0]["files"] == markers[1]["files"]  # the digests too
    assert "sample_wall_time_s" in markers[0]["timing"]  # timing kept, outside the tables
    assert f"stored in {a.resolve()}" in done[0].stdout


def test_a_rewritten_value_is_refused_by_every_reader_and_by_verify(mixed, tmp_path):
    from ovtraj.pipeline import training_data

    source = mixed["run"].directory
    shutil.copytree(source, tmp_path / "runs" / source.name)
    store = tmp_path / "runs"
    run = RunStore(store).run(source.name)
    victim = run.directory / "totals" / "part-00001.parquet"
    table = pq.read_table(victim)
    frame = table.to_pandas()
    frame.loc[0, "parking_altitude_km"] += 1e-6
    pq.write_table(table.from_pandas(frame, schema=table.schema), victim)  # a valid file
    assert pq.read_table(victim).num_rows == table.num_rows
    for read in (run.totals, lambda: training_data(run), run.summary):
        with pytest.raises(StoreError, match=r"totals/part-00001\.parquet: changed"):
            read()
    line = _one_line_error(_cli("replay", run.id, "--store", str(store)))
    assert "totals/part-00001.parquet" in line
    _one_line_error(_cli("show", run.id, "--store", str(store)))
    verified = _cli("verify", run.id, "--store", str(store))
    assert verified.returncode == 1
    bad = [line for line in verified.stdout.splitlines() if line.startswith("bad:")]
    assert len(bad) == 1 and "totals/part-00001.parquet" in bad[0]
    # Every other file is intact and still read; the library's replay reads the stage rows.
    assert len(execute.replay(run)) == 8
    stage = run.directory / "stages" / "launch" / "part-00002.parquet"
    rows = pq.read_table(stage)
    pq.write_table(rows, stage, compression="gzip")  # the same values, other bytes
    with pytest.raises(StoreError, match=r"stages/launch/part-00002\.parquet: changed"):
        execute.replay(run)


def test_verify_a_clean_run_and_list_files_no_marker_covers(mixed, tmp_path):
    source = mixed["run"].directory
    shutil.copytree(source, tmp_path / "runs" / source.name)
    store = str(tmp_path / "runs")
    clean = _cli("verify", source.name, "--store", store)
    assert clean.returncode == 0 and "clean" in clean.stdout, clean.stdout
    run = RunStore(store).run(source.name)
    before = run.summary()
    stray = run.directory / "totals" / "part-00009.parquet"  # e.g. a batch cut short
    shutil.copy(run.directory / "totals" / "part-00000.parquet", stray)
    assert run.summary()["evaluated"] == before["evaluated"] == 8  # only marked batches count
    listed = _cli("verify", source.name, "--store", store)
    assert listed.returncode == 0 and str(stray) in listed.stdout


def test_a_stored_file_is_never_overwritten(tmp_path):
    path = tmp_path / "a.bin"
    digest = write_bytes(path, b"first")
    assert write_bytes(path, b"first") == digest  # the same content: nothing to do
    with pytest.raises(StoreError, match="already stored with other content"):
        write_bytes(path, b"second")
    assert read_bytes(path, digest) == b"first"
    with pytest.raises(StoreError, match="changed since it was stored"):
        read_bytes(path, Digest.of(b"other"))
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_a_file_decoded_before_is_still_verified_on_every_read(tmp_path):
    """The decoded-table reuse skips only the decoding: the file is read and hashed each
    time, so a file changed after its first read is refused, not served from memory."""
    import pyarrow as pa

    from ovtraj.store.files import decoded_tables, parquet_bytes, read_table

    table = pa.table({"sample_id": pa.array([0, 1, 2], pa.int64()), "x": [1.0, 2.0, 3.0]})
    path = tmp_path / "part.parquet"
    digest = write_bytes(path, parquet_bytes(table))
    first = read_table(path, digest, table.schema)
    assert first.equals(table)
    assert read_table(path, digest, table.schema) is first  # decoded once
    changed = table.set_column(1, "x", pa.array([1.0, 2.0, 4.0]))
    os.chmod(path, 0o644)
    path.write_bytes(parquet_bytes(changed))  # a valid file, other values
    with pytest.raises(StoreError, match=r"part\.parquet: changed since it was stored"):
        read_table(path, digest, table.schema)
    with pytest.raises(StoreError, match=r"part\.parquet: columns or types differ"):
        read_table(path, Digest.of(path.read_bytes()), pa.schema([("sample_id", pa.int32())]))
    from ovtraj.config.orchestration import load_orchestration

    assert decoded_tables().limit_bytes == load_orchestration().reads.decoded_tables_mib * 2**20
    decoded_tables().clear()
    assert read_table(path, expected=None, schema=None).equals(changed)


def test_decoded_tables_keep_the_most_recent_within_their_bound():
    import pyarrow as pa

    from ovtraj.store.files import DecodedTables, parquet_bytes

    payloads = [parquet_bytes(pa.table({"x": np.arange(1000.0) + k})) for k in range(4)]
    size = DecodedTables(limit_bytes=0).get("any", payloads[0]).nbytes  # each table's
    tables = DecodedTables(limit_bytes=2 * size)
    decoded = [tables.get(Digest.of(p).sha256, p) for p in payloads[:3]]
    assert tables.get(Digest.of(payloads[2]).sha256, payloads[2]) is decoded[2]
    again = tables.get(Digest.of(payloads[0]).sha256, payloads[0])  # evicted: decoded anew
    assert again is not decoded[0] and again.equals(decoded[0])
    assert tables.nbytes == 2 * size and len(tables) == 2
    huge = DecodedTables(limit_bytes=size // 2)
    assert huge.get(Digest.of(payloads[3]).sha256, payloads[3]).num_rows == 1000
    assert len(huge) == 0 and huge.nbytes == 0  # larger than the whole bound: not kept


def test_a_full_disk_is_one_error_naming_the_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    import ovtraj.store.files

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(ovtraj.store.files.os, "fsync", full)
    with pytest.raises(StoreError) as caught:
        write_bytes(tmp_path / "x" / "part.parquet", b"payload")
    assert str(caught.value) == f"cannot write {tmp_path / 'x' / 'part.parquet'}: no space " + (
        "left on the device"
    )
    assert list((tmp_path / "x").iterdir()) == []


def test_replay_of_a_run_with_no_stored_batch_is_one_line(tmp_path, scenario):
    from ovtraj.runs import prepare_run

    run = prepare_run(scenario, samples=2, seed=1, code="test", store=RunStore(tmp_path))
    line = _one_line_error(_cli("replay", run.id, "--store", str(tmp_path)))
    assert line == f"run {run.id} has no stored batch: nothing to replay"


@pytest.fixture
def tmpfs(tmp_path):
    """A small tmpfs of its own (root and mount permission needed, else the test skips)."""
    mount = tmp_path / "mnt"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=160k", "tmpfs", str(mount)],
        capture_output=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def _remount(mount: Path, options: str) -> None:
    subprocess.run(["mount", "-o", f"remount,{options}", str(mount)], check=True)


def test_full_then_read_only_file_system(tmpfs, tmp_path):
    config = _write_config(tmp_path, yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8")))
    store = tmpfs / "runs"
    args = ("run", str(config), "--samples", "6", "--seed", "5", "--store", str(store))
    # 160 kB: less than the DoE's estimate (configs/io_limits.yaml): refused, nothing written.
    line = _one_line_error(_process(*args))
    assert line.startswith(f"{store}: a DoE of 6 samples takes ~") and "free on its disk" in line
    assert not store.exists() or not any(store.iterdir())
    # An estimate that lets it start: the run's first files and a batch or two fit, then
    # the disk is full.
    configs = tmp_path / "configs"
    shutil.copytree(REPO / "configs", configs)
    limits = configs / "io_limits.yaml"
    limits.write_text(
        re.sub(r"doe_bytes_per_sample: \d+", "doe_bytes_per_sample: 1", limits.read_text())
    )
    line = _one_line_error(_process(*args, env={"OVTRAJ_CONFIG_DIR": str(configs)}))
    assert line.startswith(f"cannot write {store}") and line.endswith("no space left on the device")
    (run_dir,) = store.iterdir()
    run = RunStore(store).run(run_dir.name)
    assert run.manifest["status"] == "interrupted" and "no space" in run.manifest["interrupted"]
    kept = run.done_batches()
    assert not list(run_dir.rglob("*.tmp"))
    report = run.verify()
    assert report.clean and not report.uncovered, report
    # More space: the run resumes where it stopped and nothing stored is lost.
    before = {p: p.read_bytes() for p in run_dir.rglob("*.parquet")}
    _remount(tmpfs, "size=20m")
    done = _process(*args)
    assert done.returncode == 0, done.stderr
    assert f"batch {min(kept) + 1}/" not in done.stdout if kept else True
    assert run.status() == "complete" and run.verify().clean
    assert all(p.read_bytes() == content for p, content in before.items())
    # Read-only: the complete run is listed again without a write; anything new is refused.
    manifest = (run_dir / "manifest.json").read_bytes()
    _remount(tmpfs, "ro")
    again = _process(*args)
    assert again.returncode == 0 and run_dir.name in again.stdout, again.stderr
    assert (run_dir / "manifest.json").read_bytes() == manifest
    assert _process("verify", run_dir.name, "--store", str(store)).returncode == 0
    line = _one_line_error(_process("run", str(config), "--samples", "2", "--store", str(store)))
    assert line.startswith(f"cannot write {store}") and line.endswith("read-only file system")


def _batches_stored(stdout: str) -> list[int]:
    """The batches this process computed and stored (``batch k/n: m samples, ...``)."""
    return [
        int(line.split()[1].split("/")[0])
        for line in stdout.splitlines()
        if re.match(r"batch \d+/\d+: \d+ samples, ", line) and "already stored" not in line
    ]


def _batches_of_one(directory: Path) -> Path:
    """The default scenario, one sample per batch (many batch boundaries to stop at)."""
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"]["batch_size"] = 1
    return _write_config(directory, data)


def _wait_for_the_first_batch(proc: subprocess.Popen, store: Path) -> None:
    deadline = time.monotonic() + 300
    while not list(store.glob("*/batches/0.json")):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)


def test_two_processes_on_one_run_compute_each_batch_once(tmp_path):
    config = _batches_of_one(tmp_path)
    args = [OVTRAJ, "run", str(config), "--samples", "6", "--seed", "8", "--store", str(tmp_path)]
    procs = [subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)]
    procs.append(subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    outputs = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1] for o in outputs]
    stored = [_batches_stored(out) for out, _ in outputs]
    assert sorted(stored[0] + stored[1]) == [1, 2, 3, 4, 5, 6], stored
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    run = RunStore(tmp_path).run(run_dir.name)
    assert run.status() == "complete" and run.verify().clean
    assert len(run.totals()) == 6 and run.totals()["sample_id"].is_unique


def test_a_killed_run_is_reported_interrupted_and_resumes_cleanly(tmp_path):
    config = _batches_of_one(tmp_path)
    store = tmp_path / "runs"
    args = ["run", str(config), "--samples", "5", "--seed", "9", "--store", str(store)]
    proc = subprocess.Popen([OVTRAJ, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _wait_for_the_first_batch(proc, store)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    (run_dir,) = store.iterdir()
    run = RunStore(store).run(run_dir.name)
    assert run.manifest["status"] == "running" and run.status() == "interrupted"
    shown = json.loads(_process("show", run.id, "--store", str(store)).stdout)
    assert shown["summary"]["status"] == "interrupted"
    done_before = run.done_batches()
    orphan = run_dir / "totals" / f".part-00004.parquet.host-1-{uuid.uuid4().hex[:8]}.tmp"
    orphan.write_bytes(b"half a file")
    resumed = _process(*args)
    assert resumed.returncode == 0, resumed.stderr
    assert re.search(
        r"removed [1-9]\d* temporary file\(s\) of an interrupted write", resumed.stdout
    )
    assert not orphan.exists()
    assert not set(_batches_stored(resumed.stdout)) & {k + 1 for k in done_before}
    assert run.status() == "complete" and run.manifest["resumed_after_interruption"] == 1
    report = run.verify()
    assert report.clean and not report.uncovered


def test_an_interrupt_wrapped_by_compiled_code_marks_the_run_interrupted(tmp_path, scenario):
    """A SIGTERM's KeyboardInterrupt raised while numba's dispatcher types a call comes
    back as CPython's ``SystemError: ... returned a result with an exception set`` (seen in
    CI): the run is marked interrupted by the signal, and the interrupt goes on."""
    from ovtraj.interrupts import interrupt_of
    from ovtraj.runs import prepare_run

    run = prepare_run(scenario, samples=2, seed=1, code="test", store=RunStore(tmp_path))
    with pytest.raises(KeyboardInterrupt, match="signal 15"), run.working():
        try:
            raise KeyboardInterrupt("signal 15")
        except KeyboardInterrupt as interrupt:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") from (
                interrupt
            )
    manifest = json.loads((run.directory / "manifest.json").read_text())
    assert manifest["status"] == "interrupted"
    assert manifest["interrupted"] == "KeyboardInterrupt: signal 15"
    plain_error = ValueError("not an interrupt")
    assert interrupt_of(plain_error) is None and interrupt_of(None) is None


def test_the_command_reports_a_wrapped_interrupt_as_interrupted():
    """The command's exit for that SystemError: ``interrupted``, 130 (not an internal error)."""
    script = (
        "import ovtraj.cli as cli\n"
        "def app(**_):\n"
        "    try:\n"
        "        raise KeyboardInterrupt('signal 15')\n"
        "    except KeyboardInterrupt as interrupt:\n"
        "        raise SystemError('returned a result with an exception set') from interrupt\n"
        "cli.app = app\n"
        "cli.entry_point()\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    assert (done.returncode, done.stderr.strip()) == (130, "interrupted")


def test_sigterm_marks_the_run_interrupted_in_its_manifest(tmp_path):
    config = _batches_of_one(tmp_path)
    # 20 samples: the run cannot finish before the signal (5 took ~0.2 s after the first).
    args = [OVTRAJ, "run", str(config), "--samples", "20", "--seed", "9", "--store", str(tmp_path)]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_the_first_batch(proc, tmp_path)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and err.strip() == "interrupted"
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert manifest["status"] == "interrupted" and "signal 15" in manifest["interrupted"]
    run = RunStore(tmp_path).run(run_dir.name)
    assert run.verify().clean
    resumed = subprocess.run(args, capture_output=True, text=True, timeout=600, check=False)
    assert resumed.returncode == 0, resumed.stderr
    assert run.status() == "complete" and run.manifest["resumed_after_interruption"] == 1


def test_the_dependency_versions_are_looked_up_once_and_handed_out_as_copies():
    from importlib import metadata

    from ovtraj.environment import dependency_versions

    first = dependency_versions()
    assert first["pyarrow"] == metadata.version("pyarrow")
    first["pyarrow"] = "edited by a caller"
    assert dependency_versions()["pyarrow"] == metadata.version("pyarrow")


def test_decoded_tables_serve_reader_threads_within_their_bound():
    """Prefect's task runner reads from threads: evictions under concurrent reads give
    every reader its own payload's table and keep the bound."""
    from concurrent.futures import ThreadPoolExecutor

    import pyarrow as pa

    from ovtraj.store.files import DecodedTables, parquet_bytes

    payloads = [parquet_bytes(pa.table({"x": np.full(200, float(k))})) for k in range(24)]
    keys = [Digest.of(p).sha256 for p in payloads]
    size = DecodedTables(limit_bytes=0).get("any", payloads[0]).nbytes
    tables = DecodedTables(limit_bytes=5 * size)

    def read(k: int) -> float:
        j = k % len(payloads)
        return float(tables.get(keys[j], payloads[j])["x"][0].as_py()) - j

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # threads switch often: without its lock 20 of 20 runs fail
    try:
        with ThreadPoolExecutor(8) as threads:
            offsets = list(threads.map(read, range(4000)))
    finally:
        sys.setswitchinterval(interval)
    assert offsets == [0.0] * 4000
    assert len(tables) <= 5 and tables.nbytes == len(tables) * size <= 5 * size
