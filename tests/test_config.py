"""Config layer: the default scenario loads; bad input is refused with a clear message."""

from __future__ import annotations

from pathlib import Path

import pytest

from ovtraj.config import ConfigError
from ovtraj.target_sources import load_scenario
from tests.conftest import build_scenario


def test_default_scenario_loads(scenario):
    assert scenario.target.orbit.inclination_deg == pytest.approx(51.64)
    assert scenario.epoch.iso().startswith("2026-12-01T00:00:00")
    # The Earth model comes from configs/earth.yaml, with SPEC's figures.
    assert scenario.earth.mu_m3_s2 == 3.986004418e14
    assert scenario.earth.j2 == 1.08262668e-3


def test_resolved_config_round_trips(scenario):
    again = build_scenario(scenario.resolved())
    assert again == scenario


def _refused(data) -> str:
    with pytest.raises(ConfigError) as info:
        build_scenario(data)
    return str(info.value)


@pytest.mark.parametrize(
    ("section", "key"),
    [((), "colour"), (("target", "orbit"), "mean_anomaly_deg"), (("vehicle",), "wings")],
)
def test_unknown_keys_are_named(scenario_data, section, key):
    node = scenario_data
    for part in section:
        node = node[part]
    node[key] = 1
    message = _refused(scenario_data)
    path = ".".join([*section, key])
    assert f"{path}: unknown key" in message
    assert "allowed keys:" in message


@pytest.mark.parametrize("eccentricity", [1.0, 1.5, -0.01])
def test_eccentricity_outside_unit_interval(scenario_data, eccentricity):
    scenario_data["target"]["orbit"]["eccentricity"] = eccentricity
    message = _refused(scenario_data)
    assert f"target.orbit.eccentricity = {eccentricity!r}" in message
    assert "allowed [0, 1)" in message


@pytest.mark.parametrize("inclination", [-1.0, 180.5, 270.0])
def test_inclination_outside_range(scenario_data, inclination):
    scenario_data["target"]["orbit"]["inclination_deg"] = inclination
    message = _refused(scenario_data)
    assert "target.orbit.inclination_deg" in message
    assert "allowed [0, 180] deg" in message


def test_perigee_below_100_km(scenario_data):
    # 6500 km with e = 0.02 puts perigee at 6370 km: below the Earth's radius + 100 km.
    scenario_data["target"]["orbit"].update(semi_major_axis_km=6500.0, eccentricity=0.02)
    message = _refused(scenario_data)
    assert "target.orbit: perigee altitude" in message
    assert "allowed >= 100 km" in message


def test_parking_orbit_below_100_km(scenario_data):
    scenario_data["parking_orbit"]["altitude_km"] = 90.0
    message = _refused(scenario_data)
    assert "parking_orbit.altitude_km" in message
    assert "allowed >= 100 km" in message


def test_orbit_just_above_the_floor_is_accepted(scenario_data):
    scenario_data["parking_orbit"]["altitude_km"] = 100.5
    assert build_scenario(scenario_data).parking_orbit.altitude_km == 100.5


@pytest.mark.parametrize(
    ("key", "allowed"),
    [
        ("mass_kg", "(0, 1e+06] kg"),
        ("dry_mass_kg", "(0, 1e+06] kg"),
        ("thrust_n", "(0, 1e+07] N"),
        ("isp_s", "(0, 10000] s"),
        ("max_impulse_mps", "(0, 20000] m/s"),
    ],
)
def test_negative_vehicle_figures(scenario_data, key, allowed):
    scenario_data["vehicle"][key] = -5.0
    message = _refused(scenario_data)
    assert f"vehicle.{key} = -5.0: out of range, allowed {allowed}" in message


def test_dry_mass_above_wet_mass(scenario_data):
    scenario_data["vehicle"]["dry_mass_kg"] = 1000.0
    assert "dry_mass_kg (1000) must not exceed mass_kg (400)" in _refused(scenario_data)


@pytest.mark.parametrize("text", ["2026-13-01T00:00:00Z", "tomorrow", "", "2026-02-30"])
def test_epoch_that_does_not_parse(scenario_data, text):
    scenario_data["epoch_utc"] = text
    message = _refused(scenario_data)
    assert "epoch_utc" in message
    assert "ISO 8601" in message


def test_epoch_with_offset_is_converted_to_utc(scenario_data):
    scenario_data["epoch_utc"] = "2026-12-01T02:00:00+02:00"
    assert build_scenario(scenario_data).epoch.iso().startswith("2026-12-01T00:00:00")


def test_transfer_time_bounds_must_bracket_one(scenario_data):
    scenario_data["rendezvous"]["transfer_time_bounds"] = [1.2, 0.8]
    assert "rendezvous.transfer_time_bounds" in _refused(scenario_data)


def test_a_scenario_never_names_a_dask_scheduler(scenario_data, monkeypatch):
    """A shared scenario file naming a scheduler would make ``ovtraj run``
    speak Dask's pickle protocol to it; the address comes from the command line, the flow
    or the environment only."""
    from ovtraj.runs.runners import DASK_ADDRESS_ENV, dask_address

    scenario_data["mission"]["doe"]["dask_address"] = "tcp://203.0.113.9:8786"
    message = _refused(scenario_data)
    assert "mission.doe.dask_address" in message and "never names a Dask scheduler" in message
    scenario_data["mission"]["doe"]["dask_address"] = None  # what stored configs hold
    build_scenario(scenario_data)
    monkeypatch.delenv(DASK_ADDRESS_ENV, raising=False)
    assert dask_address(None) is None and dask_address("tls://a:1") == "tls://a:1"
    monkeypatch.setenv(DASK_ADDRESS_ENV, "tls://b:2")
    assert dask_address(None) == "tls://b:2" and dask_address("tls://a:1") == "tls://a:1"


def test_missing_key_is_named(scenario_data):
    del scenario_data["target"]["orbit"]["eccentricity"]
    assert "target.orbit.eccentricity: required key is missing" in _refused(scenario_data)


def test_wrong_type_is_named(scenario_data):
    scenario_data["vehicle"]["thrust_n"] = "strong"
    assert "vehicle.thrust_n = 'strong'" in _refused(scenario_data)


def test_several_problems_reported_together(scenario_data):
    scenario_data["target"]["orbit"]["eccentricity"] = 2.0
    scenario_data["vehicle"]["thrust_n"] = -1.0
    message = _refused(scenario_data)
    assert "eccentricity" in message and "thrust_n" in message


def test_yaml_syntax_error_names_the_file(tmp_path: Path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("target: [unclosed\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scenario(bad)
    assert "broken.yaml" in str(info.value) and "not valid YAML" in str(info.value)


def test_missing_file(tmp_path: Path):
    with pytest.raises(ConfigError, match="cannot read the file"):
        load_scenario(tmp_path / "nope.yaml")


def test_top_level_must_be_a_mapping(tmp_path: Path):
    path = tmp_path / "list.yaml"
    path.write_text("- 1\n- 2\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_scenario(path)


def test_a_config_stored_before_shortlist_size_existed_still_reads(scenario_data):
    """Runs keep their resolved config: a key added later must not make them unreadable."""
    surrogate = scenario_data["mission"]["surrogate"]
    del surrogate["shortlist_size"]
    assert build_scenario(scenario_data).mission.surrogate.shortlist_size is None
    surrogate["selection"] = "shortlist"
    with pytest.raises(ConfigError, match="shortlist_size"):
        build_scenario(scenario_data)


def test_part_inputs_are_checked_and_optional(scenario_data):
    surrogate = scenario_data["mission"]["surrogate"]
    surrogate.pop("part_inputs", None)
    assert build_scenario(scenario_data).mission.surrogate.part_inputs == {}
    surrogate["part_inputs"] = {"dv_rendezvous_mps": ["parking_altitude_km", "sin_wait_phase"]}
    surrogate["burn_phase"] = True  # the burn's phase inputs replace the wait's
    with pytest.raises(ConfigError, match=r"part_inputs\.dv_rendezvous_mps.*burn_phase true"):
        build_scenario(scenario_data)
    surrogate["burn_phase"] = False
    surrogate["part_inputs"] = {"dv_rendezvous_mps": ["parking_altitude_km", "sin_2u_burn"]}
    with pytest.raises(ConfigError, match=r"part_inputs\.dv_rendezvous_mps.*burn_phase false"):
        build_scenario(scenario_data)
    surrogate["part_inputs"] = {"dv_rendezvous_mps": ["altitude"]}
    with pytest.raises(ConfigError, match=r"part_inputs\.dv_rendezvous_mps\.0"):
        build_scenario(scenario_data)
    surrogate["part_inputs"] = {"dv_total_mps": ["parking_altitude_km"]}
    with pytest.raises(ConfigError, match=r"part_inputs\.dv_total_mps"):
        build_scenario(scenario_data)


def test_the_departure_phase_needs_the_pass_model_and_names_its_inputs(scenario_data):
    surrogate = scenario_data["mission"]["surrogate"]
    assert build_scenario(scenario_data).mission.surrogate.departure_phase
    surrogate.pop("departure_phase")
    surrogate.pop("part_inputs")
    assert not build_scenario(scenario_data).mission.surrogate.departure_phase
    surrogate["part_inputs"] = {"dv_transfer_mps": ["sin_departure_phase"]}
    with pytest.raises(ConfigError, match=r"part_inputs\.dv_transfer_mps.*departure_phase false"):
        build_scenario(scenario_data)
    surrogate.pop("part_inputs")
    surrogate["departure_phase"] = True
    surrogate["pass_forecast"] = None
    with pytest.raises(ConfigError, match=r"departure_phase needs pass_forecast"):
        build_scenario(scenario_data)
