"""Strict configuration inputs: no bool for a number, YAML values that
cannot be built, plausible bounds on physical inputs.

Every config family is covered through its own loader; each refusal is one readable line
naming the field.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.config import ConfigError
from ovtraj.config.deorbit_burn import deorbit_burn_config_from_dict
from ovtraj.config.maneuver import load_maneuver_config, maneuver_config_from_dict
from ovtraj.config.optimal_entry import load_optimal_entry_config, optimal_entry_config_from_dict
from ovtraj.target_sources import load_scenario
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario

CASES = REPO / "configs" / "cases"
OPTIMAL_ENTRY = CASES / "suborbital_return.yaml"
MANEUVER = CASES / "upper_stage_rendezvous.yaml"
DEORBIT_BURN = CASES / "shuttle_deorbit.yaml"
runner = CliRunner()


def _data(path: Path) -> dict[str, Any]:
    return copy.deepcopy(yaml.safe_load(path.read_text(encoding="utf-8")))


def _set(data: dict[str, Any], dotted: str, value: Any) -> dict[str, Any]:
    node = data
    *parents, last = dotted.split(".")
    for part in parents:
        node = node[part]
    node[last] = value
    return data


def _problems(build: Any, data: dict[str, Any]) -> list[str]:
    with pytest.raises(ConfigError) as info:
        build(data, "case.yaml")
    return info.value.problems


# --------------------------------------------------------------------------- booleans


@pytest.mark.parametrize(
    ("path", "build", "field"),
    [
        (OPTIMAL_ENTRY, optimal_entry_config_from_dict, "initial.longitude_deg"),
        (MANEUVER, maneuver_config_from_dict, "optimizer.population_per_variable"),
        (MANEUVER, maneuver_config_from_dict, "finite_burn.position_scale_m"),
        (OPTIMAL_ENTRY, optimal_entry_config_from_dict, "guess.alpha_deg"),  # float | None
        (DEORBIT_BURN, deorbit_burn_config_from_dict, "guidance.strategy"),  # Literal[1, 2]
    ],
)
@pytest.mark.parametrize("flag", [True, False])
def test_a_bool_is_not_a_number(path, build, field, flag):
    data = _set(_data(path), field, flag)
    assert _problems(build, data) == [f"{field} = {flag!r}: expected a number, not a boolean"]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("rendezvous.transfer_time_bounds", [True, 1.5]),  # tuple
        ("rendezvous.start_transfer_fractions", [0.85, False]),  # variable-length tuple
        ("launch.design_bounds.payload_kg.lower", True),  # nested model
        ("launch.fit.ridge_candidates", [1.0e-6, True]),
        ("reentry.vehicle.aero.cl", [[True, 0.0], [0.025, 0.0]]),  # list of lists
        ("reentry.guidance.newton_iterations", True),  # int
    ],
)
def test_a_bool_inside_a_nested_or_list_field_is_refused(scenario_data, field, value):
    data = _set(scenario_data, field, value)
    assert _problems(build_scenario_from, data) == [
        f"{field} = {value!r}: expected a number, not a boolean"
    ]


def build_scenario_from(data: dict[str, Any], source: str) -> Any:
    return build_scenario(data)


def test_a_bool_in_the_earth_model_is_refused(scenario_data, earth):
    scenario_data["earth"] = earth.model_dump() | {"mu_m3_s2": True}
    assert _problems(build_scenario_from, scenario_data) == [
        "earth.mu_m3_s2 = True: expected a number, not a boolean"
    ]


def test_real_bool_fields_still_take_bools(scenario_data):
    scenario_data["reentry"]["integration"]["earth_rotation"] = False
    scenario_data["mission"]["surrogate"]["phase_input"] = False
    scenario = build_scenario(scenario_data)
    assert scenario.reentry.integration.earth_rotation is False
    assert scenario.mission.surrogate.phase_input is False
    data = _set(_data(MANEUVER), "finite_burn.enabled", False)
    assert maneuver_config_from_dict(data).finite_burn.enabled is False


def test_several_bools_are_reported_together():
    data = _set(_data(OPTIMAL_ENTRY), "initial.longitude_deg", True)
    _set(data, "vehicle.mass_kg", False)
    problems = _problems(optimal_entry_config_from_dict, data)
    assert len(problems) == 2
    assert all("expected a number, not a boolean" in p for p in problems)


def test_a_bool_in_a_yaml_file_is_refused_by_the_cli(tmp_path):
    text = OPTIMAL_ENTRY.read_text(encoding="utf-8")
    initial = text.index("\ninitial:")
    start = text.index("  longitude_deg: 100.0", initial)
    text = text[:start] + "  longitude_deg: true" + text[start + len("  longitude_deg: 100.0") :]
    assert yaml.safe_load(text)["initial"]["longitude_deg"] is True  # YAML really holds a bool
    path = tmp_path / "bool.yaml"
    path.write_text(text, encoding="utf-8")
    result = runner.invoke(app, ["optimal-entry", str(path), "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "initial.longitude_deg = True: expected a number, not a boolean" in result.output


# --------------------------------------------------------------------------- YAML values


def _scenario_text_with_epoch(epoch: str) -> str:
    text = DEFAULT_SCENARIO.read_text(encoding="utf-8")
    lines = text.splitlines()
    index = next(i for i, line in enumerate(lines) if line.startswith("epoch_utc:"))
    lines[index] = f"epoch_utc: {epoch}"
    return "\n".join(lines) + "\n"


def test_an_impossible_unquoted_date_is_a_config_error_naming_the_key(tmp_path):
    path = tmp_path / "scenario.yaml"
    path.write_text(_scenario_text_with_epoch("2026-13-45T00:00:00Z"), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    (problem,) = info.value.problems
    assert info.value.source == str(path)
    assert problem.startswith("epoch_utc = 2026-13-45T00:00:00Z (line ")
    assert "month must be in 1..12" in problem and "quote it" in problem


def test_the_cli_prints_one_line_and_exits_2_on_an_impossible_date(tmp_path):
    path = tmp_path / "scenario.yaml"
    path.write_text(_scenario_text_with_epoch("2026-13-45T00:00:00Z"), encoding="utf-8")
    result = runner.invoke(app, ["rendezvous", str(path), "--json"])
    assert result.exit_code == 2
    assert result.stdout == ""
    assert "Traceback" not in result.output
    (line,) = result.stderr.splitlines()  # one line: the file, the key and the value
    assert line.startswith(f"invalid configuration in {path}: epoch_utc = 2026-13-45T00:00:00Z")


def test_a_valid_unquoted_date_asks_for_quotes(tmp_path):
    path = tmp_path / "scenario.yaml"
    path.write_text(_scenario_text_with_epoch("2026-12-01T00:00:00Z"), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    (problem,) = info.value.problems
    assert problem.startswith("epoch_utc = ") and "quote it" in problem


def test_an_unbuildable_value_inside_a_list_is_located(tmp_path):
    text = MANEUVER.read_text(encoding="utf-8") + "\nextra: [1, !!int twelve]\n"
    path = tmp_path / "case.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_maneuver_config(path)
    (problem,) = info.value.problems
    assert problem.startswith("extra[1] = twelve (line ")


def test_a_binary_file_is_a_config_error(tmp_path):
    path = tmp_path / "binary.yaml"
    path.write_bytes(b"\xff\xfe\x00name: x\n")
    with pytest.raises(ConfigError, match="not a UTF-8 text file"):
        load_optimal_entry_config(path)


def test_an_impossible_date_in_the_launcher_file_names_it(scenario_data, tmp_path):
    launcher = REPO / "configs" / "launchers" / "pegasus_xl.yaml"
    text = launcher.read_text(encoding="utf-8") + "\nreleased: 1990-02-30\n"
    path = tmp_path / "launcher.yaml"
    path.write_text(text, encoding="utf-8")
    scenario_data["launch"]["launcher"] = str(path)
    (problem,) = _problems(build_scenario_from, scenario_data)
    assert f"launcher file {path}: released = 1990-02-30 (line " in problem


# --------------------------------------------------------------------------- bounds


def test_every_shipped_config_loads():
    assert load_scenario(DEFAULT_SCENARIO).launch is not None  # with its launcher file
    assert load_optimal_entry_config(OPTIMAL_ENTRY).vehicle.reference_area_m2 == 42.0
    assert load_maneuver_config(MANEUVER).stage.initial_mass_kg == 30400.0
    data = _data(DEORBIT_BURN)
    assert deorbit_burn_config_from_dict(data).vehicle.mass_kg == 95000.0


@pytest.mark.parametrize(
    ("field", "value", "allowed"),
    [
        ("reentry.vehicle.reference_area_m2", 1.0e30, "(0, 1000] m^2"),
        ("reentry.vehicle.mass_kg", 1.0e9, "(0, 1e+06] kg"),
        ("reentry.integration.step_s", 1.0e-9, "[0.001, 10] s"),
        ("reentry.integration.max_time_s", 1.0e9, "(0, 100000] s"),
        ("reentry.limits.max_load_g", 1.0e4, "(0, 100] g"),
        ("vehicle.thrust_n", 1.0e12, "(0, 1e+07] N"),
        ("rendezvous.trajectory_step_s", 1.0e-9, "[0.01, 86400] s"),
        ("rendezvous.max_wait_time_s", 1.0e9, "[0, 2.592e+06] s"),
        ("launch.genetic.seed", 2**40, "[0, 4.29497e+09]"),
        ("launch.integration.powered_step_s", 1.0e-6, "[0.01, 5] s"),
        ("deorbit.solver.dv_scale_mps", 1.0e9, "(0, 10000] m/s"),
    ],
)
def test_absurd_scenario_figures_are_refused_naming_the_field(scenario_data, field, value, allowed):
    data = _set(scenario_data, field, value)
    assert _problems(build_scenario_from, data) == [
        f"{field} = {value!r}: out of range, allowed {allowed}"
    ]


@pytest.mark.parametrize(
    ("path", "build", "field", "value", "fragment"),
    [
        (OPTIMAL_ENTRY, optimal_entry_config_from_dict, "vehicle.reference_area_m2", 1e30, "1000]"),
        (OPTIMAL_ENTRY, optimal_entry_config_from_dict, "guess.max_time_s", 1e30, "100000] s"),
        (
            OPTIMAL_ENTRY,
            optimal_entry_config_from_dict,
            "state_bounds.speed_mps",
            [1.0, 1e400],
            "finite",
        ),
        (MANEUVER, maneuver_config_from_dict, "finite_burn.position_scale_m", 1e30, "1e+08] m"),
        (
            MANEUVER,
            maneuver_config_from_dict,
            "maneuver.time_of_flight_bounds_s",
            [1.0, 1e9],
            "1e6",
        ),
        (
            DEORBIT_BURN,
            deorbit_burn_config_from_dict,
            "vehicle.thrust_per_engine_n",
            1e30,
            "1e+07] N",
        ),
    ],
)
def test_absurd_case_figures_are_refused_naming_the_field(path, build, field, value, fragment):
    (problem,) = _problems(build, _set(_data(path), field, value))
    assert problem.startswith(f"{field} = ") and fragment in problem


def test_launch_design_bounds_must_be_plausible(scenario_data):
    scenario_data["launch"]["design_bounds"]["coast_s"] = {"lower": 5.0, "upper": 1.0e9}
    (problem,) = _problems(build_scenario_from, scenario_data)
    assert problem == "launch.design_bounds: coast_s [5, 1e+09] must lie in [0, 10000]"


def test_a_huge_reference_area_is_refused_quickly_by_the_cli(tmp_path):
    """Measured before the bound: ~290 s of integration, then 'math domain error'."""
    text = OPTIMAL_ENTRY.read_text(encoding="utf-8").replace(
        "reference_area_m2: 42.0", "reference_area_m2: 1e30"
    )
    path = tmp_path / "area.yaml"
    path.write_text(text, encoding="utf-8")
    result = runner.invoke(app, ["optimal-entry", str(path), "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "vehicle.reference_area_m2 = '1e30': out of range, allowed (0, 1000] m^2" in (
        result.output
    )


def test_the_earth_model_file_refuses_a_bool_for_a_number(tmp_path):
    from pydantic import ValidationError

    from ovtraj.config.physical import load_earth

    text = (REPO / "configs" / "earth.yaml").read_text(encoding="utf-8")
    path = tmp_path / "earth.yaml"
    path.write_text(text.replace("j2: 1.08262668e-3", "j2: true"), encoding="utf-8")
    assert "j2: true" in path.read_text(encoding="utf-8")
    with pytest.raises(ValidationError, match="expected a number, not a boolean"):
        load_earth(path)


@pytest.mark.parametrize("problems", [["mission.surrogate.seed: required"], ["a: bad", "b: bad"]])
def test_a_config_error_from_a_worker_process_keeps_its_lines(problems):
    """Pickled back from a worker, the error is rebuilt from its problems, not its text
    (which was read as a list of characters: one line per letter)."""
    import pickle

    error = ConfigError(problems, "batch scenario")
    again = pickle.loads(pickle.dumps(error))
    assert str(again) == str(error) and again.problems == problems
    assert again.source == "batch scenario"
