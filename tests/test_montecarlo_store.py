"""The stored plan Monte Carlo: `ovtraj fly PLAN --monte-carlo N` and the plan Monte Carlo
flow run one driver and study (ovtraj.store.monte_carlo, ovtraj.runs.plan_monte_carlo), so
they store the same run; the run is catalogued, fills the history's Monte Carlo columns, and
carries its pictures.

The plans are the session's re-plan nights (tests/conftest.py:replan_nights), stored by
real pipelines; the Monte Carlo flies three runs of the J2 sky (the cheapest).
"""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import pytest
import yaml
from PIL import Image
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.mission.montecarlo_outcome import MANOEUVRES
from ovtraj.mission.montecarlo_statistics import planned_dv
from ovtraj.mission.montecarlo_store import PlanMonteCarloRun
from ovtraj.mission.plan_store import read_plan
from ovtraj.paths import config_path
from ovtraj.plots.render import png_bytes
from ovtraj.runs.plan_monte_carlo import PICTURES, monte_carlo_figures
from ovtraj.store.environment_block import unstamped
from ovtraj.tracking.catalog_rows import plan_id
from tests.conftest import replan_nights

# minutes: the session's re-plan nights (shared), then flights
pytestmark = pytest.mark.slow

RUNS, SEED, BATCH = 3, 2, 2  # two batches: runs 0-1 and 2
runner = CliRunner()


@pytest.fixture(scope="module")
def nights(tmp_path_factory):
    """The session's re-plan nights, their workspace (the launch fits) as OVTRAJ_HOME."""
    found = replan_nights(tmp_path_factory)
    saved = os.environ.get("OVTRAJ_HOME")
    os.environ["OVTRAJ_HOME"] = str(found["home"])
    try:
        yield found
    finally:
        if saved is None:
            os.environ.pop("OVTRAJ_HOME", None)
        else:
            os.environ["OVTRAJ_HOME"] = saved


def _dispersions(folder: Path, store: Path, **execution) -> Path:
    """The shipped dispersions with the Monte Carlo's store and batches set."""
    data = yaml.safe_load(config_path("dispersions.yaml").read_text())
    data["execution"].update(store=str(store), batch_size=BATCH, **execution)
    path = folder / f"dispersions-{store.name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _fly(plan: Path, dispersions: Path, *options: str):
    done = runner.invoke(
        app,
        ["fly", str(plan), "--monte-carlo", str(RUNS), "--seed", str(SEED),
         "--dispersions", str(dispersions), *options],
    )  # fmt: skip
    assert done.exit_code in (0, 1), done.output  # 1: the nominal replay missed, not a fault
    return done


def _files(directory: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(directory)): p.read_bytes()
        for p in sorted(directory.rglob("*"))
        if p.is_file() and p.suffix != ".lock" and "locks" not in p.relative_to(directory).parts
    }


def _record(payload: bytes, *drop: str) -> dict:
    """A JSON record without its environment block and the keys that say when and how
    long (the host's, never the results')."""
    return {k: v for k, v in unstamped(json.loads(payload)).items() if k not in drop}


def test_the_command_and_the_flow_store_the_same_run(prefect_server, nights, tmp_path):
    from flows.mission_monte_carlo import plan_monte_carlo_flow

    plan = nights["plans"][-1]
    theirs = _dispersions(tmp_path, tmp_path / "flow", workers=2, task_runner="threads")
    flown = plan_monte_carlo_flow(str(plan), dispersions=str(theirs), runs=RUNS, seed=SEED)
    done = _fly(plan, _dispersions(tmp_path, tmp_path / "command"), "--json")
    mc = json.loads(done.stdout)["monte_carlo"]
    # One run id for the same plan, dispersions, seed and runs; each where its store is.
    assert mc["run_id"] == flown["run_id"]
    assert mc["directory"] == str(tmp_path / "command" / mc["run_id"])
    assert flown["directory"] == str(tmp_path / "flow" / mc["run_id"])
    assert mc["simulated_runs"] == flown["simulated_runs"] == RUNS
    assert mc["status"] == flown["status"] == "complete" and mc["stored_runs"] == RUNS
    ours, theirs = _files(Path(mc["directory"])), _files(Path(flown["directory"]))
    assert (
        sorted(ours)
        == sorted(theirs)
        == sorted(
            [
                "config.json",
                "run.json",
                "summary.json",
                "batches/00000.json",
                "batches/00002.json",
                "runs/part-00000.parquet",
                "runs/part-00002.parquet",
                *(f"plots/{name}.png" for name in PICTURES),
            ]
        )
    )
    # The data byte for byte: the rows, the config, the summary and the pictures.
    for name in ours:
        if name.endswith((".parquet", ".png")) or name in ("config.json", "summary.json"):
            assert ours[name] == theirs[name], name
    # The records too, but for when they were written and how long each run took.
    assert _record(ours["run.json"], "created_utc") == _record(theirs["run.json"], "created_utc")
    for marker in ("batches/00000.json", "batches/00002.json"):
        assert _record(ours[marker], "timing") == _record(theirs[marker], "timing")
    # What both return is the stored summary plus where it is and what this pass flew.
    added = {"directory", "simulated_runs", "plots", "failed_batches"}
    stored = json.loads(ours["summary.json"])
    assert {k: v for k, v in mc.items() if k not in added} == stored
    assert {k: v for k, v in flown.items() if k not in added} == stored
    assert mc["plots"] == [str(Path(mc["directory"]) / "plots" / f"{n}.png") for n in PICTURES]
    # The command again: nothing to fly, nothing stored changes (the same bytes).
    again = json.loads(_fly(plan, _dispersions(tmp_path, tmp_path / "command"), "--json").stdout)
    assert again["monte_carlo"]["simulated_runs"] == 0
    assert _files(Path(mc["directory"])).keys() == ours.keys()
    assert {k: v for k, v in _files(Path(mc["directory"])).items() if k != "run.json"} == {
        k: v for k, v in ours.items() if k != "run.json"
    }


def test_a_stored_command_monte_carlo_is_catalogued_and_fills_the_history(nights, tmp_path):
    store = tmp_path / "store"
    shutil.copytree(nights["store"], store)
    plan = store / nights["plans"][-1].relative_to(nights["store"])
    done = _fly(plan, _dispersions(tmp_path, store))
    # Where it is stored, said as an absolute path, and its pictures.
    (line,) = [x for x in done.stdout.splitlines() if x.startswith("monte carlo run ")]
    run_id = line.split()[3]
    directory = store / run_id
    assert line == f"monte carlo run {run_id} (flown now): {directory}"
    shown = [x.split("picture: ", 1)[1] for x in done.stdout.splitlines() if "picture: " in x]
    assert shown == [str(directory / "plots" / f"{name}.png") for name in PICTURES]
    summary = json.loads((directory / "summary.json").read_text())
    assert summary["run_id"] == run_id and summary["runs"] == RUNS
    # `ovtraj runs` lists it after the DoE runs, with its plan and figures, and the
    # catalog's query finds it.
    identity = plan_id(json.loads(plan.read_text()))
    listed = runner.invoke(app, ["runs", "--store", str(store), "--json"])
    assert listed.exit_code == 0, listed.output
    (entry,) = json.loads(listed.stdout)["monte_carlo"]
    assert entry["run_id"] == run_id and entry["plan_id"] == identity
    assert entry["status"] == "complete" and entry["runs"] == RUNS and entry["size_bytes"] > 0
    assert entry["dv_margin_p95_mps"] == summary["dv_mps"]["total"]["p95_minus_planned"]
    table = runner.invoke(app, ["runs", "--store", str(store)]).stdout.splitlines()
    assert table[-1] == "1 plan Monte Carlo run; its pictures in RUN/plots/"
    assert f" {identity}  complete  {RUNS} " in next(x for x in table if x.startswith(run_id))
    listed = runner.invoke(
        app, ["runs", "--store", str(store), "--where", "kind = 'monte_carlo'", "--json"]
    )
    assert listed.exit_code == 0, listed.output
    (row,) = json.loads(listed.stdout)["rows"]
    assert row["id"] == run_id and row["status"] == "complete" and row["error"] is None
    assert row["plan_id"] == identity and row["mc_runs"] == RUNS
    # The history's Monte Carlo columns: filled on that plan's row, from its summary.
    found = runner.invoke(app, ["history", "--store", str(store), "--json"])
    assert found.exit_code == 0, found.output
    rows = {r["plan_id"]: r for r in json.loads(found.stdout)["rows"]}
    assert len(rows) == len(nights["plans"])
    mine = rows.pop(identity)
    assert mine["mc_runs"] == RUNS
    assert mine["mc_landing_miss_p95_m"] == (summary["landing_miss_m"] or {}).get("p95")
    assert mine["mc_dv_margin_p95_mps"] == summary["dv_mps"]["total"]["p95_minus_planned"]
    assert mine["mc_dv_margin_p95_mps"] is not None
    assert all(r["mc_runs"] is None for r in rows.values())  # the other nights have none
    # Checked clean, pictures included (run.json lists their digests).
    checked = runner.invoke(app, ["verify", run_id, "--store", str(store)])
    assert checked.exit_code == 0 and checked.stdout.strip().endswith("clean"), checked.output
    _pictures_match_the_stored_run(PlanMonteCarloRun(directory), plan)
    # A picture changed on disk is found.
    footprint = directory / "plots" / "landing_footprint.png"
    footprint.write_bytes(footprint.read_bytes()[:-1] + b"\0")
    checked = runner.invoke(app, ["verify", run_id, "--store", str(store)])
    assert checked.exit_code == 1 and str(footprint) in checked.stdout, checked.output


def _pictures_match_the_stored_run(run: PlanMonteCarloRun, plan_file: Path) -> None:
    """The stored PNGs are the figures drawn from the stored run again, and those figures
    plot the stored rows: a point per landed run, a histogram per loop and manoeuvre
    counting the runs that flew it, the plan's dV marked."""
    frame = run.results()
    figures = monte_carlo_figures(run)
    for name in PICTURES:
        payload = (run.directory / "plots" / f"{name}.png").read_bytes()
        with Image.open(io.BytesIO(payload)) as image:
            image.verify()  # a whole PNG
            assert image.format == "PNG"
        assert payload == png_bytes(figures[name]), name
    every, near = figures["landing_footprint"].axes
    for ax in (every, near):
        scatters = {c.get_label().split(":")[0]: c for c in ax.collections}
        for loop in ("closed", "open"):
            rows = frame[frame["loop"] == loop]
            landed = rows[rows["landed"].astype(bool)]
            points = scatters[f"{loop} loop"]
            assert len(points.get_offsets()) == len(landed)
            assert points.get_label() == f"{loop} loop: {len(landed)} of {len(rows)} landed"
    # Each point lies its run's landing miss from the site (the projection keeps distances
    # from the site), in run order; the closed loop lands.
    closed = {c.get_label().split(":")[0]: c for c in near.collections}["closed loop"]
    distances = [float((x * x + y * y) ** 0.5) for x, y in closed.get_offsets()]
    misses = frame[(frame["loop"] == "closed") & frame["landed"]]["landing_miss_m"] / 1e3
    assert len(distances) > 0 and distances == pytest.approx(misses.tolist(), rel=1e-9)
    # The stated miss drawn is the plan's.
    stated_km = read_plan(plan_file).terminal.stated_miss_m / 1e3
    (circle,) = [p for p in near.patches if p.get_label().startswith("stated miss")]
    assert circle.get_radius() == stated_km
    planned = planned_dv(read_plan(plan_file))
    panels = {ax.get_title(): ax for ax in figures["dv_per_manoeuvre"].axes if ax.get_visible()}
    assert list(panels) == [*MANOEUVRES, "total"]
    for name, column in [*MANOEUVRES.items(), ("total", "dv_total_mps")]:
        ax = panels[name]
        (line,) = [x for x in ax.get_lines() if x.get_label().startswith("planned")]
        assert line.get_xdata()[0] == planned[name]
        bars = {c.patches[0].get_label().split(" (")[0]: c for c in ax.containers}
        for loop in ("closed", "open"):
            flew = int(frame[frame["loop"] == loop][column].notna().sum())
            assert sum(p.get_height() for p in bars[f"{loop} loop"]) == flew, (name, loop)
