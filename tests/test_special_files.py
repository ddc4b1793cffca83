"""No write and no comparison follows a special file, and files get the user's umask.

A write whose target already exists compares the file there with what it would write
(the store never overwrites): that read goes through the regular-file reader, so a FIFO
or a link to ``/dev/zero`` put where a deterministic id will write (``<store>/<id>/
config.json``, a plan's file) ends the command at once in one line naming it, instead of
waiting forever for a writer or reading /dev/zero until memory runs out. Every folder on
the path of a written file is checked too: a store's ``catalog/`` turned into a link to an
outside folder is refused, nothing written there. ``export --out`` must be a regular file
or absent. Real FIFOs, links and /dev/zero; the commands run in this process through
:func:`ovtraj.cli.run_command` under an alarm, so that a hang fails the test, not the suite.
"""

from __future__ import annotations

import os
import signal
import stat
import time
from pathlib import Path

import pytest

from ovtraj.cli import run_command
from ovtraj.mission.plan import PlanError
from ovtraj.mission.plan_store import write_plan
from ovtraj.store import locks
from ovtraj.store.files import StoreError, write_bytes

AT_ONCE_S = 1.0  # the bound the checks promise: before any work, no read of the file
ALARM_S = 60  # the old code never ended: the alarm ends the case and fails it


class _Hung(BaseException):
    """Raised by the alarm (a BaseException: the CLI turns every Exception into a line)."""


def _hung(signum, frame) -> None:
    raise _Hung


def _timed(args: list[str]) -> tuple[int | None, float]:
    previous = signal.signal(signal.SIGALRM, _hung)
    signal.alarm(ALARM_S)
    start = time.monotonic()
    try:
        code = run_command(args)
    except _Hung:
        code = None
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    return code, time.monotonic() - start


def _special(path: Path, kind: str) -> str:
    """A FIFO or a link to /dev/zero at ``path``; what the error line calls it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "FIFO":
        os.mkfifo(path)
        return "a FIFO"
    path.symlink_to("/dev/zero")
    return "a symbolic link"


def _one_line(capsys) -> str:
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err and "internal error" not in err, err
    (line,) = err.splitlines()
    return line


@pytest.fixture(scope="module")
def stored_run_id(tmp_path_factory) -> str:
    """The id `ovtraj run --samples 2` gives the shipped scenario in this process (the
    code version is read once a process, so the same inputs give the same id again)."""
    store = tmp_path_factory.mktemp("first") / "store"
    assert run_command(["run", "--samples", "2", "--store", str(store)]) == 0
    (directory,) = [p for p in store.iterdir() if p.name != "catalog"]
    return directory.name


@pytest.fixture
def home(tmp_path, monkeypatch):
    monkeypatch.setenv("OVTRAJ_HOME", str(tmp_path / "home"))
    return tmp_path


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero"])
def test_a_special_file_at_a_runs_config_ends_the_run_at_once(kind, stored_run_id, home, capsys):
    capsys.readouterr()
    store = home / "store"
    target = store / stored_run_id / "config.json"
    what = _special(target, kind)
    code, elapsed = _timed(["run", "--samples", "2", "--store", str(store)])
    line = _one_line(capsys)
    assert code == 2 and line == f"{target}: {what}, not a stored file; not read"
    assert elapsed < AT_ONCE_S, elapsed


@pytest.fixture(scope="module")
def plan(reference_plan):
    return reference_plan


@pytest.fixture(scope="module")
def plan_file(reference_plan_file) -> Path:
    return reference_plan_file


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero"])
def test_a_special_file_at_a_plans_path_is_refused_at_once(kind, plan, tmp_path):
    plans = tmp_path / "plans"
    what = _special(plans / "plan-sample-38.json", kind)
    start = time.monotonic()
    with pytest.raises(PlanError) as caught:
        write_plan(plan, plans, "plan-sample-38")
    assert time.monotonic() - start < AT_ONCE_S
    assert str(caught.value) == (
        f"{plans / 'plan-sample-38.json'}: {what}, not a stored file; not read"
    )
    assert not (plans / "plan-sample-38.yaml").exists()  # neither file written


@pytest.mark.parametrize("kind", ["folder", "FIFO", "/dev/zero", "link"])
def test_export_out_must_be_a_regular_file_or_absent(kind, plan_file, tmp_path, capsys):
    out = tmp_path / "out.oem"
    if kind == "folder":
        out.mkdir()
        what = "a directory, not a regular file; not written"
    elif kind == "FIFO":
        os.mkfifo(out)
        what = "a FIFO, not a regular file; not written"
    elif kind == "/dev/zero":
        out = Path("/dev/zero")
        what = "a character device, not a regular file; not written"
    else:
        (tmp_path / "elsewhere.oem").write_text("someone's file\n")
        out.symlink_to(tmp_path / "elsewhere.oem")
        what = "a symbolic link; not written through it"
    capsys.readouterr()
    code, elapsed = _timed(["export", str(plan_file), "--format", "oem", "--out", str(out)])
    assert code == 2 and _one_line(capsys) == f"--out {out}: {what}"
    assert elapsed < AT_ONCE_S  # refused before the replay
    if kind == "link":
        assert (tmp_path / "elsewhere.oem").read_text() == "someone's file\n"


def test_a_stores_catalog_folder_linked_elsewhere_is_refused(home, capsys):
    store, outside = home / "store", home / "outside"
    store.mkdir()
    outside.mkdir()
    (store / "catalog").symlink_to(outside, target_is_directory=True)
    capsys.readouterr()
    for args in (["runs"], ["catalog"], ["tag", "0123456789abcdef", "k=v"]):
        code, _ = _timed([*args, "--store", str(store)])
        line = _one_line(capsys)
        assert code == 2 and f"{store / 'catalog'}: a symbolic link on the path" in line, line
    assert list(outside.iterdir()) == []  # no catalog, stamp, lock or tag written there


def test_a_link_anywhere_below_a_written_file_is_refused(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "root").mkdir()
    (tmp_path / "root" / "linked").symlink_to(tmp_path / "real", target_is_directory=True)
    with pytest.raises(StoreError, match="linked: a symbolic link on the path"):
        write_bytes(tmp_path / "root" / "linked" / "deeper" / "file.json", b"{}")
    with pytest.raises(StoreError, match="linked: a symbolic link on the path"):
        with locks.hold(tmp_path / "root" / "linked" / "x.lock"):
            pass
    assert list((tmp_path / "real").iterdir()) == []


def test_files_and_locks_get_the_processs_umask(tmp_path):
    previous = os.umask(0o077)
    try:
        write_bytes(tmp_path / "private.json", b"{}")
        with locks.hold(tmp_path / "private.lock"):
            pass
    finally:
        os.umask(previous)
    for name in ("private.json", "private.lock"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o600, name
