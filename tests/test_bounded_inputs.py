"""Bounded inputs against hostile files and values: YAML anchors and aliases refused, config
files read only if regular and within ``config_file_max_kib``, echoed values cut, ``--weights``
finite, and a DoE refused when the free disk is below its estimated size.

Real files, a real FIFO and ``/dev/zero``; the commands run in this process through
:func:`ovtraj.cli.run_command` (the entry point's body), except the FIFO and
``/dev/zero`` cases: a subprocess with a time-out, so that a hang or an exhausted memory
fails the test instead of the suite.
"""

from __future__ import annotations

import logging
import math
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from ovtraj.cli import run_command
from ovtraj.config import ConfigError
from ovtraj.config.base import load_model
from ovtraj.config.export import CcsdsExportSettings
from ovtraj.config.io_limits import io_limits
from ovtraj.config.physical import load_earth
from ovtraj.config.target import default_source_settings
from ovtraj.mission.plan import PlanError
from ovtraj.mission.plan_store import read_plan
from ovtraj.optimize import Normalisation
from ovtraj.pipeline import Pick, PipelineError, pick_front_point
from ovtraj.runs import RunStore
from ovtraj.runs.execute import check_free_disk
from ovtraj.target_sources import load_scenario, read_source
from tests.conftest import DEFAULT_SCENARIO, REPO

OVTRAJ = Path(sys.executable).with_name("ovtraj")
ISS_TLE = REPO / "tests" / "data" / "targets" / "iss_2019-12-09.tle"


def _one_line(capsys) -> str:
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err
    (line,) = err.splitlines()
    return line


# --------------------------------------------------------------------------- #
# YAML anchors and aliases
# --------------------------------------------------------------------------- #
def _alias_bomb(path: Path, levels: int) -> Path:
    """The shipped scenario (33 kB) with ``name`` holding ``levels`` levels of ten
    aliases each: 10^levels leaves. Seven levels keep the old code's failure bounded
    (2.5 s and an 80 MB error line measured); ten never ended."""
    bomb = ['  - &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    bomb += [f"  - &a{k} [{', '.join([f'*a{k - 1}'] * 10)}]" for k in range(1, levels)]
    lines = DEFAULT_SCENARIO.read_text(encoding="utf-8").splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("name:"))
    path.write_text("\n".join([*lines[:at], "name:", *bomb, *lines[at + 1 :]]), encoding="utf-8")
    return path


def test_an_alias_bomb_ends_in_under_a_second_in_one_short_line(tmp_path, capsys):
    bomb = _alias_bomb(tmp_path / "bomb.yaml", levels=7)
    run_command(["run", str(tmp_path / "missing.yaml")])  # the command's imports, once
    capsys.readouterr()
    start = time.monotonic()
    code = run_command(["run", str(bomb), "--store", str(tmp_path / "store")])
    elapsed = time.monotonic() - start
    line = _one_line(capsys)
    assert code == 2 and elapsed < 1.0 and len(line) < 300
    at = 1 + next(i for i, t in enumerate(bomb.read_text().splitlines()) if "&a0" in t)
    assert line == (
        f"invalid configuration in {bomb}: not valid YAML: line {at}, column 5: YAML anchors "
        "and aliases (&name, *name) are not accepted; write the values out"
    )


def test_a_plan_with_an_anchor_is_refused_naming_the_file(tmp_path):
    plan = tmp_path / "plan.yaml"
    plan.write_text("schema_version: &v 1\nagain: *v\n", encoding="utf-8")
    with pytest.raises(PlanError, match=r"plan\.yaml: not valid YAML: line 1, column 17: YAML"):
        read_plan(plan)


def test_a_yaml_syntax_error_is_one_line(tmp_path, capsys):
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [a\nb: 1\n", encoding="utf-8")
    assert run_command(["run", str(broken)]) == 2
    assert _one_line(capsys) == (
        f"invalid configuration in {broken}: not valid YAML: line 2, column 2: while parsing "
        "a flow sequence; did not find expected ',' or ']'"
    )


# --------------------------------------------------------------------------- #
# Only regular files, within their size cap
# --------------------------------------------------------------------------- #
def _limit_memory() -> None:
    """The child's address space: 4 GiB, so that reading /dev/zero to the end (the old
    code) fails in seconds instead of taking the machine's memory."""
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


@pytest.mark.parametrize("kind", ["/dev/zero", "FIFO"])
def test_dev_zero_and_a_fifo_as_the_config_path_end_in_one_line(kind, tmp_path):
    if kind == "FIFO":
        path = tmp_path / "scenario.yaml"
        os.mkfifo(path)  # no writer ever opens it: reading it would wait forever
        what = "a FIFO"
    else:
        path, what = Path(kind), "a character device"
    done = subprocess.run(
        [OVTRAJ, "run", str(path), "--store", str(tmp_path / "store")],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_limit_memory,
    )
    assert (done.returncode, done.stdout) == (2, "")
    assert done.stderr.splitlines() == [
        f"invalid configuration in {path}: not a regular file ({what})"
    ]
    assert not (tmp_path / "store").exists()


def _readers(tmp_path: Path) -> dict:
    """Every reader of a config, scenario, launcher, plan or element-set file, each
    given ``path`` (a launcher through a scenario that names it)."""

    def launcher(path: Path) -> None:
        data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
        data["launch"]["launcher"] = str(path)
        scenario = tmp_path / "with_launcher.yaml"
        scenario.write_text(yaml.safe_dump(data), encoding="utf-8")
        load_scenario(scenario)

    return {
        "scenario": load_scenario,
        "export settings": lambda path: load_model(CcsdsExportSettings, path),
        "Earth model": load_earth,
        "launcher": launcher,
        "plan": read_plan,
        "TLE file": lambda path: read_source(path, settings=default_source_settings()),
    }


def test_every_reader_refuses_a_directory_and_a_file_over_its_cap(tmp_path):
    folder = tmp_path / "folder.json"
    folder.mkdir()
    limits = io_limits()
    big = tmp_path / "big.json"  # comment lines: valid YAML, a byte over the cap
    line = b"#" * 63 + b"\n"
    big.write_bytes(line * (limits.config_file_max_bytes // len(line) + 1))
    small_cap = {**default_source_settings().model_dump(), "url_max_mib": 1e-4}
    for name, read in _readers(tmp_path).items():
        with pytest.raises((ConfigError, PlanError, ValueError)) as caught:
            read(folder)
        assert "not a regular file (a directory)" in str(caught.value), name
        if name == "TLE file":
            with pytest.raises(ConfigError, match=r"larger than url_max_mib = 0\.0001 MiB"):
                read_source(ISS_TLE, settings=type(default_source_settings())(**small_cap))
            continue
        with pytest.raises((ConfigError, PlanError, ValueError)) as caught:
            read(big)
        assert f"B: larger than config_file_max_kib = {limits.config_file_max_kib:g} KiB" in str(
            caught.value
        ), name


def test_an_echoed_value_is_cut_to_one_short_line(tmp_path, monkeypatch, capsys):
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["vehicle"]["mass_kg"] = "9" * 5000 + "\n\x1b[31m" + "kg"
    (tmp_path / "long.yaml").write_text(yaml.safe_dump(data), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert run_command(["run", "long.yaml"]) == 2
    line = _one_line(capsys)
    head = "invalid configuration in long.yaml: vehicle.mass_kg = "
    tail = ": Input should be a valid number, unable to parse string as a number"
    assert line.startswith(head + "'9999") and tail in line and len(line) < 300
    shown = line[len(head) : line.index(tail)]
    assert len(shown) == io_limits().echo_max_chars
    assert "999...999" in shown and shown.endswith("999\\n\\x1b[31mkg'")


# --------------------------------------------------------------------------- #
# --weights
# --------------------------------------------------------------------------- #
def test_weights_are_finite_non_negative_and_not_all_zero(scenario, tmp_path, capsys):
    norm = Normalisation.mission(scenario.mission.optimize)
    front = pd.DataFrame(
        {
            "front_index": [0, 1],
            "sample_id": [7, 3],
            "t_total_s": [260000.0, 340000.0],
            "dv_total_mps": [290.0, 230.0],
            "m_load_kg": [409.0, 400.0],
        }
    )
    with pytest.raises(PipelineError, match=r"weights \(nan, 1.0, 1.0\): every weight must be"):
        pick_front_point(front, norm, Pick(weights=(math.nan, 1.0, 1.0)))
    with pytest.raises(PipelineError, match="every weight must be a finite number"):
        pick_front_point(front, norm, Pick(weights=(math.inf, 1.0, 1.0)))
    # the command refuses them before it opens the run: one line naming --weights
    store = ["--store", str(tmp_path)]
    assert run_command(["plan", "0123456789abcdef", "--weights", "nan,1,1", *store]) == 2
    assert _one_line(capsys) == "--weights 'nan,1,1': every weight must be a finite number"
    assert run_command(["plan", "0123456789abcdef", "--max-dv-mps", "inf", *store]) == 2
    assert _one_line(capsys) == "--max-dv-mps inf: must be a finite number"


# --------------------------------------------------------------------------- #
# A DoE larger than the free disk
# --------------------------------------------------------------------------- #
@pytest.fixture
def config_copy(tmp_path, monkeypatch):
    """A copy of configs/ as OVTRAJ_CONFIG_DIR; returns a function changing a figure of
    its io_limits.yaml (read again: the cached limits are cleared, now and after)."""
    copied = tmp_path / "configs"
    shutil.copytree(REPO / "configs", copied)
    monkeypatch.setenv("OVTRAJ_CONFIG_DIR", str(copied))
    io_limits.cache_clear()

    def change(key: str, value: float) -> None:
        data = yaml.safe_load((copied / "io_limits.yaml").read_text(encoding="utf-8"))
        (copied / "io_limits.yaml").write_text(yaml.safe_dump({**data, key: value}))
        io_limits.cache_clear()

    yield change
    io_limits.cache_clear()


def test_a_doe_above_the_free_disk_is_refused_before_it_writes(config_copy, tmp_path, capsys):
    store = tmp_path / "store"
    free = shutil.disk_usage(tmp_path).free
    config_copy("doe_bytes_per_sample", float(free))  # 4 samples: four times the free disk
    code = run_command(["run", "--samples", "4", "--store", str(store)])
    line = _one_line(capsys)
    assert code == 2
    assert (
        line.startswith(f"{store}: a DoE of 4 samples takes ~") and "GiB free on its disk" in line
    )
    assert not store.exists()  # not a byte written


def test_a_large_doe_says_its_estimate(config_copy, tmp_path, caplog):
    config_copy("doe_estimate_shown_gib", 0.0)
    with caplog.at_level(logging.INFO, logger="ovtraj.runs.execute"):
        check_free_disk(RunStore(tmp_path / "store"), 100)
    (record,) = caplog.records
    assert record.getMessage().startswith(f"a DoE of 100 samples: ~8.23 MiB in {tmp_path}")
