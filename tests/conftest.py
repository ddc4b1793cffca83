"""Shared fixtures: the project's Earth model and the default scenario."""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import pytest
import yaml

from ovtraj.astro.constants import EarthModel, default_earth
from ovtraj.config import Scenario, load_scenario, scenario_from_dict

# Prefect must never try to reach the network from the test suite.
os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")

REPO = Path(__file__).resolve().parents[1]
# Keys the rendezvous result row (and `ovtraj rendezvous --json`) must carry (issue 2).
REQUIRED_KEYS = {
    "dv1_mps",
    "dv2_mps",
    "transfer_time_s",
    "wait_time_s",
    "lead_angle_deg",
    "lead_angle_two_body_deg",
    "miss_distance_m",
    "feasible",
}
# Keys `ovtraj deorbit --json` must carry (issue 4).
DEORBIT_KEYS = {
    "burn_epoch_utc",
    "dv_mps",
    "wait_time_s",
    "entry_lat_deg",
    "entry_lon_deg",
    "entry_fpa_deg",
    "entry_speed_mps",
    "entry_error_km",
    "feasible",
}
# Keys `ovtraj reentry --json` must carry (issue 5).
REENTRY_KEYS = {
    "miss_distance_km",
    "flight_time_s",
    "max_heat_rate_kw_m2",
    "max_load_g",
    "max_dynamic_pressure_kpa",
    "terminal_altitude_km",
    "terminal_speed_mps",
    "feasible",
}
DEFAULT_SCENARIO = REPO / "configs" / "scenario.yaml"


@pytest.fixture(scope="session")
def prefect_server():
    """One temporary Prefect server for every flow test of the session.

    Its start costs 6-60 s on this machine (CPU-bound, varies with the VM's speed); one
    per module cost minutes of the suite's budget.
    """
    from prefect.testing.utilities import prefect_test_harness

    with prefect_test_harness(server_startup_timeout=120):
        yield


@pytest.fixture(scope="session")
def earth() -> EarthModel:
    return default_earth()


@pytest.fixture(scope="session")
def scenario() -> Scenario:
    return load_scenario(DEFAULT_SCENARIO)


@pytest.fixture
def scenario_data() -> dict[str, Any]:
    """The default scenario as a fresh mutable mapping."""
    with open(DEFAULT_SCENARIO, encoding="utf-8") as fh:
        return copy.deepcopy(yaml.safe_load(fh))


def build_scenario(data: dict[str, Any]) -> Scenario:
    return scenario_from_dict(data, "test")
