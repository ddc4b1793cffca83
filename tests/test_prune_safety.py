"""`ovtraj prune --yes` deletes inside its roots only.

A store and a Prefect results folder shared with other people may hold symbolic links
planted there: a ``.pruned-*`` link, a run directory that is a link, a product folder
that is a link, a link among the task results. Each case is tried with the real command
on a real run family (`ovtraj run`, then `run --append` twice), run in this process
(tests/cli_runner.py: the entry point's body, its exit code and output; a time-out fails a
prune that hangs): the link's target outside the store is intact afterwards. Only files
that parse as Prefect result records (written here by Prefect's own ``ResultStore``) count
as task results, and what another process holds (a run's lock, a product folder's lock) is
kept.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli_runner import run_cli
from tests.conftest import DEFAULT_SCENARIO, prefect_record

# Generous: a prune takes ~2 s here; one that waits on a FIFO never ends.
TIMEOUT_S = 120


def _cli(*args: str, results: Path | None = None) -> subprocess.CompletedProcess:
    # OVTRAJ_PREFECT_RESULTS: configs/orchestration.yaml `results`, read at each use
    env = None if results is None else {"OVTRAJ_PREFECT_RESULTS": str(results)}
    return run_cli(*args, env=env, timeout=TIMEOUT_S)


def _run(store: Path, samples: int, parent: str | None = None) -> str:
    args = ["run", str(DEFAULT_SCENARIO), "--samples", str(samples), "--store", str(store)]
    done = _cli(*args, "--json", *(["--append", parent] if parent else []))
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)["run_id"]


@pytest.fixture(scope="module")
def family(tmp_path_factory):
    """A DoE run and two child runs extending it: the middle one is superseded by the last
    (every sample of it is in a later complete run), so `prune` removes it."""
    store = tmp_path_factory.mktemp("family") / "runs"
    root = _run(store, 2)
    middle = _run(store, 2, root)
    last = _run(store, 2, middle)
    return store, {"root": root, "middle": middle, "last": last}


def _copy(family, tmp_path: Path) -> tuple[Path, dict[str, str]]:
    store, ids = family
    copy = tmp_path / "runs"
    shutil.copytree(store, copy, symlinks=True)
    return copy, ids


def _outside(tmp_path: Path) -> Path:
    """A folder of someone else's files, outside the store."""
    folder = tmp_path / "elsewhere"
    (folder / "sub").mkdir(parents=True)
    (folder / "thesis.tex").write_text("years of work\n", encoding="utf-8")
    (folder / "sub" / "data.csv").write_text("1,2,3\n", encoding="utf-8")
    return folder


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _prune(store: Path, *args: str, results: Path | None = None) -> subprocess.CompletedProcess:
    done = _cli("prune", "--store", str(store), "--yes", *args, results=results)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return done


def test_a_pruned_link_in_the_store_leaves_its_target(family, tmp_path):
    store, _ = _copy(family, tmp_path)
    outside = _outside(tmp_path)
    before = _tree(outside)
    link = store / ".pruned-0123456789abcdef"  # looks like what a stopped prune leaves
    link.symlink_to(outside, target_is_directory=True)
    _prune(store, "--only", "children")
    assert _tree(outside) == before
    assert link.is_symlink()  # not ours to judge: left as found


def test_a_run_directory_that_is_a_link_leaves_its_target(family, tmp_path):
    store, ids = _copy(family, tmp_path)
    moved = tmp_path / "elsewhere" / ids["middle"]  # the superseded run, moved out ...
    moved.parent.mkdir()
    shutil.move(store / ids["middle"], moved)
    (store / ids["middle"]).symlink_to(moved, target_is_directory=True)  # ... and linked
    before = _tree(moved)
    done = _prune(store, "--only", "children")
    assert _tree(moved) == before and (store / ids["middle"]).is_symlink(), done.stdout
    # The same run as a real directory of the store is superseded, and removed.
    (store / ids["middle"]).unlink()
    shutil.move(moved, store / ids["middle"])
    done = _prune(store, "--only", "children")
    assert f"deleted: {store.resolve() / ids['middle']} " in done.stdout, done.stdout
    assert not (store / ids["middle"]).exists()
    assert (store / ids["root"]).is_dir() and (store / ids["last"]).is_dir()


def test_a_product_folder_that_is_a_link_or_being_written_is_kept(family, tmp_path):
    store, ids = _copy(family, tmp_path)
    fits = store / ids["root"] / "surrogates"
    fits.mkdir()
    stale = {"run_id": ids["root"], "code": "0.0.1+gdeadbeef0000", "files": {}}
    outside = _outside(tmp_path)
    (outside / "meta.json").write_text(json.dumps(stale), encoding="utf-8")
    before = _tree(outside)
    (fits / "0123456789abcdef").symlink_to(outside, target_is_directory=True)
    written = fits / "fedcba9876543210"  # a fit of another code version, being written
    written.mkdir()
    (written / "meta.json").write_text(json.dumps(stale), encoding="utf-8")
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys\n"
            "from pathlib import Path\n"
            "from ovtraj.store.locks import hold_directory\n"
            "with hold_directory(Path(sys.argv[1]), wait_s=0):\n"
            "    print('held', flush=True)\n"
            "    sys.stdin.read()\n",
            str(written),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline() == "held\n"
        _prune(store, "--only", "fits")
        assert _tree(outside) == before and (fits / "0123456789abcdef").is_symlink()
        assert (written / "meta.json").is_file()  # its writer holds it
    finally:
        holder.communicate(input="", timeout=TIMEOUT_S)  # releases the lock
    done = _prune(store, "--only", "fits")
    assert not written.exists(), done.stdout  # released: stale, removed
    assert _tree(outside) == before


def test_only_prefect_result_records_count_and_a_link_among_them_leaves_its_target(
    family, tmp_path
):
    store, _ = _copy(family, tmp_path)
    results = tmp_path / "prefect-results"
    results.mkdir()
    record = prefect_record(results, "3f9a1c")
    notes = results / "README.txt"
    notes.write_text("results of the March campaign, do not delete\n", encoding="utf-8")
    foreign = results / "5d2e77"  # JSON, but not a result record
    foreign.write_text(json.dumps({"metadata": "x", "result": 1}), encoding="utf-8")
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    elsewhere = prefect_record(outside, "8b0c4d")  # a real record, outside the folder
    before = elsewhere.read_bytes()
    (results / "8b0c4d").symlink_to(elsewhere)
    listed = _cli(
        "prune", "--store", str(store), "--only", "prefect-results", "--json", results=results
    )
    assert listed.returncode == 0, listed.stderr
    items = json.loads(listed.stdout)["items"]
    assert [(Path(i["path"]).name, i["size_bytes"]) for i in items] == [
        ("3f9a1c", record.stat().st_size)
    ]
    _prune(store, "--only", "prefect-results", results=results)
    assert not record.exists()
    assert notes.is_file() and foreign.is_file() and (results / "8b0c4d").is_symlink()
    assert elsewhere.read_bytes() == before


def test_a_run_whose_lock_cannot_be_checked_is_kept_without_waiting(family, tmp_path):
    store, ids = _copy(family, tmp_path)
    lock = store / ids["middle"] / "locks" / "run.lock"
    lock.unlink(missing_ok=True)
    os.mkfifo(lock)  # opening it to test the lock would wait for a writer forever
    done = _prune(store, "--only", "children")
    assert (store / ids["middle"] / "manifest.json").is_file(), done.stdout
