"""The Prefect layer runs on the pinned stack (temporary local server, no network)."""

from __future__ import annotations

from tests.conftest import DEFAULT_SCENARIO


def test_rendezvous_flow_end_to_end(prefect_server):
    from flows.rendezvous import rendezvous_flow

    row = rendezvous_flow(str(DEFAULT_SCENARIO))
    assert row["feasible"] is True
    assert row["miss_distance_m"] <= 10.0
    assert row["dv1_mps"] > 0 and row["dv2_mps"] > 0


def test_every_deployment_entrypoint_is_a_flow_taking_its_parameters():
    import importlib
    import inspect

    import yaml
    from prefect import Flow

    from tests.conftest import REPO

    spec = yaml.safe_load((REPO / "prefect.yaml").read_text(encoding="utf-8"))
    names = [d["name"] for d in spec["deployments"]]
    assert {"rendezvous", "launch-fit"} <= set(names)
    for deployment in spec["deployments"]:
        path, attribute = deployment["entrypoint"].split(":")
        module = importlib.import_module(path.removesuffix(".py").replace("/", "."))
        flow_object = getattr(module, attribute)
        assert isinstance(flow_object, Flow), deployment["entrypoint"]
        accepted = inspect.signature(flow_object.fn).parameters
        assert set(deployment.get("parameters", {})) <= set(accepted), deployment["name"]
        for value in deployment.get("parameters", {}).values():
            if isinstance(value, str) and value.startswith("configs/"):
                assert (REPO / value).is_file(), value
