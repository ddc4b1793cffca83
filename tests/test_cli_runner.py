"""tests/cli_runner.py's in-process command answers as the installed command does.

Each command line runs twice, as the ``ovtraj`` command in a subprocess and through
:func:`tests.cli_runner.run_cli` in this process, on the same store: the exit code, stdout
and stderr must be equal, for a JSON answer, a rich table, a usage error, a store error
(exit 2), a failed check (exit 1) and an environment variable given to the command.
Then the state the helper sets for a run is back as it was.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli_runner import run_cli
from tests.conftest import DEFAULT_SCENARIO

OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))


def _both(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    real = subprocess.run(
        [OVTRAJ, *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env=None if env is None else os.environ | env,
    )
    here = run_cli(*args, env=env)
    assert (here.returncode, here.stdout, here.stderr) == (
        real.returncode,
        real.stdout,
        real.stderr,
    ), args
    return here


def test_a_command_in_this_process_answers_as_the_installed_command(tmp_path):
    store = str(tmp_path / "runs")
    made = run_cli("run", str(DEFAULT_SCENARIO), "--samples", "1", "--store", store, "--json")
    assert made.returncode == 0, made.stderr
    run_id = json.loads(made.stdout)["run_id"]
    assert json.loads(_both("verify", run_id, "--store", store, "--json").stdout)["clean"]
    assert run_id in _both("runs", "--store", store).stdout  # a rich table on stdout
    assert _both("run", "--samples", "0", "--store", store).returncode == 2  # usage error
    assert _both("replay", "0123456789abcdef", "--store", store).returncode == 2
    home = str(tmp_path / "home")
    paths = json.loads(_both("paths", "--json", env={"OVTRAJ_HOME": home}).stdout)
    assert paths["workspace"] == home and os.environ.get("OVTRAJ_HOME") != home
    (totals,) = (tmp_path / "runs" / run_id / "totals").glob("part-*.parquet")
    os.chmod(totals, 0o644)
    totals.write_bytes(totals.read_bytes() + b"\0")
    assert _both("verify", run_id, "--store", store).returncode == 1


def test_the_helper_restores_what_it_sets(tmp_path):
    logger = logging.getLogger("ovtraj")
    before = (list(logger.handlers), logger.level, Path.cwd(), dict(os.environ))
    out, err = sys.stdout, sys.stderr
    done = run_cli("-q", "paths", "--json", env={"OVTRAJ_HOME": str(tmp_path)}, cwd=tmp_path)
    assert done.returncode == 0 and json.loads(done.stdout)["workspace"] == str(tmp_path)
    assert (list(logger.handlers), logger.level, Path.cwd(), dict(os.environ)) == before
    assert (sys.stdout, sys.stderr) == (out, err)
    with pytest.raises(ValueError, match="OVTRAJ_CONFIG_DIR"):
        run_cli("paths", env={"OVTRAJ_CONFIG_DIR": str(tmp_path)})
