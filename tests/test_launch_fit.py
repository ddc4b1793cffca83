"""Launch fit (patent 5.1) on the default grid, and the Prefect flow that solves it.

``data/reference/launch_fit/<scenario>/`` holds the default 21-point grid as the
flow solved it (``python -m flows.launch_fit``, ~4 min). The tests refit it, and
re-solve one grid point with the same task code from its stored neighbours, so the
stored data is checked against the code rather than trusted.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ovtraj.astro.epoch import Epoch
from ovtraj.launch.fourier import FourierRangeError
from ovtraj.launch.launch_fit import GRID_SCHEMA, LaunchFit, find_launch_fit, fit_rows
from ovtraj.launch.result import LaunchResult
from ovtraj.store.files import StoreError
from tests.conftest import REPO, replan_config

REFERENCE = REPO / "data" / "reference" / "launch_fit" / "iss-like-rendezvous"
# A launch row's wall times (the solve's and its phases'): the only columns that may differ
# between two solves of the same inputs.
WALL_TIMES = {"wall_time_s", "genetic_time_s", "slsqp_time_s", "trust_constr_time_s"}


@pytest.fixture(scope="module")
def grid_rows() -> list[dict]:
    return LaunchFit.load(REFERENCE).grid.to_dict(orient="records")  # every file checked


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


def test_reference_fit_lists_its_files_and_has_the_declared_schema(scenario):
    """meta.json (written last) gives the key and every file's size and SHA-256; the grid
    has the declared schema although whole columns are null (no genetic phase on it)."""
    meta = json.loads((REFERENCE / "meta.json").read_text())
    assert meta["key"] == json.loads((REFERENCE / "coefficients.json").read_text())["key"]
    assert set(meta["files"]) == {"coefficients.json", "grid.parquet"}
    for name, recorded in meta["files"].items():
        payload = (REFERENCE / name).read_bytes()
        assert recorded == {"bytes": len(payload), "sha256": hashlib.sha256(payload).hexdigest()}
    grid = pq.read_table(REFERENCE / "grid.parquet")
    assert grid.schema.equals(GRID_SCHEMA)
    assert grid.column("genetic_payload_kg").null_count == grid.num_rows
    assert grid.column("reason").null_count == grid.num_rows
    found = find_launch_fit(scenario)
    assert found is not None and found.key == meta["key"]


def test_a_changed_or_missing_file_of_a_stored_fit_is_refused_naming_it(scenario, tmp_path):
    root = tmp_path / "fits"
    directory = root / "copy"
    shutil.copytree(REFERENCE, directory)
    # One value rewritten in a still valid Parquet file.
    path = directory / "grid.parquet"
    original = path.read_bytes()
    table = pq.read_table(path)
    payload = table.column("payload_kg").to_pylist()
    payload[3] += 0.5
    index = table.schema.get_field_index("payload_kg")
    pq.write_table(table.set_column(index, "payload_kg", pa.array(payload)), path)
    with pytest.raises(StoreError, match=r"grid\.parquet: changed since it was stored"):
        LaunchFit.load(directory)
    with pytest.raises(StoreError, match=r"grid\.parquet: changed"):
        find_launch_fit(scenario, roots=(root,))  # never skipped as if it were absent
    path.write_bytes(original)
    (directory / "coefficients.json").unlink()
    with pytest.raises(StoreError, match=r"coefficients\.json: missing"):
        LaunchFit.load(directory)
    # Without its meta.json a fit is incomplete: not found, and a save completes it.
    shutil.copy(REFERENCE / "coefficients.json", directory)
    (directory / "meta.json").unlink()
    assert find_launch_fit(scenario, roots=(root,)) is None
    reference = LaunchFit.load(REFERENCE)
    reference.save(directory)
    assert find_launch_fit(scenario, roots=(root,)).to_dict() == reference.to_dict()


def test_a_stored_fit_is_never_overwritten(default_fit, tmp_path):
    first = default_fit.save(tmp_path / "fit")
    assert default_fit.save(tmp_path / "fit") == first  # the same fit again: nothing changes
    other = LaunchFit(
        series=default_fit.series,
        grid=default_fit.grid,
        launcher="another launcher",
        ridges=default_fit.ridges,
    )
    with pytest.raises(StoreError, match=r"already stored with other content"):
        other.save(tmp_path / "fit")
    assert LaunchFit.load(tmp_path / "fit").launcher == default_fit.launcher


def test_launch_row_nan_is_null():
    """LaunchResult.to_row uses ovtraj.store.records.plain: NaN (also numpy's) becomes None."""
    result = LaunchResult(
        feasible=False,
        reason="made up",
        target_altitude_m=3.0e5,
        opportunity="ascending",
        launch_day=Epoch.from_iso("2026-03-01T00:00:00"),
        payload_kg=np.float64(math.nan),
        speed_gain_mps=math.inf,
        design={"payload_kg": math.nan},
    )
    row = result.to_row()
    assert row["payload_kg"] is None and row["speed_gain_mps"] is None
    assert row["design_payload_kg"] is None and row["drop_epoch_utc"] is None
    json.dumps(row, allow_nan=False)


def test_stored_grid_point_is_what_the_task_computes(grid_rows, scenario):
    """Re-solve the second point of the upward chain from its two stored predecessors."""
    from tasks.launch import launch_point_task

    by_altitude = {row["target_altitude_km"]: row for row in grid_rows}
    reference_km = scenario.launch.target_altitude_km
    upward = sorted(h for h in by_altitude if h > reference_km)
    seed, point = upward[0], upward[1]
    row = launch_point_task.fn(scenario.resolved(), point, by_altitude[seed], None)
    # The stored chain had the reference optimum (not on the grid) before `seed`, so
    # the start differs slightly; the converged optimum must not.
    assert row["feasible"]
    assert row["payload_kg"] == pytest.approx(by_altitude[point]["payload_kg"], abs=0.15)


def test_a_launch_solve_is_the_same_whatever_the_process_blas_threads(tmp_path):
    """A process with two BLAS threads (a command's, by default on 2 cores) and one with one
    (a flow's tasks) store the same launch: with two, the solve's sums split differently and
    its optimum moved in the 7th digit (payload, flight time, design), so the command and
    the flow stored different fits of one grid."""
    from threadpoolctl import threadpool_limits

    from ovtraj.launch import launch_input, solve_launch
    from ovtraj.target_sources import load_scenario

    scenario = load_scenario(replan_config(tmp_path))  # the short launch search: ~1.5 s
    inp = launch_input(scenario, altitude_km=scenario.launch.fit.altitudes_km()[1])
    rows = {}
    for threads in (2, 1):
        with threadpool_limits(limits=threads, user_api="blas"):
            row = solve_launch(inp).to_row()
        rows[threads] = {k: v for k, v in row.items() if k not in WALL_TIMES}
    assert rows[2]["feasible"] and WALL_TIMES <= set(row)
    assert rows[2] == rows[1]


# The launch-fit flow (a small grid in parallel tasks, cached on re-run, recomputed after a
# code change) is tested in tests/test_caching.py, on the session's Prefect server.


def test_a_fit_travels_as_its_coefficients_and_predicts_the_same():
    """What a DoE batch carries to a worker with no fit on its disk."""
    reference = LaunchFit.load(REFERENCE)
    carried = LaunchFit.from_dict(json.loads(json.dumps(reference.to_dict())))
    low, high = reference.altitude_range_km
    for altitude_km in np.linspace(low, high, 7):
        assert carried.evaluate(altitude_km * 1e3) == reference.evaluate(altitude_km * 1e3)
    assert carried.key == reference.key and carried.launcher == reference.launcher
    with pytest.raises(ValueError, match="series"):
        LaunchFit.from_dict({"launcher": "x"})
