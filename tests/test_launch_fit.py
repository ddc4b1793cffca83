"""Launch fit (patent 5.1) on the default grid, and the Prefect flow that solves it.

``data/reference/launch_fit/<scenario>/`` holds the default 21-point grid as the
flow solved it (``python -m flows.launch_fit``, ~4 min). The tests refit it, and
re-solve one grid point with the same task code from its stored neighbours, so the
stored data is checked against the code rather than trusted.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest

from ovtraj.config import load_scenario
from ovtraj.launch.fit import LaunchFit, fit_rows
from ovtraj.launch.fourier import FourierRangeError
from ovtraj.version import code_version
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario

REFERENCE = REPO / "data" / "reference" / "launch_fit" / "iss-like-rendezvous"


@pytest.fixture(scope="module")
def grid_rows() -> list[dict]:
    frame = pd.read_parquet(REFERENCE / "grid.parquet")
    return frame.to_dict(orient="records")


@pytest.fixture(scope="module")
def default_fit(grid_rows, scenario) -> LaunchFit:
    return fit_rows(grid_rows, scenario.launch.fit, scenario.launch.launcher.name)


def test_reference_grid_is_the_configured_grid(grid_rows, scenario):
    altitudes = sorted(row["target_altitude_km"] for row in grid_rows)
    assert altitudes == pytest.approx(scenario.launch.fit.altitudes_km())
    assert all(row["feasible"] for row in grid_rows)


def test_payload_decreases_with_target_altitude_across_the_grid(grid_rows):
    ordered = sorted(grid_rows, key=lambda row: row["target_altitude_km"])
    payload = np.array([row["payload_kg"] for row in ordered])
    assert np.all(np.diff(payload) < 0.0)
    # One branch of optima, no jumps: the payload lost per grid step grows smoothly
    # with altitude (1.0 kg at 200 km, 4.2 kg at 500 km); a point on another branch
    # or a badly converged one shows as a negative second difference.
    steps = -np.diff(payload)
    assert np.all(np.diff(steps) > -0.05)


def test_leave_one_out_error_below_one_percent_of_the_payload_range(default_fit):
    assert default_fit.loo_relative_error("payload_kg") < 0.01
    for name in ("insertion_time_s", "insertion_u_deg"):
        assert np.isfinite(default_fit.series[name].loo_max_error)


def test_fit_reproduces_the_grid_and_refuses_to_extrapolate(default_fit, grid_rows, tmp_path):
    default_fit.save(tmp_path)
    loaded = LaunchFit.load(tmp_path)
    for row in grid_rows:
        h = row["target_altitude_km"] * 1e3
        fitted = loaded.evaluate(h)
        assert fitted["payload_kg"] == pytest.approx(row["payload_kg"], abs=0.1)
        assert fitted["insertion_time_s"] == pytest.approx(row["insertion_time_s"], abs=3.0)
        du = (fitted["insertion_u_deg"] - row["insertion_u_deg"] + 180.0) % 360.0 - 180.0
        assert abs(du) < 0.2
    lo, hi = loaded.altitude_range_km
    with pytest.raises(FourierRangeError, match="payload_kg"):
        loaded.evaluate((hi + 1.0) * 1e3)
    with pytest.raises(FourierRangeError):
        loaded.evaluate((lo - 1.0) * 1e3)


def test_stored_grid_point_is_what_the_task_computes(grid_rows, scenario):
    """Re-solve the second point of the upward chain from its two stored predecessors."""
    from tasks.launch import launch_point_task

    by_altitude = {row["target_altitude_km"]: row for row in grid_rows}
    reference_km = scenario.launch.target_altitude_km
    upward = sorted(h for h in by_altitude if h > reference_km)
    seed, point = upward[0], upward[1]
    row = launch_point_task.fn(
        scenario.resolved(), point, by_altitude[seed], None, code=code_version()
    )
    # The stored chain had the reference optimum (not on the grid) before `seed`, so
    # the start differs slightly; the converged optimum must not.
    assert row["feasible"]
    assert row["payload_kg"] == pytest.approx(by_altitude[point]["payload_kg"], abs=0.15)


# -- the flow: a small grid, solved in parallel tasks, cached on re-run -------------------


def _small_grid_scenario_data() -> dict:
    import yaml

    data = copy.deepcopy(yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8")))
    data["name"] = "launch-fit-flow-test"
    data["launch"]["fit"].update(
        {"altitude_min_km": 285.0, "altitude_max_km": 315.0, "points": 5, "order": 1}
    )
    data.pop("mission")  # its design bounds need the full fit range
    return data


def test_launch_fit_flow_runs_the_grid_in_parallel_and_caches_every_point(tmp_path):
    import yaml
    from prefect.settings import PREFECT_LOCAL_STORAGE_PATH, temporary_settings
    from prefect.testing.utilities import prefect_test_harness

    from flows.launch_fit import launch_fit_flow

    data = _small_grid_scenario_data()
    # The launcher file is relative to configs/: point at the repository's copy.
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    build_scenario(data)  # valid
    config = tmp_path / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    storage = tmp_path / "results"
    with (
        temporary_settings(updates={PREFECT_LOCAL_STORAGE_PATH: storage}),
        prefect_test_harness(server_startup_timeout=60),
    ):
        first = launch_fit_flow(str(config), output_dir=str(tmp_path / "fit"))
        second = launch_fit_flow(str(config), output_dir=str(tmp_path / "fit2"))
    assert first["points"] == 5
    assert first["cached_points"] == 0
    assert second["cached_points"] == second["solved_points"] == first["solved_points"]
    assert second["payload_kg"] == first["payload_kg"]
    payload = np.array(first["payload_kg"])
    assert np.all(np.diff(payload) < 0.0)
    fit = LaunchFit.load(tmp_path / "fit")
    assert fit.altitude_range_km == pytest.approx((285.0, 315.0))
    scenario = load_scenario(config)
    assert fit.launcher == scenario.launch.launcher.name
