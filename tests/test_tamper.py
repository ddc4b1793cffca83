"""Tamper evidence: HMAC seals on manifests and markers under a key
kept outside the store (``OVTRAJ_STORE_KEY``, :mod:`ovtraj.store.seals`).

An attacker who can write the store but has no key rewrites a totals file and its batch
marker with the new size and SHA-256, as the checksums alone cannot see. The stores are
real (a run store with made-up records: no simulation; a product; a Monte Carlo run),
``ovtraj verify`` runs as a user runs it, with the key in its environment (in this process,
tests/cli_runner.py: the entry point's body; the key is read at each use).
"""

from __future__ import annotations

import hashlib
import json
import secrets
import subprocess
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, MissionDesign, MissionRecord, reference
from ovtraj.paths import reference_dir
from ovtraj.runs import RunStore, execute, latin_hypercube
from ovtraj.store.files import Digest, StoreError
from ovtraj.store.products import Product
from ovtraj.store.seals import STORE_KEY_ENV, TamperedError
from ovtraj.studies.deorbit_burn.store import MonteCarloRun
from tests.cli_runner import run_cli
from tests.test_products_integrity import _frame

KEY_A = secrets.token_hex(32)
KEY_B = secrets.token_hex(32)


def _verify(run_id: str, store: Path, key: str | None) -> subprocess.CompletedProcess:
    return run_cli("verify", run_id, "--store", str(store), env={STORE_KEY_ENV: key}, timeout=120)


def _made_up_run(root: Path, scenario):
    """A run of 6 samples in two batches of made-up records (no simulation), and a product
    of the run (a front's marker and one data file)."""
    samples = latin_hypercube(scenario.mission.design_bounds, 6, 5)
    run = RunStore(root).create(resolved=scenario.resolved(), samples=samples, seed=5, code="t")
    steps = execute.trajectory_steps(scenario)
    for k, batch in run.batches(3):
        records = [
            MissionRecord(
                design=MissionDesign(*(getattr(r, n) for n in DESIGN_NAMES)),
                failed_stage="rendezvous",
                reason="made up",
            )
            for r in batch.itertuples(index=False)
        ]
        run.write_batch(k, records, batch["sample_id"].tolist(), trajectory_steps=steps)
    front = Product(run.directory / "fronts" / "f1", "meta.json")
    with front.writing() as out:
        out.write_json("front.json", {"points": [1.0, 2.0]})
        out.finish({"kind": "made up", "code": "t"})
    return run


def _rewrite_totals_and_marker(run) -> Path:
    """What an attacker without the key does: a changed value in a valid totals file, and
    the batch marker's recorded size and SHA-256 updated to match (its seal left as it was)."""
    victim = run.directory / "totals" / "part-00001.parquet"
    table = pq.read_table(victim)
    frame = table.to_pandas()
    frame.loc[0, "parking_altitude_km"] += 1.0
    pq.write_table(pa.Table.from_pandas(frame, schema=table.schema), victim)
    payload = victim.read_bytes()
    marker = run.directory / "batches" / "1.json"
    content = json.loads(marker.read_text(encoding="utf-8"))
    content["files"]["totals/part-00001.parquet"] = {
        "bytes": len(payload),
        "sha256": hashlib.sha256(payload).hexdigest(),
    }
    marker.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")
    return marker


def _lines(done: subprocess.CompletedProcess, prefix: str) -> list[str]:
    return [line for line in done.stdout.splitlines() if line.startswith(prefix)]


def test_a_rewritten_totals_file_and_marker_are_tampered_with_the_key_clean_without(
    tmp_path, scenario, monkeypatch
):
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    run = _made_up_run(tmp_path / "runs", scenario)
    store = tmp_path / "runs"
    assert _verify(run.id, store, KEY_A).returncode == 0
    marker = _rewrite_totals_and_marker(run)

    done = _verify(run.id, store, KEY_A)
    assert done.returncode == 1, (done.stdout, done.stderr)
    tampered = _lines(done, "tampered:")
    assert len(tampered) == 1 and str(marker) in tampered[0], done.stdout
    assert not _lines(done, "bad:")  # the digests agree: not an accident
    assert "1 tampered file(s)" in done.stdout and "clean" not in done.stdout
    assert KEY_A not in done.stdout + done.stderr
    # A normal read refuses it naming the marker; the command says so in one line, exit 2.
    with pytest.raises(TamperedError, match=r"batches/1\.json: tampered"):
        run.totals()
    shown = run_cli("show", run.id, "--store", str(store), env={STORE_KEY_ENV: KEY_A}, timeout=120)
    assert shown.returncode == 2 and "Traceback" not in shown.stderr
    assert shown.stderr.strip().splitlines() == [tampered[0].removeprefix("tampered: ")]

    # The limit without a key: the checksums agree, so verify says clean.
    plain = _verify(run.id, store, None)
    assert plain.returncode == 0 and "clean" in plain.stdout, plain.stdout
    # The key is never written into the store.
    for path in run.directory.rglob("*"):
        if path.is_file():
            assert KEY_A.encode() not in path.read_bytes(), path


def test_a_store_sealed_with_one_key_is_tampered_under_another(tmp_path, scenario, monkeypatch):
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    run = _made_up_run(tmp_path / "runs", scenario)
    done = _verify(run.id, tmp_path / "runs", KEY_B)
    assert done.returncode == 1, (done.stdout, done.stderr)
    named = sorted(Path(line.split(": ", 2)[1]) for line in _lines(done, "tampered:"))
    expected = [
        run.directory / "batches" / "0.json",
        run.directory / "batches" / "1.json",
        run.directory / "fronts" / "f1" / "meta.json",
        run.directory / "manifest.json",
    ]
    assert named == sorted(expected), done.stdout
    assert all("does not match" in line for line in _lines(done, "tampered:"))
    monkeypatch.setenv(STORE_KEY_ENV, KEY_B)
    with pytest.raises(TamperedError, match=r"manifest\.json: tampered"):
        _ = run.manifest
    with pytest.raises(TamperedError, match=r"f1/meta\.json: tampered"):
        Product(run.directory / "fronts" / "f1", "meta.json").marker()


def test_a_store_written_without_the_key_cannot_be_authenticated(tmp_path, scenario, monkeypatch):
    monkeypatch.delenv(STORE_KEY_ENV, raising=False)
    run = _made_up_run(tmp_path / "runs", scenario)
    assert _verify(run.id, tmp_path / "runs", None).returncode == 0
    done = _verify(run.id, tmp_path / "runs", KEY_A)
    assert done.returncode == 1, (done.stdout, done.stderr)
    tampered = _lines(done, "tampered:")
    assert len(tampered) == 4 and all("no HMAC" in line for line in tampered), done.stdout
    assert any(str(run.directory / "manifest.json") in line for line in tampered)
    assert not _lines(done, "bad:")  # every data file still matches its (unsealed) digest
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    with pytest.raises(TamperedError, match=r"manifest\.json: tampered: no HMAC"):
        run.samples()
    with pytest.raises(TamperedError, match=r"batches/[01]\.json: tampered: no HMAC"):
        run.totals()


def test_same_inputs_and_key_write_the_same_bytes_and_no_key_writes_no_seal(
    tmp_path, scenario, monkeypatch
):
    def markers(run) -> dict[str, bytes]:
        names = ["batches/0.json", "batches/1.json", "fronts/f1/meta.json"]
        return {name: (run.directory / name).read_bytes() for name in names}

    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    first = _made_up_run(tmp_path / "a", scenario)
    second = _made_up_run(tmp_path / "b", scenario)
    assert first.id == second.id
    assert markers(first) == markers(second)
    for payload in markers(first).values():
        assert len(json.loads(payload)["hmac"]) == 64
    manifest = json.loads((first.directory / "manifest.json").read_bytes())
    assert len(manifest["hmac"]) == 64
    # Rewritten (a status change): sealed again, and every reader still accepts it.
    first.update_manifest(status="done")
    assert first.manifest["status"] == "done" and "hmac" not in first.manifest
    assert len(first.totals()) == 6
    # The shipped reference data is code, not store: unsealed, it reads under any key.
    assert find_launch_fit(scenario, roots=(reference_dir() / "launch_fit",)) is not None
    values, marker = reference.load()
    assert len(values) and "hmac" not in marker
    # Without a key, the bytes are those of a store without seals.
    monkeypatch.delenv(STORE_KEY_ENV)
    unsealed = _made_up_run(tmp_path / "c", scenario)
    for name, payload in markers(unsealed).items():
        keyed = json.loads(markers(first)[name])
        del keyed["hmac"]
        assert json.loads(payload) == keyed
        assert payload == (json.dumps(keyed, indent=2) + "\n").encode()
    assert "hmac" not in json.loads((unsealed.directory / "manifest.json").read_bytes())


def test_a_child_run_seals_the_batches_it_adopts(tmp_path, scenario, monkeypatch):
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    parent = _made_up_run(tmp_path / "runs", scenario)
    more = latin_hypercube(scenario.mission.design_bounds, 3, 6)
    samples = pd.concat(
        [parent.samples(), more.assign(sample_id=more["sample_id"] + 6)], ignore_index=True
    )
    child = RunStore(tmp_path / "runs").create(
        resolved=scenario.resolved(), samples=samples, seed=5, code="t", parent=parent.id
    )
    assert child.adopt(parent) == 2
    for k in (0, 1):
        stored = json.loads((child.directory / "batches" / f"{k}.json").read_bytes())
        assert stored["adopted_from"] == [parent.id, k] and len(stored["hmac"]) == 64
    assert len(child.totals()) == 6
    done = _verify(child.id, tmp_path / "runs", KEY_A)
    assert done.returncode == 0 and "clean" in done.stdout, done.stdout


def test_a_monte_carlo_run_is_sealed_and_checked(tmp_path, monkeypatch):
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    run = MonteCarloRun.create(
        tmp_path, resolved={"name": "test"}, runs=3, strategies=[1, 2], seed=1, code="test"
    )
    assert run.write_batch(0, _frame(runs=(0, 1, 2)))
    for name in ("run.json", "batches/00000.json"):
        assert len(json.loads((run.directory / name).read_bytes())["hmac"]) == 64
    assert len(run.results()) == 6 and run.config == {"name": "test"}
    marker = run.directory / "batches" / "00000.json"
    content = json.loads(marker.read_bytes())
    content["runs"] = [0, 1]
    marker.write_text(json.dumps(content))
    with pytest.raises(TamperedError, match=r"00000\.json: tampered"):
        run.results()
    info = run.directory / "run.json"
    content = json.loads(info.read_bytes())
    content["status"] = "done"
    info.write_text(json.dumps(content))
    with pytest.raises(StoreError, match=r"run\.json: tampered"):
        _ = run.config


def test_a_short_store_key_is_one_line_naming_the_variable(tmp_path, scenario, monkeypatch):
    monkeypatch.delenv(STORE_KEY_ENV, raising=False)
    run = _made_up_run(tmp_path / "runs", scenario)
    done = _verify(run.id, tmp_path / "runs", "secret")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert STORE_KEY_ENV in line and "6 bytes" in line and "secret" not in line


# --- the catalog and the tags: sealed, and rebuilt from the sealed documents otherwise ---


def _forge_catalog(store: Path, run_id: str, samples: int) -> Path:
    """What an attacker without the key does to the catalog: a row's figure changed in
    catalog.parquet and its size and SHA-256 put in catalog.json (its seal left as it was)."""
    folder = store / "catalog"
    table = pq.read_table(folder / "catalog.parquet")
    frame = table.to_pandas()
    frame.loc[frame["id"] == run_id, "samples"] = samples
    pq.write_table(
        pa.Table.from_pandas(frame, schema=table.schema, preserve_index=False),
        folder / "catalog.parquet",
    )
    payload = (folder / "catalog.parquet").read_bytes()
    marker = json.loads((folder / "catalog.json").read_bytes())
    marker["file"] = Digest.of(payload).to_json()
    (folder / "catalog.json").write_text(json.dumps(marker))
    return folder / "catalog.json"


def _samples_shown(store: Path, run_id: str) -> int:
    from ovtraj.tracking.catalog import refresh

    frame = refresh(store).frame
    return int(frame.loc[frame["id"] == run_id, "samples"].item())


def test_a_forged_catalog_is_tampered_and_rebuilt_from_the_sealed_manifests(
    tmp_path, scenario, monkeypatch
):
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    store = tmp_path / "runs"
    run = _made_up_run(store, scenario)
    assert _samples_shown(store, run.id) == 6
    assert len(json.loads((store / "catalog" / "catalog.json").read_bytes())["hmac"]) == 64
    assert _verify("catalog", store, KEY_A).returncode == 0
    marker = _forge_catalog(store, run.id, 999)
    done = _verify("catalog", store, KEY_A)
    assert done.returncode == 1
    (line,) = _lines(done, "tampered:")
    assert str(marker) in line
    assert _samples_shown(store, run.id) == 6  # rebuilt, the forged row never shown
    assert _verify("catalog", store, KEY_A).returncode == 0
    # Without a key only checksums hold: the forged digest matches, but the rows are not
    # those of the store's documents, which verify compares.
    _forge_catalog(store, run.id, 999)
    done = _verify("catalog", store, None)
    assert done.returncode == 1 and "not those of the store's documents" in done.stdout


def test_a_catalog_built_without_the_key_is_not_trusted_with_it(tmp_path, scenario, monkeypatch):
    monkeypatch.delenv(STORE_KEY_ENV, raising=False)
    store = tmp_path / "runs"
    run = _made_up_run(store, scenario)
    _samples_shown(store, run.id)
    _forge_catalog(store, run.id, 999)
    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    from ovtraj.tracking.catalog import refresh

    # The run's own manifest was written without the key: its row is an error, not a figure.
    catalog = refresh(store)
    assert "tampered" in catalog.rebuilt_because
    row = catalog.frame[catalog.frame["id"] == run.id].iloc[0]
    assert row["samples"] is None and "tampered" in row["error"]


def test_tag_files_are_sealed_and_a_forged_or_foreign_one_is_not_shown(
    tmp_path, scenario, monkeypatch
):
    from ovtraj.tracking.catalog import refresh, set_tags
    from ovtraj.tracking.catalog_tags import read_tags

    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    store = tmp_path / "runs"
    run = _made_up_run(store, scenario)
    set_tags(store, run.id, {"night": "1"})
    tag_file = store / "catalog" / "tags" / f"{run.id}.json"
    assert len(json.loads(tag_file.read_bytes())["hmac"]) == 64
    for forged in (
        {"id": run.id, "tags": {"night": "2"}},  # no seal
        [1, 2],  # not a tag file at all
        {"id": run.id, "tags": {"night": "x" * 5_000_000}},  # beyond what `tag` accepts
    ):
        tag_file.write_text(json.dumps(forged))
        with pytest.raises(StoreError, match=str(tag_file)):
            read_tags(store, run.id)
        frame = refresh(store).frame
        assert frame.loc[frame["id"] == run.id, "tags"].item() == "{}"
        done = _verify("catalog", store, KEY_A)
        assert done.returncode == 1 and str(tag_file) in done.stdout
        assert len(done.stdout) < 10_000


def test_an_id_read_from_a_stored_document_is_checked_before_it_is_shown(
    tmp_path, scenario, monkeypatch
):
    """A manifest naming a parent that is a path, not an id: its catalog row is an error
    naming the field, never a row whose parent a reader would follow."""
    from ovtraj.tracking.catalog import refresh

    monkeypatch.delenv(STORE_KEY_ENV, raising=False)
    store = tmp_path / "runs"
    run = _made_up_run(store, scenario)
    manifest = run.directory / "manifest.json"
    content = json.loads(manifest.read_bytes())
    content["parent"] = "../../outside/fakerun"
    manifest.write_text(json.dumps(content))
    row = refresh(store).frame.query("kind == 'run'").iloc[0]
    assert row["parent"] is None and "parent" in row["error"] and "not an id" in row["error"]


def test_a_forged_export_record_names_no_file_to_hash(tmp_path, monkeypatch, caplog):
    """The export record beside the catalog is sealed: one rewritten without the key to
    name another file (lineage would hash it and print its digest) lists no export."""
    from ovtraj.tracking.catalog_rows import plan_id
    from ovtraj.tracking.lineage import _export_links, record_export

    monkeypatch.setenv(STORE_KEY_ENV, KEY_A)
    store = tmp_path / "runs"
    plans = store / ("a" * 16) / "pipeline" / ("b" * 16) / "plans"
    plans.mkdir(parents=True)
    plan = {"schema_version": 1, "name": "made up"}
    (plans / "plan-sample-1.json").write_text(json.dumps(plan))
    export = tmp_path / "plan.oem"
    export.write_text("CCSDS_OEM_VERS = 2.0\n")
    record = record_export(plans / "plan-sample-1.json", plan, export, "oem")
    assert len(json.loads(record.read_bytes())["hmac"]) == 64
    (link,) = _export_links(RunStore(store), plan_id(plan))
    assert (link.path, link.state) == (str(export.resolve()), "ok")
    secret = tmp_path / "outside.txt"
    secret.write_text("not for lineage")
    forged = json.loads(record.read_bytes())
    forged["exports"] = {str(secret): {"format": "oem", **forged["exports"][str(export.resolve())]}}
    record.write_text(json.dumps(forged))
    assert _export_links(RunStore(store), plan_id(plan)) == []
    assert "tampered" in caplog.text and str(record) in caplog.text
