"""Air-launch stage: configuration checks, the optimised ascent, the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.config import ConfigError
from ovtraj.launch import launch_input, solve_launch
from ovtraj.launch.ascent_optimization import Standing, is_better
from ovtraj.launch.launch_fit import design_of
from ovtraj.launch.stage import insertion_time_s, nominal_azimuth_rad
from tests.conftest import REPO, build_scenario

LAUNCH_KEYS = {
    "payload_kg",
    "insertion_altitude_error_m",
    "insertion_speed_error_mps",
    "insertion_fpa_error_deg",
    "inclination_error_deg",
    "insertion_time_s",
    "insertion_u_deg",
    "max_dynamic_pressure_pa",
    "feasible",
}


def _with_launcher(data: dict, edit: callable) -> dict:
    launcher = yaml.safe_load((REPO / "configs" / "launchers" / "pegasus_xl.yaml").read_text())
    edit(launcher)
    data["launch"]["launcher"] = launcher
    return data


# -- configuration: impossible figures are refused with the field named -------------------


def test_thrust_below_weight_is_refused(scenario_data):
    def weak_first_stage(launcher):
        launcher["stages"][0]["vacuum_thrust_n"] = 150000.0  # < 23 t * g0
        launcher["stages"][0]["burn_time_s"] = 15000.0 * 295 * 9.80665 / 150000.0

    with pytest.raises(ConfigError, match=r"stages\[1\].*does not exceed the weight"):
        build_scenario(_with_launcher(scenario_data, weak_first_stage))


def test_burn_time_inconsistent_with_propellant_thrust_isp_is_refused(scenario_data):
    def long_burn(launcher):
        launcher["stages"][1]["burn_time_s"] = 80.0  # 69.1 s implied: 16 % off

    with pytest.raises(ConfigError, match=r"stages\[2\].*burn_time_s 80.*allowed 5 %"):
        build_scenario(_with_launcher(scenario_data, long_burn))


def test_target_altitude_below_150_km_is_refused(scenario_data):
    scenario_data["launch"]["target_altitude_km"] = 120.0
    with pytest.raises(ConfigError, match=r"launch.target_altitude_km.*allowed \[150, 2000\]"):
        build_scenario(scenario_data)
    scenario_data["launch"]["target_altitude_km"] = 300.0
    scenario_data["launch"]["fit"]["altitude_min_km"] = 100.0
    with pytest.raises(ConfigError, match=r"altitude_min_km.*allowed \[150"):
        build_scenario(scenario_data)


def test_unreachable_plane_is_infeasible_not_an_exception(scenario_data):
    scenario_data["target"]["orbit"]["inclination_deg"] = 20.0  # below the 28 deg drop latitude
    result = solve_launch(launch_input(build_scenario(scenario_data)))
    assert result.feasible is False
    assert "never passes over the drop latitude" in result.reason
    assert result.payload_kg is None


def test_nominal_azimuth_is_the_spherical_trigonometry_one():
    # sin A = cos i / cos(phi); the descending opportunity is the supplement.
    i, phi = math.radians(51.6), math.radians(28.0)
    a = nominal_azimuth_rad(i, phi, "ascending")
    assert math.sin(a) == pytest.approx(math.cos(i) / math.cos(phi), rel=1e-12)
    assert nominal_azimuth_rad(i, phi, "descending") == pytest.approx(math.pi - a)
    # Due east from a latitude equal to the inclination.
    assert math.degrees(nominal_azimuth_rad(phi, phi, "ascending")) == pytest.approx(90.0)


def test_phase_ordering_is_converged_then_feasible_then_payload():
    def better(a: tuple, b: tuple) -> bool:
        return is_better(Standing(*a), Standing(*b), converged_residual=0.1)

    # (payload kg, violation, residual)
    assert better((300.0, 0.0, 0.5), (400.0, 0.5, 1.5))  # feasible beats heavier infeasible
    assert better((410.0, 0.0, 0.05), (400.0, 0.0, 0.05))
    assert not better((390.0, 0.0, 0.05), (400.0, 0.0, 0.05))
    assert better((200.0, 0.1, 1.1), (400.0, 0.5, 1.5))  # between infeasible: less violation
    # A converged design beats a heavier one at the edge of the tolerance box...
    assert better((399.9, 0.0, 0.05), (400.1, 0.0, 0.9))
    # ...and between two merely feasible designs the payload decides.
    assert better((400.1, 0.0, 0.9), (399.9, 0.0, 0.5))


# -- the optimised ascent at two altitudes (one global search, one continuation) -----------


# The tests of the solved ascent share one global search and one continuation (~15 s):
# left out of the fast tier (-m "not slow"), where the refusals above and
# tests/test_launch_dynamics.py check the launch.
SOLVED = pytest.mark.slow


@pytest.fixture(scope="module")
def solved(scenario):
    reference = solve_launch(launch_input(scenario))
    lower = solve_launch(
        launch_input(scenario, altitude_km=250.0),
        seed_design=reference.design,
        global_search=False,
    )
    return reference, lower


@SOLVED
def test_insertion_constraints_met_within_tolerances_at_two_altitudes(solved, scenario):
    tol = scenario.launch.insertion_tolerances
    for result in solved:
        assert result.feasible, result.reason
        row = result.to_row()
        assert LAUNCH_KEYS <= row.keys()
        assert abs(row["insertion_altitude_error_m"]) <= tol.altitude_m
        assert abs(row["insertion_speed_error_mps"]) <= tol.speed_mps
        assert abs(row["insertion_fpa_error_deg"]) <= tol.flight_path_angle_deg
        assert abs(row["inclination_error_deg"]) <= tol.inclination_deg
        # The epoch puts the mean node on the target's (exact by construction, re-derived
        # here from the final ECI state).
        assert abs(row["raan_error_deg"]) < 1e-6
        limits = scenario.launch.launcher.limits
        over = 1.0 + tol.path_limit_fraction
        assert row["max_dynamic_pressure_pa"] <= limits.max_dynamic_pressure_kpa * 1e3 * over
        assert row["max_axial_load_g"] <= limits.max_axial_load_g * over
        # Independent check of the insertion orbit: near-circular at the target radius.
        radius = scenario.earth.radius + result.target_altitude_m
        assert row["semi_major_axis_km"] * 1e3 == pytest.approx(radius, abs=2 * tol.altitude_m)
        assert row["eccentricity"] < 1e-3


@SOLVED
def test_payload_decreases_with_target_altitude(solved):
    reference, lower = solved
    assert lower.target_altitude_m < reference.target_altitude_m
    assert lower.payload_kg > reference.payload_kg


@SOLVED
def test_local_phases_never_end_worse_than_their_seed(solved, scenario):
    converged = scenario.launch.local.converged_residual
    for result in solved:
        best = result.phases[0].standing
        for phase in result.phases[1:]:
            # A phase replaces the incumbent exactly when it ranks better.
            assert phase.accepted == is_better(phase.standing, best, converged)
            if phase.accepted:
                best = phase.standing
        assert result.payload_kg == best.payload_kg
        assert not is_better(result.phases[0].standing, best, converged)
        # The local phases closed the constraints to a converged design.
        assert best.residual <= converged
    reference = solved[0]
    assert reference.phases[0].name == "genetic"
    assert [p.name for p in reference.phases] == ["genetic", "slsqp", "trust-constr"]


@SOLVED
def test_launch_epoch_is_on_the_launch_day_and_in_plane(solved, scenario):
    reference = solved[0]
    assert 0.0 <= reference.drop_time_s < 86400.0
    assert reference.insertion_time_s == pytest.approx(
        reference.drop_time_s + reference.flight_time_s
    )
    inp = launch_input(scenario)
    # The root of the node equation: shifting the node by the Earth's turn in dt moves
    # the insertion time by dt (mod one synodic day).
    node = 1.0
    t_drop, t_ins = insertion_time_s(inp, node, reference.flight_time_s)
    _, t_ins_shifted = insertion_time_s(
        inp, node - inp.earth.omega * 100.0, reference.flight_time_s
    )
    assert (t_ins_shifted - t_ins) % 86164.0 == pytest.approx(
        100.0 * inp.earth.omega / (inp.earth.omega - inp.target_plane.raan_rate_rad_s), abs=1e-6
    )
    assert t_drop >= 0.0


@SOLVED
def test_trajectory_table_is_complete_and_consistent(solved):
    table = solved[0].trajectory
    for column in (
        "time_s",
        "altitude_m",
        "speed_mps",
        "flight_path_angle_deg",
        "mass_kg",
        "alpha_deg",
        "dynamic_pressure_pa",
        "stage",
    ):
        assert column in table.columns
        assert np.all(np.isfinite(table[column].to_numpy(dtype=float)))
    assert np.all(np.diff(table["time_s"]) >= 0.0)
    assert set(table["stage"]) == {1, 2, 3}
    assert np.all(np.diff(table["mass_kg"]) <= 1e-9)  # mass never grows
    assert table["dynamic_pressure_pa"].max() <= solved[0].max_dynamic_pressure_pa * (1 + 1e-9)


@SOLVED
def test_design_round_trips_through_the_row(solved):
    reference = solved[0]
    assert design_of(reference.to_row()) == reference.design


# -- CLI ------------------------------------------------------------------------------------


def test_cli_launch_json_keys_and_exit_code(tmp_path, scenario_data):
    # A tiny search budget: the run is quick and (most likely) infeasible; either way the
    # JSON carries the required keys and the exit code follows feasibility.
    launch = scenario_data["launch"]
    launch["genetic"].update(population=6, generations=1)
    launch["local"].update(slsqp_max_iterations=2, trust_constr_max_iterations=1)
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(scenario_data))
    out = CliRunner().invoke(app, ["launch", str(path), "--altitude-km", "250", "--json"])
    row = json.loads(out.stdout)
    assert LAUNCH_KEYS <= row.keys()
    assert row["target_altitude_km"] == 250.0
    assert out.exit_code == (0 if row["feasible"] else 1)


def test_cli_launch_rejects_an_altitude_out_of_range():
    out = CliRunner().invoke(
        app, ["launch", str(REPO / "configs" / "scenario.yaml"), "--altitude-km", "100"]
    )
    assert out.exit_code == 2
    assert "altitude_km must lie in [150, 2000] km" in out.stderr
