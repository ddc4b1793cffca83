"""The re-plan: a target source as a parameter, runs that share samples."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

from ovtraj.launch.launch_fit import find_launch_fit, launch_fit_key
from ovtraj.runs import RunStore, execute, prepare_run, run_doe
from ovtraj.runs.ids import run_id
from ovtraj.target_sources import load_scenario, load_scenario_with_target
from tests.conftest import DEFAULT_SCENARIO, REPO

EXAMPLE_TLE = REPO / "configs" / "targets" / "iss-like-2026-12-01.tle"
OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))


def test_a_target_source_replaces_the_target_and_keys_new_results(scenario):
    replanned = load_scenario_with_target(DEFAULT_SCENARIO, str(EXAMPLE_TLE))
    target = replanned.resolved()["target"]
    lines = EXAMPLE_TLE.read_text(encoding="utf-8").splitlines()
    assert target["tle"][-2:] == lines[-2:]  # the element set itself, not the file name
    assert "orbit" not in target and str(EXAMPLE_TLE) not in json.dumps(target)
    samples = pd.DataFrame({"sample_id": [0], "parking_altitude_km": [300.0]})
    before = run_id(scenario.resolved(), 1, samples, "v", None)
    after = run_id(replanned.resolved(), 1, samples, "v", None)
    assert before != after and launch_fit_key(scenario) != launch_fit_key(replanned)
    # Everything else is the scenario's own.
    for key in ("vehicle", "rendezvous", "deorbit", "reentry", "mission"):
        assert replanned.resolved()[key] == scenario.resolved()[key]
    # The same element set again: the same scenario, so every stored result is reused.
    again = load_scenario_with_target(DEFAULT_SCENARIO, str(EXAMPLE_TLE))
    assert again.resolved() == replanned.resolved()
    assert load_scenario_with_target(DEFAULT_SCENARIO, None) == load_scenario(DEFAULT_SCENARIO)


def test_the_example_tle_is_the_default_targets_orbit(scenario):
    """tools/example_tle.py fitted SGP4 to the hand-typed target at the epoch."""
    import numpy as np

    from ovtraj.target_state import target_state

    replanned = load_scenario_with_target(DEFAULT_SCENARIO, str(EXAMPLE_TLE))
    typed = target_state(scenario.target.orbit, scenario)
    from_tle = target_state(replanned.target.orbit, replanned)
    # The TLE's 7-8 significant digits and our J2 fit to SGP4 over a day (rms ~0.2 km).
    assert np.linalg.norm(from_tle[:3] - typed[:3]) < 1.0e3
    assert np.linalg.norm(from_tle[3:] - typed[3:]) < 1.0


def test_a_larger_doe_extends_the_stored_one_instead_of_drawing_another(tmp_path, scenario):
    store = RunStore(tmp_path)
    fit = find_launch_fit(scenario)
    nightly = prepare_run(scenario, samples=2, seed=5, code="test", store=store)
    run_doe(scenario, nightly, fit, batch_size=2)
    before = execute.EVALUATIONS["count"]
    replan = prepare_run(scenario, samples=4, seed=5, code="test", store=store)
    assert replan.manifest["parent"] == nightly.id and replan.manifest["inherited_batches"] == 1
    pd.testing.assert_frame_equal(replan.samples().iloc[:2], nightly.samples())
    run_doe(scenario, replan, fit, batch_size=2)
    assert execute.EVALUATIONS["count"] - before == 2  # only the two new samples
    # Both sizes are reopened, not drawn again; another seed is another hypercube.
    assert prepare_run(scenario, samples=4, seed=5, code="test", store=store).id == replan.id
    assert prepare_run(scenario, samples=2, seed=5, code="test", store=store).id == nightly.id
    other = prepare_run(scenario, samples=4, seed=6, code="test", store=store)
    assert other.manifest["parent"] is None and other.id not in (nightly.id, replan.id)


def test_a_target_without_a_launch_fit_is_one_line_naming_what_to_run(tmp_path):
    """With configs/orchestration.yaml ``preparation.launch_fit: require`` (the shipped
    ``fit`` solves it first: tests/test_flows_preparation.py)."""
    configs = tmp_path / "configs"
    shutil.copytree(REPO / "configs", configs)
    settings = yaml.safe_load((configs / "orchestration.yaml").read_text(encoding="utf-8"))
    settings["preparation"]["launch_fit"] = "require"
    (configs / "orchestration.yaml").write_text(yaml.safe_dump(settings), encoding="utf-8")
    done = subprocess.run(
        [OVTRAJ, "run", "--target", str(EXAMPLE_TLE), "--samples", "2", "--store", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={
            "OVTRAJ_HOME": str(tmp_path / "home"),
            "OVTRAJ_CONFIG_DIR": str(configs),
            "PATH": "/usr/bin:/bin",
        },
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert "no launch fit for this scenario" in line and "launch-fit" in line
