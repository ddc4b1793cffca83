"""``ovtraj fly PLAN`` and ``ovtraj fly PLAN --fidelity high`` store their flight beside a
plan of a run store and write the plan's report again with it.

On a copy of the re-plan nights' store (tests/conftest.py:replan_nights), under a store key
(the plan's marker sealed with it first, as a store written under the key has it), the two
commands run as a user runs them: each flight is stored once, sealed, without its timing,
listed in the plan's marker (``ovtraj verify`` passes), and the report's section of flights
holds both flights' figures as ``--json`` printed them. Flown again, nothing new is
stored; flown by another code version, the stored flight is kept, the new one printed but
not stored (one line on stderr, the flight's own exit code); a plan outside a store stores
nothing.
"""

from __future__ import annotations

import hashlib
import json
import re
import secrets
import shutil
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.mission.plan_store import read_plan
from ovtraj.pipeline.plan_flights import flight_document
from ovtraj.pipeline.report import FLOWN_END, FLOWN_START, flown_section
from ovtraj.store.files import file_digest, read_json
from ovtraj.store.seals import STORE_KEY_ENV, seal_problem, write_sealed
from tests.conftest import replan_nights

# minutes: the session's re-plan nights (shared), then flights
pytestmark = pytest.mark.slow

KEY = secrets.token_hex(32)
runner = CliRunner()


def _folder_bytes(folder: Path) -> dict[str, str]:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir() if p.is_file()
    }


def _fly(plan: Path, *args: str) -> Any:
    return runner.invoke(app, ["fly", str(plan), *args, "--json"])


def _said(result: Any) -> dict[str, str]:
    """The ``what: path`` lines fly wrote on stderr (with --json)."""
    return dict(line.split(": ", 1) for line in result.stderr.splitlines() if ": /" in line)


@pytest.fixture(scope="module")
def flown(tmp_path_factory) -> dict[str, Any]:
    nights = replan_nights(tmp_path_factory)
    store = tmp_path_factory.mktemp("flights") / "runs"
    shutil.copytree(nights["store"], store)
    plan = store / nights["plans"][-1].relative_to(nights["store"])
    folder = plan.parent
    original_report = (folder / f"{plan.stem}-report.html").read_text(encoding="utf-8")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(STORE_KEY_ENV, KEY)
        marker = folder / f"{plan.stem}.files.json"
        write_sealed(marker, read_json(marker), replace=True)  # as a keyed store has it
        j2 = _fly(plan)
        high = _fly(plan, "--fidelity", "high")
    return {
        "store": store,
        "plan": plan,
        "folder": folder,
        "original_report": original_report,
        "j2": j2,
        "high": high,
    }


def _row(result: Any) -> dict[str, Any]:
    row = json.loads(result.stdout)
    assert result.exit_code == (0 if row["landed_within_stated_miss"] else 1), result.output
    return row


def _section(text: str) -> str:
    start = text.index(FLOWN_START)
    return text[start : text.index(FLOWN_END, start) + len(FLOWN_END)]


def test_each_flight_is_stored_sealed_without_timing_and_listed(flown, monkeypatch):
    monkeypatch.setenv(STORE_KEY_ENV, KEY)
    folder, stem = flown["folder"], flown["plan"].stem
    marker_path = folder / f"{stem}.files.json"
    marker = json.loads(marker_path.read_text())
    assert seal_problem(marker_path, marker) is None
    for fidelity in ("j2", "high"):
        result = flown[fidelity]
        row = _row(result)
        path = folder / f"{stem}-flight-{fidelity}.json"
        said = _said(result)
        assert said["flight stored"] == str(path) and Path(said["flight stored"]).is_absolute()
        assert said["report"] == str(folder / f"{stem}-report.html")
        stored = json.loads(path.read_text())
        assert "hmac" in stored and seal_problem(path, stored) is None
        content = {k: v for k, v in stored.items() if k != "hmac"}
        assert "wall_time_s" not in content  # timing is no content
        assert content == flight_document(row)
        assert marker["files"][path.name] == file_digest(path).to_json()
    high = json.loads((folder / f"{stem}-flight-high.json").read_text())
    assert high["force_model_file"] == "force_model.yaml"  # where it was read is the machine's
    j2 = json.loads((folder / f"{stem}-flight-j2.json").read_text())
    assert {k: v for k, v in _row(flown["j2"]).items() if k != "wall_time_s"} == {
        k: v for k, v in j2.items() if k != "hmac"
    }


def test_verify_passes_with_the_flights(flown):
    plan = read_plan(flown["plan"])
    for item in (plan.source["pipeline_id"], plan.source["doe_run"]):
        done = runner.invoke(app, ["verify", item, "--store", str(flown["store"]), "--json"])
        assert done.exit_code == 0, done.output
        report = json.loads(done.stdout)
        assert report["clean"], report
        assert not [p for p in report["uncovered"] if "-flight-" in p], report["uncovered"]


def test_the_flights_bring_their_plans_catalog_row_up_to_date(flown):
    """A flight rewrites its plan's marker and refreshes that catalog row: the stamp the
    catalog records for the marker is the marker's as it is now (the next refresh does not
    read it again)."""
    from ovtraj.tracking.catalog_sources import stamp_of

    store = flown["store"]
    stamps = json.loads((store / "catalog" / "stamps.json").read_text(encoding="utf-8"))
    marker = flown["folder"] / f"{flown['plan'].stem}.files.json"
    assert stamps[marker.relative_to(store).as_posix()] == stamp_of([str(marker)])


def test_the_report_shows_both_flights_as_printed(flown):
    folder, stem = flown["folder"], flown["plan"].stem
    plan = read_plan(flown["plan"])
    text = (folder / f"{stem}-report.html").read_text(encoding="utf-8")
    j2, high = _row(flown["j2"]), _row(flown["high"])
    # The section of flights is the one write_report draws for the stored flights; the
    # rest of the report is the plan's, as it was.
    section = _section(text)
    assert section == flown_section([flight_document(j2), flight_document(high)], plan)
    original = flown["original_report"]
    assert "No flight of this plan is stored" in _section(original)
    assert text == original.replace(_section(original), section)
    # Figures of each flight in its table, as --json printed them.
    tables = re.findall(r"<table>.*?</table>", section, flags=re.S)
    assert len(tables) == 2

    def cell(table: str, quantity: str, column: int) -> float:
        row = re.search(f"<tr><td>{re.escape(quantity)}</td>(.*?)</tr>", table, flags=re.S)
        assert row, f"no row {quantity!r}"
        return float(re.findall(r"<td>(.*?)</td>", row.group(1))[column])

    assert cell(tables[0], "landing miss", 1) == pytest.approx(
        j2["miss_distance_m"] / 1e3, rel=1e-3
    )
    assert cell(tables[0], "dV_total", 1) == pytest.approx(
        sum(burn["dv_mps"] for burn in j2["burns"]), rel=1e-3
    )
    flown_high = high["closed_loop_high_fidelity"]
    assert cell(tables[1], "dV_total", 2) == pytest.approx(flown_high["dv_total_mps"], rel=1e-3)
    assert cell(tables[1], "dV_total", 1) == pytest.approx(
        high["closed_loop_j2"]["dv_total_mps"], rel=1e-3
    )


def test_flying_again_stores_nothing_new(flown, monkeypatch):
    monkeypatch.setenv(STORE_KEY_ENV, KEY)
    folder = flown["folder"]
    before = _folder_bytes(folder)
    for args in ((), ("--fidelity", "high")):
        again = _fly(flown["plan"], *args)
        assert json.loads(again.stdout)["landed_within_stated_miss"] in (True, False)
        assert "flight already stored" in _said(again), again.stderr
    assert _folder_bytes(folder) == before


def test_another_code_versions_flight_is_not_stored_and_nothing_is_overwritten(flown, monkeypatch):
    monkeypatch.setenv(STORE_KEY_ENV, KEY)
    monkeypatch.setattr("ovtraj.mission.fly.code_version", lambda: "0.0.0+gother")
    folder = flown["folder"]
    before = _folder_bytes(folder)
    refused = _fly(flown["plan"])
    landed = json.loads(refused.stdout)["landed_within_stated_miss"]
    assert refused.exit_code == (0 if landed else 1), refused.output
    assert json.loads(refused.stdout)["replay_code_version"] == "0.0.0+gother"  # still printed
    line = refused.stderr.strip()
    assert "\n" not in line and "not overwritten" in line and "0.0.0+gother" in line
    assert str(folder / f"{flown['plan'].stem}-flight-j2.json") in line
    assert _folder_bytes(folder) == before


def test_a_plan_outside_a_store_stores_nothing(flown, tmp_path):
    plan = tmp_path / "plan.json"
    shutil.copyfile(flown["plan"], plan)
    done = _fly(plan)
    assert done.exit_code in (0, 1), done.output
    assert "this flight is not stored" in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.json"]
