"""The re-plan history: diff, history, catalog, tags and lineage on real re-plans.

Three nights of a drifting target: ``tools/example_tle.py --nights 3`` propagates the
default scenario's orbit with the project's J2 propagator and writes it as TLEs a day
apart; each night solves the launch fit of its element set and runs the pipeline with
``--target``, as the ``mission/mission-replan`` deployment does (a shortened launch search
and a small pipeline: about a minute, built once per session, tests/conftest.py). The
references are the stored plan files themselves, read and flattened here independently of
``ovtraj.tracking``.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from ovtraj.cli import app
from tests.conftest import REPLAN_NIGHTS, replan_nights

# Left out of the fast tier (-m "not slow"): every test reads the three re-plan nights, a
# launch fit and a pipeline each (about a minute).
pytestmark = pytest.mark.slow

NIGHTS = REPLAN_NIGHTS
OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))
TARGET = "ISS-like space target"


def _invoke(*args: str) -> object:
    return CliRunner().invoke(app, list(args))


@pytest.fixture(scope="module")
def nights(tmp_path_factory):
    """The session's three nights (tests/conftest.py:replan_nights); the commands here run
    in this process with the nights' workspace (their launch fits)."""
    found = replan_nights(tmp_path_factory)
    saved = os.environ.get("OVTRAJ_HOME")
    os.environ["OVTRAJ_HOME"] = str(found["home"])
    try:
        yield {**found, "tmp": found["home"].parent}
    finally:
        if saved is None:
            os.environ.pop("OVTRAJ_HOME", None)
        else:
            os.environ["OVTRAJ_HOME"] = saved


def _json(*args: str) -> dict:
    done = _invoke(*args, "--json")
    assert done.exit_code == 0, done.output
    return json.loads(done.stdout)


def _leaves(value, prefix=""):
    """Every scalar of a JSON document by its dotted path (the test's own flattening)."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _leaves(item, f"{prefix}.{key}" if prefix else key)
    elif not isinstance(value, list):
        yield prefix, value


def _tree_digests(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file() and "catalog" not in p.relative_to(root).parts and p.suffix != ".lock"
    }


def test_three_replans_give_a_three_row_history_equal_to_the_plans(nights):
    found = _json("history", "--target-name", TARGET, "--store", str(nights["store"]))
    rows = found["rows"]
    assert len(rows) == NIGHTS
    epochs = [r["element_set_epoch_utc"] for r in rows]
    assert epochs == sorted(epochs) and len(set(epochs)) == NIGHTS
    for row, path in zip(rows, nights["plans"], strict=True):
        plan = json.loads(path.read_text(encoding="utf-8"))
        assert row["dv_total_mps"] == plan["totals"]["dv_total_mps"]
        assert row["t_total_s"] == plan["totals"]["t_total_s"]
        assert row["m_load_kg"] == plan["totals"]["m_load_kg"]
        assert row["landing_miss_m"] == plan["terminal"]["miss_distance_m"]
        assert row["launch_epoch_utc"] == plan["launch"]["drop_epoch_utc"]
        assert row["pipeline_id"] == plan["source"]["pipeline_id"]
        assert row["code_version"] == plan["code_version"]
        # The night's element set, and its epoch read from the TLE's columns 19-32
        # (two-digit year, day of the year with its fraction).
        lines = Path(nights["tles"][rows.index(row)]).read_text().splitlines()
        assert plan["scenario"]["target"]["tle"] == lines
        year, day = 2000 + int(lines[1][18:20]), float(lines[1][20:32])
        epoch = datetime.datetime(year, 1, 1, tzinfo=datetime.UTC) + datetime.timedelta(
            days=day - 1
        )
        assert datetime.datetime.fromisoformat(row["element_set_epoch_utc"]) == epoch
    plot = Path(found["plot"])
    assert plot.is_absolute() and plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_diff_of_the_last_two_nights_names_exactly_the_changed_fields(nights):
    a, b = nights["plans"][-2:]
    found = _json("diff", str(a), str(b), "--store", str(nights["store"]))
    named = {f["name"]: f for f in found["fields"]}
    assert found["changed"] == len(found["fields"]) > 0
    # The independent reference: the two plan files' leaves compared here.
    pa_, pb = (json.loads(p.read_text(encoding="utf-8")) for p in (a, b))
    left, right = dict(_leaves(pa_)), dict(_leaves(pb))
    skipped = ("source.", "schema_version")
    expected = set()
    for key in left.keys() | right.keys():
        if key.startswith(skipped) or left.get(key) == right.get(key):
            continue
        expected.add(key)
    shown = {n for n in named if n != "target.element_set_epoch_utc"}
    # Lists are whole values in the scenario (the TLE's lines) and skipped in the results.
    list_valued = {n for n in shown if isinstance(named[n]["a"], list)}
    assert shown - list_valued == expected
    assert "scenario.target.tle" in list_valued
    epoch = named["target.element_set_epoch_utc"]
    assert epoch["unit"] == "utc" and epoch["change"] == pytest.approx(86400.0)
    dv = named["totals.dv_total_mps"]
    assert dv["unit"] == "m/s"
    assert dv["change"] == pytest.approx(
        pb["totals"]["dv_total_mps"] - pa_["totals"]["dv_total_mps"]
    )
    table = _invoke("diff", str(a), str(b), "--store", str(nights["store"]))
    assert "totals.dv_total_mps" in table.stdout and " m/s" in table.stdout
    markdown = _invoke("diff", str(a), str(b), "--md", "--store", str(nights["store"]))
    assert markdown.stdout.startswith("| group | field |") and "|---|" in markdown.stdout


def test_the_report_says_what_changed_since_the_previous_plan(nights):
    first, *_, last = nights["plans"]
    report = last.with_name(last.stem + "-report.html").read_text(encoding="utf-8")
    assert "Since the previous plan of this target" in report
    assert "target.element_set_epoch_utc" in report and "totals.dv_total_mps" in report
    page = first.with_name(first.stem + "-report.html").read_text(encoding="utf-8")
    assert "Since the previous plan of this target" not in page  # the first night


def test_the_rebuilt_catalog_equals_the_incremental_one(nights, tmp_path):
    from ovtraj.tracking.catalog import refresh

    store = tmp_path / "runs"
    shutil.copytree(nights["store"], store)
    incremental = refresh(store).frame  # kept by each night's pipeline, then refreshed
    shutil.rmtree(store / "catalog")
    rebuilt = refresh(store)
    assert rebuilt.written and rebuilt.rebuilt_because == "no catalog yet"
    pd.testing.assert_frame_equal(incremental, rebuilt.frame)
    kinds = rebuilt.frame["kind"].value_counts().to_dict()
    assert kinds["plan"] == NIGHTS and kinds["pipeline"] == NIGHTS and kinds["run"] >= 2 * NIGHTS
    # A damaged catalog is rebuilt, never trusted.
    path = store / "catalog" / "catalog.parquet"
    path.write_bytes(path.read_bytes()[:-10] + b"0123456789")
    again = refresh(store)
    assert again.rebuilt_because.startswith("damaged catalog")
    pd.testing.assert_frame_equal(again.frame, rebuilt.frame)
    done = _invoke("catalog", "--rebuild", "--store", str(store))
    assert done.exit_code == 0 and str(path) in done.stdout


def _pipeline_runs(store: Path, source: dict) -> set[str]:
    """The runs a stored pipeline result was made from, as its summary names them."""
    summary_file = store / source["doe_run"] / "pipeline" / source["pipeline_id"] / "pipeline.json"
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    rounds = summary["iterations"]
    found = {summary["doe_run"], summary["final_run"], *(r["run_id"] for r in rounds)}
    return found | {r["infill_run"] for r in rounds if r.get("infill_run")}


def test_writing_a_plan_refreshes_only_the_catalog_rows_it_changes(nights, tmp_path, monkeypatch):
    """``ovtraj plan`` (another point of the last night's front) brings up to date the catalog
    rows of the plan and of what it references, no other: the first night's DoE run, its
    manifest now corrupt, is not read and keeps its row, which a full refresh replaces by
    an error row. With the manifest restored, the catalog the plan left equals the one
    rebuilt from the documents alone."""
    from ovtraj.tracking import catalog_sources
    from ovtraj.tracking.catalog import refresh, refresh_entries
    from ovtraj.tracking.catalog_rows import plan_id

    store = tmp_path / "runs"
    shutil.copytree(nights["store"], store)
    catalog = refresh(store)  # the copies' stamps recorded: the catalog is the store's
    last = json.loads(nights["plans"][-1].read_text(encoding="utf-8"))["source"]
    unrelated = json.loads(nights["plans"][0].read_text(encoding="utf-8"))["source"]["doe_run"]
    family = _pipeline_runs(store, last)
    assert unrelated not in family
    manifest = store / unrelated / "manifest.json"
    kept, before = manifest.read_bytes(), catalog.item(unrelated)
    manifest.write_bytes(b"{")  # its stamp changed too: a full refresh reads it again
    read: list[Path] = []
    real = catalog_sources.read_bytes
    monkeypatch.setattr(
        catalog_sources,
        "read_bytes",
        lambda path, *a: read.append(Path(str(path))) or real(path, *a),
    )
    pick = (last["front_index"] + 1) % catalog.item(last["pipeline_id"])["front_points"]
    planned = _json("plan", last["doe_run"], "--pick", str(pick), "--store", str(store))
    monkeypatch.undo()
    plan = json.loads(Path(planned["plan_json"]).read_text(encoding="utf-8"))
    assert plan["source"]["front_index"] == pick and plan_id(plan) not in set(catalog.frame["id"])
    assert read and all(p.relative_to(store).parts[0] in family for p in read), read
    incremental = refresh_entries(store, [])
    assert not incremental.written and incremental.item(unrelated).equals(before)
    row = incremental.item(plan_id(plan))
    assert (
        row["kind"] == "plan" and row["error"] is None and row["pipeline_id"] == last["pipeline_id"]
    )
    assert "manifest" in refresh(store).item(unrelated)["error"]  # a full refresh reads it
    manifest.write_bytes(kept)
    rebuilt = refresh(store, rebuild=True)
    pd.testing.assert_frame_equal(incremental.frame, rebuilt.frame)


def test_runs_where_queries_the_catalog_with_sql(nights):
    store = str(nights["store"])
    plans = _json("runs", "--where", "kind = 'plan' AND dv_total_mps > 0", "--store", store)
    assert len(plans["rows"]) == NIGHTS
    highest = max(r["dv_total_mps"] for r in plans["rows"])
    top = _json("runs", "--where", f"kind = 'plan' AND dv_total_mps >= {highest}", "--store", store)
    assert [r["dv_total_mps"] for r in top["rows"]] == [highest]
    bad = _invoke("runs", "--where", "kind = = 'plan'", "--store", store)
    assert bad.exit_code == 2 and "--where" in bad.output and "Traceback" not in bad.output
    # The query sees the catalog only: no file, no network.
    leak = _invoke(
        "runs", "--where", "(SELECT count(*) FROM read_csv('/etc/passwd')) > 0", "--store", store
    )
    assert leak.exit_code == 2 and "root:" not in leak.output


def test_a_tag_never_changes_a_checksummed_file(nights, tmp_path):
    store = tmp_path / "runs"
    shutil.copytree(nights["store"], store)
    before = _tree_digests(store)
    pipeline = json.loads(nights["plans"][0].read_text(encoding="utf-8"))["source"]["pipeline_id"]
    tagged = _json("tag", pipeline, "reviewed=yes", "night=1", "--store", str(store))
    assert tagged["tags"] == {"night": "1", "reviewed": "yes"}
    assert _tree_digests(store) == before
    for run in _json("runs", "--store", str(store))["runs"]:
        assert _invoke("verify", run["run_id"], "--store", str(store)).exit_code == 0
    where = _json(
        "runs", "--where", "json_extract_string(tags, '$.reviewed') = 'yes'", "--store", str(store)
    )
    assert [r["id"] for r in where["rows"]] == [pipeline]
    bad = _invoke("tag", pipeline, "no spaces=x", "--store", str(store))
    assert bad.exit_code == 2 and "tag name" in bad.output
    unknown = _invoke("tag", "0123456789abcdef", "a=b", "--store", str(store))
    assert unknown.exit_code == 2 and "no run, pipeline result, plan" in unknown.output


def test_history_survives_a_pruned_child_run_and_lineage_says_it_is_gone(nights, tmp_path):
    store = tmp_path / "runs"
    shutil.copytree(nights["store"], store)
    plan = nights["plans"][-1].relative_to(nights["store"])
    clean = _json("lineage", str(store / plan), "--store", str(store))
    assert clean["clean"]
    steps = [link["step"] for link in clean["links"]]
    assert steps[:3] == ["element set", "launch fit", "DoE run"] and steps[-1] == "plan"
    assert any(s.startswith("child run") for s in steps)
    assert any(s.startswith("surrogates") for s in steps)
    # A child run deleted (what prune does to a superseded one) and a file of the DoE
    # run changed: the history keeps its rows, lineage names both links.
    child = next(link["item"] for link in clean["links"] if link["step"].startswith("child"))
    doe = next(link["item"] for link in clean["links"] if link["step"] == "DoE run")
    shutil.rmtree(store / child)
    part = sorted((store / doe / "totals").glob("*.parquet"))[0]
    part.write_bytes(part.read_bytes() + b"\0")
    rows = _json("history", "--target-name", TARGET, "--store", str(store))["rows"]
    assert len(rows) == NIGHTS
    broken = _invoke("lineage", str(store / plan), "--store", str(store), "--json")
    assert broken.exit_code == 1
    links = {link["item"]: link for link in json.loads(broken.stdout)["links"]}
    assert links[child]["state"] == "missing" and "not in the store" in links[child]["detail"]
    assert links[doe]["state"] == "FAILED" and part.name in links[doe]["detail"]


def test_lineage_follows_an_export_back_to_its_plan(nights, tmp_path):
    plan = nights["plans"][-1]
    store = nights["store"]
    out = tmp_path / "plan.opm"
    done = _invoke("export", str(plan), "--format", "opm", "--out", str(out))
    assert done.exit_code == 0, done.output
    found = _json("lineage", str(out), "--store", str(store))
    export = [link for link in found["links"] if link["step"] == "export"]
    assert [link["path"] for link in export] == [str(out.resolve())]
    assert export[0]["state"] == "ok"
    out.write_text(out.read_text() + "COMMENT changed\n")
    changed = _invoke("lineage", str(plan), "--store", str(store), "--json")
    assert changed.exit_code == 1
    (link,) = [x for x in json.loads(changed.stdout)["links"] if x["step"] == "export"]
    assert link["state"] == "FAILED" and "changed since it was exported" in link["detail"]


def test_the_commands_run_as_a_user_runs_them(nights):
    """A subprocess, as a user types it: one line on a bad id, never a traceback."""
    env = dict(os.environ, OVTRAJ_HOME=str(nights["tmp"] / "home"))
    done = subprocess.run(
        [OVTRAJ, "diff", "nope", "0123456789abcdef", "--store", str(nights["store"])],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env=env,
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "'nope'" in done.stderr


def test_front_lists_the_verified_front_a_plan_was_picked_from(nights):
    """`ovtraj front RUN` shows the indices `--pick` takes: the plan's front point is the
    row of its front index, with the objectives the plan recorded from the front."""
    plan = json.loads(nights["plans"][-1].read_text())
    source = plan["source"]
    store = str(nights["store"])
    found = _json("front", source["doe_run"], "--pipeline", source["pipeline_id"], "--store", store)
    stored = pd.read_parquet(found["front"])
    assert found["pipeline_id"] == source["pipeline_id"] and len(found["points"]) == len(stored)
    (point,) = [p for p in found["points"] if p["front_index"] == source["front_index"]]
    assert point["sample_id"] == source["sample_id"]
    assert {k: point[k] for k in source["front_objectives"]} == source["front_objectives"]
    shown = _invoke("front", source["doe_run"], "--store", store)
    assert shown.exit_code == 0, shown.output
    rows = [line for line in shown.stdout.splitlines() if re.match(r"^ +\d+ +\d+ ", line)]
    assert len(rows) == len(stored)
    missing = _invoke("front", "0123456789abcdef", "--store", store)
    assert missing.exit_code == 2 and len(missing.stderr.strip().splitlines()) == 1
