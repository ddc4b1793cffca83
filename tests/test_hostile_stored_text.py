"""What the commands do with hostile text read from files: ids that climb out of the store,
terminal control sequences and huge values in stored names and tags, weights that overflow.

- An id read from a file (a plan's ``source``, a pipeline summary's rounds) is checked as
  one typed on the command line: 16 hex digits, and the folder it names inside the store
  (a link out of the store is refused too). ``ovtraj lineage`` ends with one line naming
  the file and the field, exit 2, and opens nothing outside the store: the files a
  command opens are listed by an audit hook (:func:`sys.addaudithook`, every ``open`` and
  directory listing of this process, links resolved), and a guard folder beside the
  store holds what each hostile id points to.
- A stored text (a scenario name, a field name, a tag) in a command's plain output is
  escaped (a newline shows as ``\\n``, ESC as ``\\x1b``), cut to ``shown_max_chars``
  (configs/io_limits.yaml) and never taken as rich markup.
- ``--weights 1e308,1e308,1e308`` weighs as ``1,1,1``.

The commands run in this process (:func:`ovtraj.cli.run_command`, the entry point's body).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ovtraj.cli import run_command
from ovtraj.config.io_limits import io_limits
from ovtraj.optimize import Normalisation
from ovtraj.pipeline import Pick, pick_front_point
from ovtraj.pipeline.pick import weight_fractions
from ovtraj.pipeline.report import pick_explanation
from ovtraj.store.layout import is_id
from tests.conftest import DEFAULT_SCENARIO

DOE_ID = "0123456789abcdef"
PIPELINE_ID = "89abcdef01234567"
LINKED_ID = "fedcba9876543210"
HOSTILE_NAME = "evil\x1b[2J\x1b]0;pwned\x07\nFORGED LINE [bold]x[/] " + "y" * 1000


# --- the files this process opens ------------------------------------------------------

_opened: list[str] | None = None


def _audit(event: str, args: tuple) -> None:
    if _opened is not None and event in ("open", "os.listdir", "os.scandir") and args:
        path = args[0]
        if isinstance(path, str | bytes | os.PathLike):
            _opened.append(os.path.realpath(os.fsdecode(path)))


sys.addaudithook(_audit)  # cannot be removed; records only while a test listens


def _command(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str, str, list[str]]:
    """``ovtraj ARGS`` in this process: exit code, stdout, stderr, the files it opened."""
    global _opened
    capsys.readouterr()
    _opened = []
    try:
        code = run_command(list(args))
    finally:
        opened, _opened = _opened, None
    out, err = capsys.readouterr()
    return code, out, err, opened


def _one_line_error(code: int, out: str, err: str) -> str:
    assert code == 2, (code, out, err)
    assert out == "", out
    assert "Traceback" not in err and "internal error" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def _plain(text: str) -> None:
    """No control character but the line ends (the terminal is sent no sequence)."""
    controls = sorted({c for c in text if not c.isprintable() and c != "\n"})
    assert not controls, controls


# --- the plans ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def plan(reference_plan_file) -> dict:
    """A real plan (the chain evaluated at a feasible design), as JSON data."""
    return json.loads(reference_plan_file.read_text())


@pytest.fixture
def workspace(tmp_path, monkeypatch) -> Path:
    """``tmp_path``: the workspace (OVTRAJ_HOME ``home/``), an empty run store
    ``store/``, and beside it ``outside/``, what the hostile ids point to."""
    for name in ("home", "store", "outside"):
        (tmp_path / name).mkdir()
    monkeypatch.setenv("OVTRAJ_HOME", str(tmp_path / "home"))
    return tmp_path


def _plan_file(ws: Path, plan: dict, name: str, **source: object) -> Path:
    path = ws / f"{name}.json"
    path.write_text(json.dumps({**plan, "source": source}))
    return path


def _guard(ws: Path) -> None:
    """``outside/``: what each hostile id reaches, each file a complete product or run
    document, so that a reader that follows the id finds something to read and verify."""
    out = ws / "outside"
    (out / "fakepipe").mkdir()
    # A pipeline result whose rounds name a child run: followed, it adds links to the output.
    summary = {"files": {}, "pipeline_id": "x", "iterations": [{"iteration": 7}]}
    (out / "fakepipe" / "pipeline.json").write_text(json.dumps(summary))
    (out / "fakefit").mkdir()
    (out / "fakefit" / "meta.json").write_text(json.dumps({"files": {}}))
    (out / "fakedoe").mkdir()
    (out / "fakedoe" / "manifest.json").write_text(json.dumps({"run_id": LINKED_ID}))
    (out / "fakedoe" / "config.json").write_text("{}")
    # What a store folder that is a link leads to: a pipeline result (no manifest: the
    # catalog does not take it for a run; the lineage would read it as the plan's).
    (out / "linked" / "pipeline" / PIPELINE_ID).mkdir(parents=True)
    (out / "linked" / "pipeline" / PIPELINE_ID / "pipeline.json").write_text(json.dumps(summary))


# (the plan's source, what the one line says: the file and the field)
LINEAGE_CASES = {
    "pipeline id climbing out": (
        {"doe_run": DOE_ID, "pipeline_id": "../../../outside/fakepipe"},
        "plan.json: source.pipeline_id '../../../outside/fakepipe' is not an id",
    ),
    "DoE run id climbing out": (
        {"doe_run": "../outside/fakedoe", "pipeline_id": PIPELINE_ID},
        "plan.json: source.doe_run '../outside/fakedoe' is not an id",
    ),
    "control characters": (
        {"doe_run": "a\nb\x1b[31m"},
        "plan.json: source.doe_run 'a\\nb\\x1b[31m' is not an id",
    ),
    "a store folder linked outside": (
        {"doe_run": LINKED_ID, "pipeline_id": PIPELINE_ID},
        f"plan.json: source.doe_run: {{store}}/{LINKED_ID} leads outside the store",
    ),
    "a stored round's fit id climbing out": (
        {"doe_run": DOE_ID, "pipeline_id": PIPELINE_ID},
        "pipeline.json: iterations[0].fit_id '../../../outside/fakefit' is not an id",
    ),
}


def _hostile_store(ws: Path) -> Path:
    """The store: a DoE run's folder and pipeline result (so that ``..`` from them
    resolves), the result's round naming a fit outside, a run folder linked outside."""
    store = ws / "store"
    _guard(ws)
    pipeline = store / DOE_ID / "pipeline" / PIPELINE_ID
    pipeline.mkdir(parents=True)
    (store / DOE_ID / "surrogates").mkdir()
    rounds = [{"iteration": 1, "run_id": DOE_ID, "fit_id": "../../../outside/fakefit"}]
    summary = {"files": {}, "pipeline_id": PIPELINE_ID, "iterations": rounds}
    (pipeline / "pipeline.json").write_text(json.dumps(summary))
    (store / LINKED_ID).symlink_to(ws / "outside" / "linked")
    return store


@pytest.mark.parametrize("case", LINEAGE_CASES)
def test_lineage_refuses_an_id_from_a_file_that_leaves_the_store(workspace, plan, case, capsys):
    ws = workspace
    store = _hostile_store(ws)
    source, expected = LINEAGE_CASES[case]
    path = _plan_file(ws, plan, "plan", **source)
    code, out, err, opened = _command(capsys, "lineage", str(path), "--store", str(store))
    line = _one_line_error(code, out, err)
    assert expected.format(store=store) in line, line
    _plain(line)
    assert [p for p in opened if Path(p).is_relative_to(ws / "outside")] == []


def test_lineage_follows_the_ids_of_the_store(workspace, plan, capsys):
    ws = workspace
    store = _hostile_store(ws)
    path = _plan_file(ws, plan, "plan", doe_run=DOE_ID)
    code, out, err, opened = _command(capsys, "lineage", str(path), "--store", str(store))
    assert code == 1 and "DoE run" in out and "missing" in out, (out, err)  # not stored
    assert [p for p in opened if Path(p).is_relative_to(ws / "outside")] == []


def test_diff_shows_a_hostile_scenario_name_escaped_and_cut(workspace, plan, capsys):
    ws = workspace
    a = _plan_file(ws, plan, "a")
    hostile = {**plan, "scenario": {**plan["scenario"], "name": HOSTILE_NAME}}
    b = ws / "b.json"
    b.write_text(json.dumps(hostile))
    limit = io_limits().shown_max_chars
    for extra in ([], ["--md"]):
        code, out, err, _ = _command(
            capsys, "diff", str(a), str(b), "--store", str(ws / "store"), *extra
        )
        assert code == 0 and err == "", (code, err)
        _plain(out)
        assert not [line for line in out.splitlines() if line.startswith("FORGED")], out
        assert "evil\\x1b[2J\\x1b]0;pwned\\x07\\nFORGED LINE [bold]x[/] yyy" in out, out
        (row,) = [line for line in out.splitlines() if "scenario.name" in line]
        shown = row[row.index("evil") :].split("|")[0].strip()
        assert len(shown) == limit and "y...y" in shown, shown  # cut in the middle


@pytest.fixture(scope="module")
def hostile_run(tmp_path_factory) -> tuple[Path, str]:
    """A real 8-sample run of the shipped scenario renamed with a terminal escape, a
    newline and rich markup (a scenario's name is free text)."""
    ws = tmp_path_factory.mktemp("hostile_run")
    text = DEFAULT_SCENARIO.read_text()
    assert text.startswith("name: iss-like-rendezvous\n") or "\nname: iss-like-rendezvous\n" in text
    escaped = json.dumps(HOSTILE_NAME)  # a YAML double-quoted scalar
    scenario = ws / "scenario.yaml"
    scenario.write_text(text.replace("name: iss-like-rendezvous\n", f"name: {escaped}\n", 1))
    store = ws / "store"
    before = os.environ.get("OVTRAJ_HOME")
    os.environ["OVTRAJ_HOME"] = str(ws / "home")
    try:
        code = run_command(["run", str(scenario), "--samples", "8", "--store", str(store)])
    finally:
        if before is None:
            os.environ.pop("OVTRAJ_HOME")
        else:
            os.environ["OVTRAJ_HOME"] = before
    assert code == 0
    (run_id,) = [p.name for p in store.iterdir() if is_id(p.name)]
    return store, run_id


def test_runs_shows_a_hostile_scenario_name_escaped_and_cut(hostile_run, capsys):
    store, run_id = hostile_run
    limit = io_limits().shown_max_chars
    for extra in ([], ["--where", "kind = 'run'"]):
        code, out, err, _ = _command(capsys, "runs", "--store", str(store), *extra)
        assert code == 0 and "Traceback" not in err and "internal error" not in err, err
        _plain(out)
        assert not [line for line in out.splitlines() if line.startswith("FORGED")], out
        (row,) = [line for line in out.splitlines() if run_id in line]
        assert "evil\\x1b[2J\\x1b]0;pwned\\x07\\nFORGED LINE [bold]x[/] yyy" in row, row
        shown = row[row.index("evil") :].split("  ")[0]
        assert len(shown) == limit and "y...y" in shown, shown


def test_a_hostile_tag_file_is_never_printed_whole_nor_raw(hostile_run, tmp_path, capsys):
    store, run_id = hostile_run
    tags = store / "catalog" / "tags" / f"{run_id}.json"
    tags.parent.mkdir(parents=True, exist_ok=True)
    try:
        for value in ("z" * 5_000_000, "a\x1b[2J\nFORGED"):
            tags.write_text(json.dumps({"id": run_id, "tags": {"note": value}}))
            code, out, err, _ = _command(capsys, "tag", run_id, "--store", str(store))
            assert "Traceback" not in err and "internal error" not in err, err
            # the item's tags on one line, or one line naming the file that holds them
            assert len((out + err).strip().splitlines()) == 1, (out + err)[:500]
            assert len(out + err) < 1000, len(out + err)
            _plain(out + err)
            assert code == 2 and str(tags) in err if code else out.startswith(f"{run_id}: note=")
    finally:
        tags.unlink()


def test_weights_of_1e308_pick_the_point_weights_1_1_1_pick(scenario):
    norm = Normalisation.mission(scenario.mission.optimize)
    front = pd.DataFrame(  # equal weights pick point 1: an overflow picked point 0
        {
            "front_index": [0, 1, 2],
            "sample_id": [9, 7, 3],
            "t_total_s": [430000.0, 260000.0, 340000.0],
            "dv_total_mps": [200.0, 290.0, 230.0],
            "m_load_kg": [392.0, 409.0, 400.0],
        }
    )
    equal = Pick(weights=(1.0, 1.0, 1.0))
    huge = Pick(weights=(1e308, 1e308, 1e308))
    picked = pick_front_point(front, norm, equal)
    assert picked["front_index"] == 1
    assert pick_front_point(front, norm, huge)["front_index"] == 1
    text = pick_explanation(front, norm, huge, picked)
    score = pick_explanation(front, norm, equal, picked).rsplit("score ", 1)[1]
    assert text.rsplit("score ", 1)[1] == score != "0.0000"
    # the proportions stay: 1e308 twice and 2e308 weigh as 1, 1, 2
    fractions = weight_fractions(np.array([1e308, 1e308, 1e308]) * [0.5, 0.5, 1.0])
    assert fractions.tolist() == [0.25, 0.25, 0.5]


def test_history_refuses_a_catalog_row_whose_id_is_not_an_id(tmp_path):
    from ovtraj.store.files import StoreError
    from ovtraj.tracking.catalog import Catalog
    from ovtraj.tracking.catalog_schema import SCHEMA
    from ovtraj.tracking.history import history

    row = dict.fromkeys(SCHEMA.names)
    row.update(kind="plan", id=PIPELINE_ID, source="x", source_sha256="-", tags="{}")
    row.update(target="t", doe_run=DOE_ID, run_id=DOE_ID, pipeline_id=PIPELINE_ID)
    path = tmp_path / "catalog" / "catalog.parquet"

    def catalog(**values: object) -> Catalog:
        frame = pd.DataFrame([{**row, **values}], columns=SCHEMA.names, dtype=object)
        return Catalog(frame, path)

    assert history(catalog())["plan_id"].tolist() == [PIPELINE_ID]
    for column, value in (("pipeline_id", "../../x"), ("doe_run", "a\nb"), ("id", "..")):
        with pytest.raises(StoreError) as raised:
            history(catalog(**{column: value}))
        shown = "plan_id" if column == "id" else column
        assert str(raised.value).startswith(f"{path}: {shown} {value!r} is not an id"), raised
