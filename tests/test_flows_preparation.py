"""One preparation for ``ovtraj pipeline`` and the mission flow
(``ovtraj/pipeline/prepare.py``): given the same options and parameters, both hand the
driver the same scenario, launch fit, run store, runner and request, in each case of the
launch fit: stored; missing and refused (configs/orchestration.yaml
``preparation.launch_fit: require``, the same one line from both); missing and solved
first (``fit``: the command in its process, the flow as the launch-fit subflow, the same
fit). The driver is replaced by one that records what it is given and stops there (the
pipeline itself: tests/test_pipeline_flow.py).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

import flows.pipeline
from ovtraj.cli import run_command
from ovtraj.launch.launch_fit import LaunchFit, find_launch_fit
from ovtraj.pipeline import drive
from ovtraj.runs.preparation import LaunchFitMissing
from ovtraj.target_sources import load_scenario
from tests.conftest import DEFAULT_SCENARIO, REPO, replan_config

TARGET = REPO / "configs" / "targets" / "iss-like-2026-12-01.tle"


class Recorded(Exception):
    """The recording driver has what it was given: the pipeline stops there."""


@pytest.fixture
def driven(monkeypatch):
    """The driver of the command and of the flow replaced: each call records its inputs
    (the launch fit as its coefficients, the store as its root) and stops."""
    given = []

    def driver(scenario, launch_fit, store, code, executor, request, **_):
        given.append(
            {
                "scenario": scenario.resolved(),
                "launch_fit": launch_fit.to_dict(),
                "store": str(store.root),
                "choice": executor.choice,
                "request": request,
            }
        )
        raise Recorded(f"the inputs of {scenario.name} recorded")

    monkeypatch.setattr(drive, "drive_pipeline", driver)
    monkeypatch.setattr(flows.pipeline, "drive_pipeline", driver)
    return given


@pytest.fixture
def launch_fit_setting(tmp_path, monkeypatch):
    """A copy of configs/ as OVTRAJ_CONFIG_DIR and a workspace of the test's own (no
    launch fit solved in it yet); returns a function setting the copy's
    ``preparation.launch_fit``."""
    copied = tmp_path / "configs"
    shutil.copytree(REPO / "configs", copied)
    monkeypatch.setenv("OVTRAJ_CONFIG_DIR", str(copied))
    monkeypatch.setenv("OVTRAJ_HOME", str(tmp_path / "home"))

    def setting(value: str) -> None:
        path = copied / "orchestration.yaml"
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        data["preparation"]["launch_fit"] = value
        path.write_text(yaml.safe_dump(data), encoding="utf-8")

    return setting


def _both(config: Path, store: Path, *options: str, **parameters):
    """``ovtraj pipeline CONFIG --store STORE OPTIONS --json`` and the mission flow with
    the same ``parameters``: the command's exit code, its stderr lines and the flow's
    final state."""
    from flows.pipeline import mission_flow

    code = run_command(["pipeline", str(config), "--store", str(store), *options, "--json"])
    state = mission_flow(config=str(config), store=str(store), return_state=True, **parameters)
    return code, state


def test_a_stored_launch_fit_gives_both_the_same_inputs(
    prefect_server, launch_fit_setting, driven, tmp_path, capsys
):
    launch_fit_setting("require")  # the shipped scenario's fit is shipped: nothing to solve
    store = tmp_path / "runs"
    options = ["--samples", "6", "--seed", "3", "--runner", "threads", "--workers", "2"]
    options += ["--weights", "1,2,1", "--max-dv-mps", "300", "--refit"]
    code, state = _both(
        DEFAULT_SCENARIO,
        store,
        *options,
        samples=6,
        seed=3,
        runner="threads",
        workers=2,
        weights=[1.0, 2.0, 1.0],
        max_dv_mps=300.0,
        refit=True,
    )
    assert code == 2 and "Recorded" in capsys.readouterr().err  # stopped in the driver
    assert state.is_failed()
    command, flow = driven
    assert command == flow
    shipped = find_launch_fit(load_scenario(DEFAULT_SCENARIO))
    assert flow["launch_fit"] == shipped.to_dict()
    assert flow["store"] == str(store.resolve())
    assert (flow["choice"].runner, flow["choice"].workers) == ("threads", 2)
    request = flow["request"]
    assert (request.samples, request.seed, request.refit) == (6, 3, True)
    assert request.config == DEFAULT_SCENARIO
    assert (request.pick.weights, request.pick.max_dv_total_mps) == ((1.0, 2.0, 1.0), 300.0)


def test_a_missing_launch_fit_refused_by_both_in_the_same_line(
    prefect_server, launch_fit_setting, driven, tmp_path, capsys
):
    launch_fit_setting("require")
    store = tmp_path / "runs"
    code, state = _both(DEFAULT_SCENARIO, store, "--target", str(TARGET), target=str(TARGET))
    (line,) = capsys.readouterr().err.splitlines()
    assert code == 2 and state.is_failed() and driven == []
    refused = state.result(raise_on_failure=False)
    assert isinstance(refused, LaunchFitMissing) and str(refused) == line
    assert line.startswith("no launch fit for this scenario") and f"--target {TARGET}" in line
    assert "preparation.launch_fit: require" in line
    assert not (tmp_path / "home" / "launch_fit").exists()  # nothing solved
    assert not store.exists()  # nothing stored


@pytest.mark.slow
def test_a_missing_launch_fit_solved_first_by_both_the_same(
    prefect_server, launch_fit_setting, driven, tmp_path, monkeypatch, capsys
):
    """``fit``: the command solves the grid in its process, the flow runs the launch-fit
    flow as its subflow, each into a workspace of its own: the same fit, stored under its
    key where the next run finds it, and the same inputs."""
    from flows.pipeline import mission_flow

    launch_fit_setting("fit")
    config = replan_config(tmp_path)  # a five-point launch grid: ~1 min, not ~4
    scenario = load_scenario(config)
    store = tmp_path / "runs"
    homes = {"command": tmp_path / "command-home", "flow": tmp_path / "flow-home"}
    monkeypatch.setenv("OVTRAJ_HOME", str(homes["command"]))
    assert find_launch_fit(scenario) is None
    code = run_command(["pipeline", str(config), "--store", str(store), "--json"])
    assert code == 2 and "Recorded" in capsys.readouterr().err
    monkeypatch.setenv("OVTRAJ_HOME", str(homes["flow"]))
    assert find_launch_fit(scenario) is None
    state = mission_flow(config=str(config), store=str(store), return_state=True)
    assert state.is_failed() and isinstance(state.result(raise_on_failure=False), Recorded)
    command, flow = driven
    assert command == flow
    for home in homes.values():
        stored = LaunchFit.load(home / "launch_fit" / LaunchFit.from_dict(flow["launch_fit"]).key)
        assert stored.to_dict() == flow["launch_fit"]
