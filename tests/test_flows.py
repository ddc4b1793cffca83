"""The Prefect layer runs on the pinned stack (temporary local server, no network)."""

from __future__ import annotations

import pytest
from prefect.testing.utilities import prefect_test_harness

from tests.conftest import DEFAULT_SCENARIO


@pytest.fixture(scope="module")
def prefect_server():
    with prefect_test_harness(server_startup_timeout=60):
        yield


def test_rendezvous_flow_end_to_end(prefect_server):
    from flows.rendezvous import rendezvous_flow

    row = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert row["feasible"] is True
    assert row["miss_distance_m"] <= 10.0
    assert row["dv1_mps"] > 0 and row["dv2_mps"] > 0
