"""Bounded, inside-the-store reads: ids by pattern, regular files only.

A hostile store (a shared folder) and hostile ids, tried as a user meets them: the
``ovtraj`` command on a real run, with real FIFOs and real symbolic links (to
``/dev/zero``, to a file outside the store). Every case ends in one line naming the file or
the id, exit 2 (``verify``: exit 1 with the bad file listed), never a traceback, never a
hang (each command has a time-out, so a hang fails the test), and nothing outside the store
is read or written. The commands run in this process (tests/cli_runner.py: the entry
point's body), except on a link to ``/dev/zero``: a subprocess under a cap on its address
space, so that an unchecked read fails the test instead of exhausting the machine's memory.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ovtraj.runs import RunStore
from ovtraj.store import locks
from ovtraj.store.files import StoreError
from tests.cli_runner import run_cli
from tests.conftest import DEFAULT_SCENARIO

OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))
# Generous: each command takes 2-5 s here; a read that waits on a FIFO never ends.
TIMEOUT_S = 120
# An unchecked read follows a /dev/zero link until memory runs out; this cap on the
# command's address space turns that into a quick MemoryError instead of starving the
# machine (a checked read needs far less: ~1.5 GB of address space measured here).
ADDRESS_SPACE_BYTES = 4 * 2**30


def _cli(*args: str) -> subprocess.CompletedProcess:
    """``ovtraj ARGS`` in this process, under the time-out."""
    return run_cli(*args, timeout=TIMEOUT_S)


def _limited(*args: str) -> subprocess.CompletedProcess:
    """``ovtraj ARGS`` as a process of its own, its address space capped."""

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))

    return subprocess.run(
        [OVTRAJ, *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
        preexec_fn=limited,
    )


def _one_line_error(done: subprocess.CompletedProcess, code: int = 2) -> str:
    assert done.returncode == code, (done.stdout, done.stderr)
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    return lines[0]


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` and its content (what must not change)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A real 8-sample run (two batches of 4) made by `ovtraj run`; tests work on copies."""
    store = tmp_path_factory.mktemp("reads") / "runs"
    done = _cli("run", str(DEFAULT_SCENARIO), "--samples", "8", "--store", str(store), "--json")
    assert done.returncode == 0, done.stderr
    run_id = json.loads(done.stdout)["run_id"]
    assert sorted(p.name for p in (store / run_id / "batches").iterdir()) == ["0.json", "1.json"]
    return store, run_id


def _copy(stored, tmp_path: Path) -> tuple[Path, str]:
    store, run_id = stored
    copy = tmp_path / "s" / "runs"
    shutil.copytree(store, copy)
    return copy, run_id


def test_a_path_or_a_control_character_as_an_id_is_refused_in_one_line(stored, tmp_path):
    store, run_id = _copy(stored, tmp_path)
    # What `../../outside/x` reaches from the store root: a readable run's files.
    outside = tmp_path / "outside" / "x"
    shutil.copytree(store / run_id, outside)
    before = _tree(tmp_path / "outside")
    for command in ("show", "verify", "replay", "optimize", "plan"):
        line = _one_line_error(_cli(command, "../../outside/x", "--store", str(store)))
        what = "id" if command == "verify" else "run id"  # verify takes every kind's id
        assert line.startswith(f"{what} '../../outside/x' is not an id of this store"), line
    forged = f"{run_id}\nINFO run {run_id}: verified clean"
    line = _one_line_error(_cli("show", forged, "--store", str(store)))
    assert repr(forged) in line  # the newline shown as \n: no second (forged) log line
    line = _one_line_error(_cli("show", "0" * 100_000, "--store", str(store)))
    assert line.startswith("run id '000") and len(line) < 300, len(line)  # cut, not echoed whole
    line = _one_line_error(
        _cli("run", str(DEFAULT_SCENARIO), "--append", "..", "--store", str(store))
    )
    assert line.startswith("run id '..' is not an id of this store"), line
    pipeline = "../../../outside/x"
    line = _one_line_error(_cli("plan", run_id, "--pipeline", pipeline, "--store", str(store)))
    assert line.startswith(f"pipeline id {pipeline!r} is not an id of this store"), line
    assert _tree(tmp_path / "outside") == before  # nothing written there


def test_a_fifo_in_place_of_a_stored_file_is_refused_at_once(stored, tmp_path):
    store, run_id = _copy(stored, tmp_path)
    part = store / run_id / "totals" / "part-00001.parquet"
    part.unlink()
    os.mkfifo(part)  # no writer: a plain read waits for one forever
    checked = _cli("verify", run_id, "--store", str(store))
    assert checked.returncode == 1 and "Traceback" not in checked.stderr, checked.stderr
    bad = [line for line in checked.stdout.splitlines() if line.startswith("bad:")]
    assert bad == [f"bad: {part}: a FIFO, not a stored file; not read"], checked.stdout
    line = _one_line_error(_cli("replay", run_id, "--store", str(store)))
    assert line == f"{part}: a FIFO, not a stored file; not read"
    marker = store / run_id / "batches" / "0.json"
    marker.unlink()
    os.mkfifo(marker)  # an index file: read with no recorded size
    line = _one_line_error(_cli("show", run_id, "--store", str(store)))
    assert line == f"{marker}: a FIFO, not a stored file; not read"


def test_a_link_to_dev_zero_in_place_of_a_stored_file_is_refused_at_once(stored, tmp_path):
    store, run_id = _copy(stored, tmp_path)
    part = store / run_id / "trajectories" / "deorbit" / "part-00000.parquet"
    part.unlink()
    part.symlink_to("/dev/zero")
    checked = _limited("verify", run_id, "--store", str(store))
    assert checked.returncode == 1 and "Traceback" not in checked.stderr, checked.stderr
    bad = [line for line in checked.stdout.splitlines() if line.startswith("bad:")]
    assert bad == [f"bad: {part}: a symbolic link, not a stored file; not read"], checked.stdout
    marker = store / run_id / "batches" / "1.json"
    marker.unlink()
    marker.symlink_to("/dev/zero")  # an index file: no recorded size bounds the read
    line = _one_line_error(_limited("replay", run_id, "--store", str(store)))
    assert line == f"{marker}: a symbolic link, not a stored file; not read"


def _record_size(marker: Path, name: str, recorded: str) -> None:
    """Write ``recorded`` (JSON text) as the size the marker records for ``name``."""
    text = marker.read_text(encoding="utf-8")
    written = f'"bytes": {json.loads(text)["files"][name]["bytes"]},'
    assert text.count(written) == 1
    marker.write_text(text.replace(written, f'"bytes": {recorded},'), encoding="utf-8")


def test_a_marker_recording_an_impossible_size_is_named(stored, tmp_path):
    store, run_id = _copy(stored, tmp_path)
    marker = store / run_id / "batches" / "0.json"
    _record_size(marker, "totals/part-00000.parquet", "1e400")  # JSON's infinity
    # refused by the bounded JSON reader (a float beyond its range is no JSON number)
    refused = f"{marker}: unreadable JSON file (1e400 is beyond a float's range)"
    for command in ("show", "replay"):
        line = _one_line_error(_cli(command, run_id, "--store", str(store)))
        assert line == refused
    checked = _cli("verify", run_id, "--store", str(store))
    assert checked.returncode == 1 and "Traceback" not in checked.stderr, checked.stderr
    assert f"bad: {refused}" in checked.stdout


@pytest.mark.parametrize("recorded", ["-1", "true", '"3009"', "1" + "0" * 30, "null", "9" * 5000])
def test_every_impossible_recorded_size_is_refused_naming_the_marker(stored, tmp_path, recorded):
    """The other forms (negative, a bool, a string, beyond any file, none, more digits than
    Python converts) through the library: the same reads the commands make."""
    store, run_id = _copy(stored, tmp_path)
    marker = store / run_id / "batches" / "0.json"
    _record_size(marker, "totals/part-00000.parquet", recorded)
    run = RunStore(store).run(run_id)
    with pytest.raises(StoreError) as refused:
        run.totals()
    assert str(refused.value).startswith(f"{marker}: ") and "\n" not in str(refused.value)


def test_a_marker_listing_a_file_outside_its_run_is_refused(stored, tmp_path):
    store, run_id = _copy(stored, tmp_path)
    secret = tmp_path / "s" / "secret.parquet"
    secret.write_bytes(b"not the store's")
    marker = store / run_id / "batches" / "0.json"
    content = json.loads(marker.read_text(encoding="utf-8"))
    content["files"]["../../secret.parquet"] = content["files"].pop("totals/part-00000.parquet")
    marker.write_text(json.dumps(content), encoding="utf-8")
    line = _one_line_error(_cli("replay", run_id, "--store", str(store)))
    assert line.startswith(f"{marker}: lists '../../secret.parquet', a file name that"), line
    checked = _cli("verify", run_id, "--store", str(store))
    assert checked.returncode == 1 and str(secret) not in checked.stdout, checked.stdout


def test_a_lock_file_that_is_a_link_is_never_written_through(tmp_path):
    """A writer records its host and process id in the lock file it holds: through a link
    planted in a shared store, it would truncate and overwrite a file elsewhere."""
    victim = tmp_path / "victim.txt"
    victim.write_text("an analyst's file\n", encoding="utf-8")
    lock = tmp_path / "runs" / "0123456789abcdef" / "locks" / "batch-1.lock"
    lock.parent.mkdir(parents=True)
    lock.symlink_to(victim)
    with pytest.raises(StoreError, match=r"batch-1\.lock: a symbolic link, so not a lock"):
        with locks.hold(lock):
            pass
    assert locks.held(lock)  # cannot be checked: whoever asks leaves the run alone
    assert victim.read_text(encoding="utf-8") == "an analyst's file\n"
