"""``flows/pipeline.py:mission_flow`` under a temporary Prefect server (issue 7).

A 12-sample DoE, one verification round of 3 front points, the plan: the verified
front's values must be the real chain's and the artifacts published. (That a second
run simulates nothing is tested on the library pipeline, tests/test_pipeline.py, and
on the DoE flow, tests/test_doe.py.)
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, evaluate
from ovtraj.mission.fly import fly_plan
from ovtraj.mission.plan import read_plan
from ovtraj.runs import RunStore, execute
from ovtraj.store.files import read_parquet
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario


@pytest.fixture(scope="module")
def flown(prefect_server, tmp_path_factory):
    from flows.pipeline import mission_flow

    tmp = tmp_path_factory.mktemp("mission-flow")
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(samples=12, batch_size=6, store=str(tmp / "runs"))
    # Two rounds, the second's NSGA-II warm from the first's front (through the front task).
    data["mission"]["verify"].update(
        points_per_iteration=3, max_iterations=2, budget=6, hypervolume_tolerance=None
    )
    data["mission"]["surrogate"].update(
        regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3
    )
    data["mission"]["optimize"].update(population=32, generations=40, warm_start_generations=10)
    config = tmp / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    before = execute.EVALUATIONS["count"]
    first = mission_flow(config=str(config))
    middle = execute.EVALUATIONS["count"]
    # The same pipeline through the command line, into a store of its own (issue 45).
    from ovtraj.cli import run_command

    cli_store = tmp / "cli-runs"
    cli_exit = run_command(["pipeline", str(config), "--store", str(cli_store), "--json"])
    from prefect.artifacts import Artifact

    artifacts = {key: Artifact.get(key) for key in ("verified-front", "surrogate-validation")}
    return {
        "first": first,
        "evaluations": (middle - before,),
        "artifacts": artifacts,
        "scenario": build_scenario(data),
        "store": RunStore(tmp / "runs"),
        "cli_exit": cli_exit,
        "cli_store": cli_store,
    }


def test_flow_verifies_the_front_with_the_real_chain(flown):
    first = flown["first"]
    assert flown["evaluations"][0] == 12 + first["real_evaluations"]["infill"]
    assert first["real_evaluations"] == {"doe": 12, "infill": 6}
    front = read_parquet(first["front"])
    totals = flown["store"].run(first["final_run"]).totals().set_index("sample_id")
    scenario = flown["scenario"]
    context = MissionContext(scenario, find_launch_fit(scenario))
    for row in front.head(3).itertuples(index=False):
        assert row.t_total_s == totals.loc[row.sample_id, "t_total_s"]
        record = evaluate(context, MissionDesign(*(getattr(row, n) for n in DESIGN_NAMES)))
        assert record.feasible
        assert record.dv_total_mps == pytest.approx(row.dv_total_mps, rel=1e-9)
        assert record.t_total_s == pytest.approx(row.t_total_s, rel=1e-9)
    assert all(artifact is not None for artifact in flown["artifacts"].values())


def test_the_flows_plan_lands_within_its_stated_miss(flown):
    report = fly_plan(read_plan(flown["first"]["plan_json"]))
    assert report.landed_within_stated_miss


def test_the_flows_second_round_starts_from_the_first_rounds_front(flown):
    """optimize.warm_start_generations through the Prefect front task: the second round's
    front names the first's as its warm start and ran the warm generations."""
    import json

    root = flown["store"].root
    markers = [json.loads(p.read_text()) for p in sorted(root.glob("*/fronts/*/meta.json"))]
    by_id = {m["front_id"]: m for m in markers}
    warm = [m for m in markers if m.get("warm_from")]
    assert len(warm) == 1 and len(markers) == 2
    assert warm[0]["warm_from"] in by_id
    assert warm[0]["nsga2"]["generations"] < by_id[warm[0]["warm_from"]]["nsga2"]["generations"]


def _stored_files(root) -> dict[str, object]:
    """Every file of a store: its bytes, or for a JSON marker its content without the
    host data a store holds: creation times, the timing of batches and fits, and the
    environment that computed them."""
    import json

    def timeless(value, key=""):
        if isinstance(value, dict):
            return {
                k: timeless(v, k)
                for k, v in value.items()
                if k not in ("created_utc", "timing", "environment")
                # a marker's digest of a nested marker: that one is compared without its times
                and not (key == "files" and k.endswith(".json"))
            }
        if isinstance(value, list):
            return [timeless(v) for v in value]
        return value

    files: dict[str, object] = {}
    for path in sorted(root.rglob("*")):
        if path.is_file() and not path.name.endswith(".lock"):
            name = str(path.relative_to(root))
            data = path.read_bytes()
            if name.startswith("catalog/history/") or name == "catalog/stamps.json":
                # the trend the flow draws for its artifact (ovtraj history's view); the
                # catalog's cache of its documents' sizes, times and inodes (host data)
                continue
            if name.startswith("catalog/"):
                files[name] = _catalog_content(path)
                continue
            files[name] = timeless(json.loads(data)) if path.suffix == ".json" else data
    return files


def _catalog_content(path):
    """The store's catalog without the creation times (its rows are derived from the
    stored documents, each row's ``source_sha256`` from a manifest that holds one)."""
    import json

    import pyarrow.parquet as pq

    if path.name == "catalog.json":
        return json.loads(path.read_bytes())["rows"]
    if path.suffix == ".parquet":
        table = pq.read_table(path).drop_columns(["created_utc", "source_sha256"])
        # Rows follow their creation times (timing): compared in the order of their source.
        return sorted(table.to_pylist(), key=lambda row: (row["kind"], row["source"]))
    return path.read_bytes()


def test_the_flow_and_the_command_line_store_the_same_pipeline(flown):
    """``mission_flow`` and ``ovtraj pipeline`` are adapters of one driver
    (``ovtraj.pipeline.drive``): the same inputs give the same stored files, byte for byte
    (JSON markers without their creation times and timing): runs, batches, fits, fronts, the
    verified front, the plan, its plots and report."""
    assert flown["cli_exit"] == 0
    flow_files = _stored_files(flown["store"].root)
    cli_files = _stored_files(flown["cli_store"])
    assert sorted(flow_files) == sorted(cli_files)
    assert any(name.endswith("report.html") for name in flow_files)
    differing = [name for name in flow_files if flow_files[name] != cli_files[name]]
    assert differing == []
    # Identical inputs, so `ovtraj diff` of the two plans (and of the two DoE runs) is empty
    # (issue 46), while the plan's own figures are all there (--all).
    from ovtraj.cli import run_command

    plan = Path(flown["first"]["plan_json"])
    twin = flown["cli_store"] / plan.relative_to(flown["store"].root)
    assert twin.is_file() and twin != plan
    for a, b in ((plan, twin), (plan.parents[3], twin.parents[3])):
        found = _diff_json(run_command, [str(a), str(b), "--store", str(flown["cli_store"])])
        assert found["changed"] == 0 and found["fields"] == []
    everything = _diff_json(run_command, [str(plan), str(twin), "--all"])
    assert len(everything["fields"]) > 100 and not any(f["changed"] for f in everything["fields"])


def _diff_json(run_command, args):
    import contextlib
    import io
    import json

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert run_command(["diff", *args, "--json"]) == 0
    return json.loads(out.getvalue())
