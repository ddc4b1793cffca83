"""The command line against hostile identifiers, paths and numbers.

Every command that takes a run id, a file or a number is given path-like ids
(``../../x``, ``/etc/passwd``, ``a/b``), control characters (a newline, a terminal
escape; a NUL cannot be passed in argv), special files (a FIFO, a directory) and huge
or non-finite numbers (``1e400``, ``nan``, ``inf``, ``-1``, ``99999999999999999999``).
Each must end with exit code 2 (the command's contract for bad input), exactly one line
on stderr and nothing on stdout, never a traceback nor an internal error, and no file
created outside the test's workspace.

The commands run in this process through :func:`ovtraj.cli.run_command`, the body of
the ``ovtraj`` entry point (its exit code and its one-line errors, no process end): ~5 s
for the ~180 cases where a subprocess costs ~2 s of imports each. An alarm ends a case
that hangs (a FIFO read as a file waits for a writer forever), failing the test and not
the suite. ``/dev/zero`` is left to tests/test_bounded_inputs.py, in a subprocess with
a memory limit: read to its end here it would take this process's memory.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from ovtraj.cli import run_command
from tests.conftest import DEFAULT_SCENARIO, REPO

ISS_TLE = REPO / "tests" / "data" / "targets" / "iss_2019-12-09.tle"
IDS = ["../../x", "/etc/passwd", "a/b", "..", "a\nb", "\x1b[31mred"]
NUMBERS = ["1e400", "nan", "inf", "-1", "99999999999999999999"]
WEIGHTS = ["nan,1,1", "inf,1,1", "1e400,1,1", "-1,1,1", "0,0,0", "1,1", "a\nb", "\x1b[31m"]
CASE_LIMIT_S = 30  # each case takes ~10-100 ms here; a hang is what this catches


class _Hung(BaseException):
    """Raised by the alarm in a case that has not ended (a BaseException: the command's
    own handler, which turns every Exception into one line, does not catch it)."""


def _hung(signum, frame) -> None:
    raise _Hung


@pytest.fixture
def workspace(tmp_path, monkeypatch):
    """``tmp_path/ws``: the workspace (OVTRAJ_HOME), the store and the current folder,
    with ``tmp_path/ws/cwd/../../x`` (``tmp_path/x``) outside it; a FIFO in it."""
    ws = tmp_path / "ws"
    for name in ("home", "store", "cwd"):
        (ws / name).mkdir(parents=True)
    os.mkfifo(ws / "fifo.yaml")
    monkeypatch.setenv("OVTRAJ_HOME", str(ws / "home"))
    monkeypatch.chdir(ws / "cwd")
    return ws


def _outside(tmp_path: Path, ws: Path) -> set[Path]:
    return {p for p in tmp_path.rglob("*") if ws not in (p, *p.parents)}


def _cases(ws: Path) -> list[list[str]]:
    store = ["--store", str(ws / "store")]
    special = [str(ws / "fifo.yaml"), str(ws), "/etc/passwd", "a\nb", "../../x"]
    cases: list[list[str]] = []
    for run_id in IDS:
        cases += [
            ["show", run_id, *store],
            ["verify", run_id, *store],
            ["replay", run_id, *store],
            ["optimize", run_id, *store],
            ["plan", run_id, *store],
            ["run", str(DEFAULT_SCENARIO), "--append", run_id, *store],
            ["pipeline", str(DEFAULT_SCENARIO), "--run", run_id, *store],
        ]
    for number in NUMBERS:
        cases += [
            ["run", "--samples", number, *store],
            ["pipeline", "--samples", number, *store],
            ["run", "--seed", number, *store],
            ["plan", "x", "--pick", number, *store],
            ["plan", "x", "--max-time-h", number, *store],
            ["plan", "x", "--max-dv-mps", number, *store],
            ["plan", "x", "--min-payload-kg", number, *store],
            ["run", "--workers", number, *store],
            ["pipeline", "--workers", number, *store],
            ["fly", "plan.json", "--monte-carlo", number],
            ["fly", "plan.json", "--seed", number],
            ["target", str(ISS_TLE), "--span-h", number],
            ["target", str(ISS_TLE), "--catalog-number", number],
            ["window", "--days", number, *store],
            ["window", "--days", "2", "--samples", number, *store],
        ]
    for number in ("nan", "inf", "1e400", "-1"):  # refused before the pipeline starts
        cases += [["pipeline", "--max-time-h", number, *store]]
        cases += [["window", "--days", "2", "--max-dv-mps", number, *store]]
    for weights in WEIGHTS:
        cases += [["plan", "x", "--weights", weights, *store]]
        cases += [["pipeline", "--weights", weights, *store]]
        cases += [["window", "--days", "2", "--weights", weights, *store]]
    for path in special:
        cases += [
            ["run", path, *store],
            ["pipeline", path, *store],
            ["rendezvous", path],
            ["optimize", "x", path, *store],
            ["fly", path],
            ["fly", str(ws / "plan.json"), "--monte-carlo", "1", "--dispersions", path],
            ["export", path, "--format", "oem", "--out", str(ws / "out.oem")],
            ["export", str(ws / "plan.json"), "--format", "opm", "--out", path],
            ["target", path],
            ["run", "--target", path, *store],
            ["window", path, "--days", "2", *store],
            ["window", "--days", "2", "--target", path, *store],
        ]
    cases += [
        ["export", "plan.json", "--format", "a\nb", "--out", "../../x.oem"],
        ["target", str(ISS_TLE), "--epoch", "\x1b[31m\nyesterday"],
        ["run", "--runner", "a\nb", *store],
        ["window", "--days", "2", "--runner", "a\nb", *store],
        ["prune", "--only", "a\nb", *store],
    ]
    return cases


def test_hostile_ids_paths_and_numbers_end_in_one_line_exit_2(workspace, tmp_path, capsys):
    before = _outside(tmp_path, workspace)
    failures = []
    cases = _cases(workspace)
    previous = signal.signal(signal.SIGALRM, _hung)
    try:
        for args in cases:
            signal.alarm(CASE_LIMIT_S)
            try:
                code = run_command(list(args))
            except _Hung:
                code = None
            finally:
                signal.alarm(0)
            out, err = capsys.readouterr()
            lines = err.splitlines()
            if code != 2 or out or len(lines) != 1 or "Traceback" in err or "internal" in err:
                failures.append(
                    f"{args!r}: exit {code}, stdout {out[:200]!r}, stderr {err[:300]!r}"
                )
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert not failures, f"{len(failures)} of {len(cases)} cases:\n" + "\n".join(failures)
    assert _outside(tmp_path, workspace) == before  # nothing written outside the workspace
    assert not (tmp_path / "x").exists() and not (tmp_path / "x.oem").exists()
