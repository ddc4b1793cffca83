"""docs/tutorial.md: its commands run, in order, as tools/tutorial.py runs them to write
the page, on short settings: the nightly re-plan's short scenario (tests/conftest.py
``replan_config``) and a Monte Carlo of 4 runs instead of the page's 20; with a real
Prefect server and process worker, a real Dask scheduler and workers and a moto S3
server, each started on 127.0.0.1 and stopped by its process group's id. And the page
shows what its steps ran: each console block's command is its step's command with the
captured values and ports filled in, followed by output.

Where the run's time goes (a few minutes): four pipelines (two on the command line, one
in the deployment's flow run, one on Dask and S3) with their launch fits, the plan and
its flights, and the services' start-ups. Against the page's own run it saves what is
not under test: heyoka's compiled code comes from the suite's disk cache (not the
temporary HOME's empty one), the Prefect worker asks for work every second, the
Monte Carlo flies 4 runs."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import heyoka as hy
import pytest

from tests.conftest import REPO, replan_config

pytestmark = pytest.mark.slow


def _tool():
    spec = importlib.util.spec_from_file_location("tutorial_tool", REPO / "tools" / "tutorial.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


tutorial = _tool()
TEXT = tutorial.TUTORIAL.read_text(encoding="utf-8")
STEPS = tutorial.steps(TEXT)


def test_the_tutorial_covers_the_analysts_path():
    commands = " ".join(step.run for step in STEPS)
    for needed in (
        "ovtraj pipeline configs/scenario.yaml",
        "ovtraj front",
        "ovtraj plan",
        "--weights",
        "ovtraj fly",
        "--fidelity high",
        "--monte-carlo",
        "ovtraj runs",
        "ovtraj export",
        "ovtraj lineage",
        "prefect deployment run mission/mission-replan",
        "ovtraj history",
        "ovtraj diff",
        "--runner dask",
        "--store s3://",
    ):
        assert needed in commands, f"docs/tutorial.md: no step runs {needed!r}"


def _pattern(template: str) -> str:
    """A step's command as a regular expression: each ``{name}`` any non-blank word."""
    parts = re.split(r"\{[a-z_0-9]+\}", template)
    return r"\S+".join(re.escape(part) for part in parts)


def test_every_console_block_shows_its_steps_command():
    blocks = list(tutorial.STEP.finditer(TEXT))
    assert len(blocks) == len(STEPS) > 20
    for step, block in zip(STEPS, blocks, strict=True):
        shown = block["shown"].splitlines()
        assert shown, f"{step.run}: the page shows nothing (run tools/tutorial.py)"
        assert re.fullmatch(r"\$ " + _pattern(step.run), shown[0]), (shown[0], step.run)
        if not (step.export or step.service or step.tail == 0):
            assert len(shown) > 1, f"{step.run}: no output shown"


MONTE_CARLO_RUNS = 4  # of the page's 20: each run flies the same code (~1 s each here)


def short_steps(steps: list) -> list:
    """The page's steps with the Monte Carlo on ``MONTE_CARLO_RUNS`` runs (its one short
    setting that is not the scenario's); every other command as the page runs it."""
    page, short = "--monte-carlo 20 ", f"--monte-carlo {MONTE_CARLO_RUNS} "
    changed = [step for step in steps if page in step.run]
    assert len(changed) == 1, [step.run for step in changed]
    return [
        dataclasses.replace(step, run=step.run.replace(page, short)) if step in changed else step
        for step in steps
    ]


def test_the_tutorial_runs_on_short_settings(tmp_path):
    scenario = replan_config(tmp_path)
    checkout, env = tutorial.prepare(tmp_path / "work", scenario)
    # heyoka's compiled code from this process's disk cache (the rest of the suite's), not
    # the temporary HOME's empty one: the page shows a first run's times, this test checks
    # the steps and their outputs, and a cold build of a model takes seconds to a minute.
    env["XDG_CACHE_HOME"] = str(Path(hy.llvm_state.get_diskcache_path()).parent)
    # The process worker asks for scheduled runs every second, not every 10 s (Prefect's
    # default): the deployment's run starts as soon as it is asked for.
    env["PREFECT_WORKER_QUERY_SECONDS"] = "1"
    # The short scenario's launch fit (the shipped one serves only the shipped launch).
    fit = subprocess.run(
        [str(Path(sys.executable).with_name("ovtraj")), "launch-fit", "configs/scenario.yaml"],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert fit.returncode == 0, fit.stderr[-2000:]
    ports = {name: tutorial._free_port() for name in tutorial.DEFAULT_PORTS}
    results = tutorial.run_steps(short_steps(STEPS), checkout, env, ports, unconverged_ok=True)
    assert len(results) == len(STEPS)
    shown = dict(results)
    # what the analyst is told to look at is there
    pipeline = next(out for command, out in results if command.startswith("ovtraj pipeline"))
    assert re.search(r"^(converged|not converged)", pipeline, re.M)
    assert (checkout / "plan.oem").is_file()
    history = next(out for command, out in shown.items() if command == "ovtraj history")
    assert "2026-11-30" in history and "2026-12-01" in history
    # the Dask run on S3 is the serial run: the same DoE run id
    runs = re.findall(r"runs/([0-9a-f]{16})/pipeline/", pipeline)
    dask = next(out for command, out in results if "--runner dask" in command)
    assert runs and runs[0] in dask
