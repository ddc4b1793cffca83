"""The launch-window scan: ``ovtraj window SCENARIO --days N`` and its flow.

A 3-day window of the default scenario with a small pipeline per day (a 12-sample DoE,
one infill round of two points, two regressors), on the process runner in a workspace
of its own: its best day must be the best of the days' own stored plans (scored here
from the plans' files and the scenario's ideal and reference points, not from the
window's table); a second scan simulates and writes nothing; days 1 and 2 fly the
shipped grid's launches, retimed, with no launch solved; the flow and the command give
the same rows. No day's loop converges (a 1e-6 error tolerance): the command exits 1
naming the days, the flow run ends Failed with the same line. The porkchop is each day's
plan swept and evaluated again by the chain, and its figure is drawn from the stored
tables. The launch-fit split is checked against the shipped reference fit and a launch
solved afresh on another day.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from ovtraj.cli import run_command
from ovtraj.launch.launch_fit import (
    day_launch_fit,
    design_of,
    find_launch_fit,
    find_launch_grid,
    launch_fit_key,
    launch_grid_key,
    retimed_launch_fit,
)
from ovtraj.window.days import day_scenario
from ovtraj.window.porkchop import PORKCHOP_SCHEMA
from ovtraj.window.report import WINDOW_SCHEMA
from tests.cli_runner import run_cli
from tests.conftest import DEFAULT_SCENARIO, REPO, build_scenario

# Left out of the fast tier (-m "not slow"): it scans a 3-day launch window, in the command and in
# its flow.
pytestmark = pytest.mark.slow

DAYS = 3
OVTRAJ = Path(sys.executable).with_name("ovtraj")


def _small(store: Path) -> dict:
    """The default scenario with a small pipeline per day (tests/test_pipeline.py's): one
    round judged by the error on the front (no promise tolerance: no fit after it), with a
    tolerance no day meets (none converges)."""
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data["mission"]["doe"].update(samples=12, batch_size=6, store=str(store))
    data["mission"]["verify"].update(
        points_per_iteration=2,
        max_iterations=1,
        budget=2,
        hypervolume_tolerance=None,
        promise_tolerance=None,
        tolerance=1e-6,
    )
    data["mission"]["surrogate"].update(
        regressors=["KRG", "RBF"], classifiers=["logistic"], folds=3
    )
    data["mission"]["optimize"].update(population=32, generations=40)
    return data


def _files(*roots: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``roots``: (size, modification time)."""
    found = {}
    for root in roots:
        for path in sorted(root.rglob("*")):
            if path.is_file():
                stat = path.stat()
                found[str(path)] = (stat.st_size, stat.st_mtime_ns)
    return found


@pytest.fixture(scope="module")
def scanned(tmp_path_factory):
    """The 3-day window scanned twice by the command (its own process, its own
    workspace): the outputs, the store's files between the two, the data."""
    tmp = tmp_path_factory.mktemp("window")
    home = tmp / "home"
    data = _small(tmp / "runs")
    config = tmp / "scenario.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    env = dict(os.environ, OVTRAJ_HOME=str(home))
    # Day 0 planned first by `ovtraj pipeline` (serial: the plan in the main process, its
    # BLAS with a thread per core); the window plans days 1 and 2 on the pool and must
    # find day 0's plan the same (before the plan was pinned to one BLAS thread, the
    # window refused it: "a different plan is stored there").
    pipeline = subprocess.run(
        [str(OVTRAJ), "pipeline", str(config), "--runner", "serial", "--json"],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    command = [str(OVTRAJ), "window", str(config), "--days", str(DAYS), "--runner", "processes"]
    first = subprocess.run(command, capture_output=True, text=True, env=env, timeout=900)
    before = _files(tmp / "runs", home)
    again = subprocess.run(
        [*command, "--json", "--allow-unconverged"],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    with pytest.MonkeyPatch.context() as patch:  # the workspace of the checks below
        patch.setenv("OVTRAJ_HOME", str(home))
        yield {
            "pipeline": pipeline,
            "first": first,
            "again": again,
            "before": before,
            "after": _files(tmp / "runs", home),
            "data": data,
            "config": config,
            "store": tmp / "runs",
            "home": home,
            "tmp": tmp,
        }


def _written(output: str, label: str) -> list[Path]:
    return [Path(line.split(": ", 1)[1]) for line in output.splitlines() if line.startswith(label)]


def test_the_command_writes_the_window_and_prints_its_absolute_paths(scanned):
    first = scanned["first"]
    assert first.returncode == 1, first.stderr  # no day converged (below)
    days = [line for line in first.stdout.splitlines() if re.match(r"day \d \d{4}-", line)]
    assert len(days) == DAYS  # a line per finished day
    paths = [
        p
        for label in ("table:", "plot:", "porkchop:", "page:", "window:")
        for p in _written(first.stdout, label)
    ]
    assert len(paths) == 8 and all(p.is_absolute() and p.is_file() for p in paths)
    assert {p.parent.parent for p in paths} == {scanned["store"] / "windows"}
    frame = pd.read_parquet(paths[0])
    assert list(frame.columns) == WINDOW_SCHEMA.names and list(frame["day"]) == [0, 1, 2]
    # The page links each day's report and plan, relatively, to files that exist.
    page = next(p for p in paths if p.suffix == ".html")
    links = re.findall(r"href='([^']+)'", page.read_text(encoding="utf-8"))
    reports = [link for link in links if link.endswith("-report.html")]
    assert len(reports) == DAYS and all(not link.startswith("/") for link in links)
    assert all((page.parent / link).resolve().is_file() for link in links)


def _score(objectives: dict, optimize: dict) -> float:
    """Equal weights on (value - ideal) / (reference - ideal) of each objective, from the
    scenario's own numbers (T in hours there, s in the plan)."""
    values = {
        "t_total_h": objectives["t_total_s"] / 3600.0,
        "dv_total_mps": objectives["dv_total_mps"],
        "m_load_kg": objectives["m_load_kg"],
    }
    ideal, reference = optimize["ideal"], optimize["reference"]
    return float(np.mean([(values[k] - ideal[k]) / (reference[k] - ideal[k]) for k in values]))


def test_the_best_day_is_the_best_of_the_days_own_plans(scanned):
    store = scanned["store"]
    plans = [
        json.loads(p.read_text(encoding="utf-8"))
        for p in sorted(store.glob("*/pipeline/*/plans/plan-*.json"))
        if not p.name.endswith(".files.json")
    ]
    by_date = {plan["launch_day_utc"][:10]: plan for plan in plans}
    assert len(plans) == DAYS and sorted(by_date) == ["2026-12-01", "2026-12-02", "2026-12-03"]
    optimize = scanned["data"]["mission"]["optimize"]
    scores = {
        date: _score(plan["source"]["front_objectives"], optimize) for date, plan in by_date.items()
    }
    best = min(scores, key=scores.get)
    assert f"best day: {best} " in scanned["first"].stdout
    frame = pd.read_parquet(_written(scanned["first"].stdout, "table:")[0])
    assert list(frame.loc[frame["best"], "date"]) == [best]
    for row in frame.itertuples(index=False):
        plan = by_date[row.date]
        front = plan["source"]["front_objectives"]
        assert row.score == pytest.approx(scores[row.date], rel=1e-12)
        assert row.dv_total_mps == front["dv_total_mps"] and row.m_load_kg == front["m_load_kg"]
        assert row.t_total_h == pytest.approx(front["t_total_s"] / 3600.0, rel=1e-15)
        assert row.plan.startswith(f"{plan['source']['doe_run']}/pipeline/")
        # The same target on every day: its elements at the campaign epoch, unchanged.
        assert plan["scenario"]["epoch_utc"] == scanned["data"]["epoch_utc"]
        assert (
            plan["scenario"]["target"]["orbit"]
            == build_scenario(scanned["data"]).resolved()["target"]["orbit"]
        )


def test_the_porkchop_is_each_days_plan_swept_and_drawn_from_the_store(scanned):
    """``porkchop.parquet``: each day's plan (its design in ``window.parquet``, the plan
    file's) with the configured variable at evenly spaced values over its bounds, each
    point the chain's own result (one evaluated again here); the figure written is the
    one the stored tables draw, its contours spanning the stored values and its markers
    at the stored plans, the best day's a star."""
    from matplotlib.dates import date2num

    from ovtraj.mission import DESIGN_NAMES, MissionContext
    from ovtraj.optimize import Normalisation
    from ovtraj.plots.render import png_bytes
    from ovtraj.runs.execute import evaluate_batch
    from ovtraj.window.porkchop import Sweep
    from ovtraj.window.report import porkchop_figure_of, svg_bytes
    from ovtraj.window.settings import load_window_settings

    written = {p.name: p for p in _written(scanned["first"].stdout, "porkchop:")}
    assert sorted(written) == ["porkchop.parquet", "porkchop.png", "porkchop.svg"]
    directory = written["porkchop.parquet"].parent
    marker = json.loads((directory / "window.json").read_text(encoding="utf-8"))
    window = pd.read_parquet(directory / "window.parquet")
    porkchop = pd.read_parquet(written["porkchop.parquet"])
    assert list(porkchop.columns) == PORKCHOP_SCHEMA.names
    base = build_scenario(scanned["data"])
    settings = load_window_settings().porkchop
    variable = settings.variable
    bounds = getattr(base.mission.design_bounds, variable)
    values = np.linspace(bounds.lower, bounds.upper, settings.points)
    assert marker["porkchop"] == {"variable": variable, "values": list(values)}
    plans = {
        json.loads(p.read_text(encoding="utf-8"))["launch_day_utc"][:10]: p
        for p in scanned["store"].glob("*/pipeline/*/plans/plan-*.json")
        if not p.name.endswith(".files.json")
    }
    assert len(porkchop) == DAYS * settings.points
    for row in window.itertuples(index=False):
        plan = json.loads(plans[row.date].read_text(encoding="utf-8"))
        design = {name: getattr(row, name) for name in DESIGN_NAMES}
        assert design == {name: plan["design"][name] for name in DESIGN_NAMES}
        day = porkchop[porkchop["day"] == row.day].sort_values("node")
        assert np.array_equal(day[variable], values)
        for name in DESIGN_NAMES:
            if name != variable:
                assert (day[name] == design[name]).all(), name
        record = json.loads(
            (directory / "days" / f"{row.day:04d}.json").read_text(encoding="utf-8")
        )
        sweep = record["sweep"]
        assert list(day["feasible"]) == sweep["feasible"]
        assert np.array_equal(
            day["dv_total_mps"], np.array(sweep["dv_total_mps"], dtype=float), equal_nan=True
        )
    # One feasible point of day 1 evaluated again by the chain on its day, as a batch is
    # (its BLAS threads pinned: the same last bits in any process).
    feasible = porkchop[(porkchop["day"] == 1) & porkchop["feasible"]].iloc[len(values) // 4]
    day1 = day_scenario(base, 1)
    (again,) = evaluate_batch(
        MissionContext(day1, day_launch_fit(day1)), feasible.to_frame().T[list(DESIGN_NAMES)]
    )
    assert again.feasible and again.dv_total_mps == feasible["dv_total_mps"]
    assert again.t_total_s / 3600.0 == pytest.approx(feasible["t_total_h"], rel=1e-15)
    # The figure: the stored tables draw the stored bytes (PNG first, as the window does).
    normalisation = Normalisation.mission(base.mission.optimize)
    title = (
        f"porkchop of {base.name}: 2026-12-01 to 2026-12-03 ({DAYS} days)\n"
        f"each day's plan with {variable} at {len(values)} values, the rest kept"
    )
    sweep = Sweep(variable, tuple(values))
    fig = porkchop_figure_of(window, porkchop, sweep, normalisation, title)
    assert png_bytes(fig) == written["porkchop.png"].read_bytes()
    assert svg_bytes(fig) == written["porkchop.svg"].read_bytes()
    panels = [ax for ax in fig.axes if any(line.get_gid() == "chosen" for line in ax.lines)]
    assert [ax.get_title() for ax in panels] == ["dV_total", "T_total"]
    best = window.loc[window["best"]].iloc[0]
    for ax, column in zip(panels, ("dv_total_mps", "t_total_h"), strict=True):
        (contours,) = [c for c in ax.collections if hasattr(c, "levels")]
        finite = porkchop[column].dropna()
        assert (contours.zmin, contours.zmax) == (finite.min(), finite.max())
        lines = {line.get_gid(): line for line in ax.lines}
        chosen, star = lines["chosen"], lines["best"]
        assert np.array_equal(chosen.get_xdata(), date2num(pd.to_datetime(window["date"])))
        assert np.array_equal(chosen.get_ydata(), window[variable])
        assert list(star.get_xdata()) == [date2num(pd.Timestamp(best["date"]))]
        assert list(star.get_ydata()) == [best[variable]]


def test_day_zero_is_the_scenario_itself(scanned):
    """Day 0's DoE run holds the scenario as ``ovtraj pipeline`` would store it (run ids
    hash the resolved config: unchanged by the window)."""
    from ovtraj.runs import RunStore

    frame = pd.read_parquet(_written(scanned["first"].stdout, "table:")[0])
    run = RunStore(scanned["store"]).run(frame.loc[frame["day"] == 0, "doe_run"].item())
    assert run.config == build_scenario(scanned["data"]).resolved()
    assert day_scenario(build_scenario(scanned["data"]), 0).resolved() == run.config


def test_day_zero_is_the_plan_the_pipeline_command_made(scanned):
    """The window's day 0 is ``ovtraj pipeline``'s plan, the same file (planned in
    another process with another BLAS thread count), and its verdict: not converged, exit
    1 there, the day's verdict in the window's JSON."""
    pipeline = scanned["pipeline"]
    assert pipeline.returncode == 1, pipeline.stderr
    printed = json.loads(pipeline.stdout)
    plan = Path(printed["plan_json"])
    frame = pd.read_parquet(_written(scanned["first"].stdout, "table:")[0])
    assert scanned["store"] / frame.loc[frame["day"] == 0, "plan"].item() == plan
    day0 = json.loads(scanned["again"].stdout)["rows"][0]
    assert printed["converged"] is False and printed["verdict"].startswith("not converged: ")
    assert (day0["converged"], day0["verdict"]) == (printed["converged"], printed["verdict"])


def test_days_that_did_not_converge_exit_1_named_on_one_line(scanned):
    """Exit 1, the line after the table naming every day (none converged), the table and
    the window written all the same; ``--allow-unconverged``: exit 0, the same verdict in
    the JSON, each day's own verdict in its row."""
    first = scanned["first"].stdout.splitlines()
    dates = ["2026-12-01", "2026-12-02", "2026-12-03"]
    expected = (
        f"not converged on 3 of 3 days: {', '.join(f'{d} (day {k})' for k, d in enumerate(dates))}"
    )
    assert expected in first
    assert first.index(expected) < first.index(next(x for x in first if x.startswith("table:")))
    summary = json.loads(scanned["again"].stdout)
    assert (summary["converged"], summary["verdict"]) == (False, expected)
    assert all(row["converged"] is False for row in summary["rows"])
    assert all(row["verdict"].startswith("not converged: ") for row in summary["rows"])


def test_a_second_scan_simulates_and_writes_nothing(scanned):
    again = scanned["again"]
    assert again.returncode == 0, again.stderr
    summary = json.loads(again.stdout)
    assert summary["reused"] is True and summary["planned_days"] == DAYS
    assert not re.search(r"^batch \d+/", again.stdout + again.stderr, flags=re.MULTILINE)
    assert scanned["after"] == scanned["before"]  # no file written, none removed
    frame = pd.read_parquet(summary["files"]["window.parquet"])
    assert summary["best_date"] == frame.loc[frame["best"], "date"].item()


def test_the_days_fly_the_shipped_grid_retimed(scanned):
    """No launch was solved: day 0 is the shipped reference fit, days 1 and 2 its grid
    flown on their days (the payload the same, the launch ~23 min earlier each day: the
    node regresses ~5 deg/day and the sidereal day is ~4 min short)."""
    base = build_scenario(scanned["data"])
    reference = find_launch_fit(base)
    assert reference is not None and find_launch_grid(base).key == reference.key
    stored = sorted(p.parent.name for p in (scanned["home"] / "launch_fit").glob("*/meta.json"))
    days = [day_scenario(base, d) for d in range(DAYS)]
    assert stored == sorted(launch_fit_key(day) for day in days[1:])
    assert launch_grid_key(days[1]) == launch_grid_key(base)
    h = np.linspace(210e3, 490e3, 5)
    previous = reference.series["insertion_time_s"](h)
    for day in days[1:]:
        fit = find_launch_fit(day)
        assert np.array_equal(fit.series["payload_kg"](h), reference.series["payload_kg"](h))
        times = fit.series["insertion_time_s"](h)
        assert np.all((previous - times > 1300.0) & (previous - times < 1500.0))
        previous = times


def test_a_launch_solved_afresh_on_another_day_is_the_retimed_one(scanned):
    """Day 1's launch at a grid altitude, solved by the stage (its local phases from the
    grid's design) on day 1: the payload and the insertion time of day 1's retimed fit."""
    from ovtraj.launch.inputs import launch_input
    from ovtraj.launch.stage import solve_launch

    base = build_scenario(scanned["data"])
    reference, day1 = find_launch_fit(base), day_scenario(base, 1)
    retimed = day_launch_fit(day1)  # stored by the scan
    row = reference.grid[(reference.grid["target_altitude_km"] - 305.0).abs() < 1e-9].iloc[0]
    solved = solve_launch(
        launch_input(day1, altitude_km=305.0),
        seed_design=design_of(row.to_dict()),
        global_search=False,
    )
    ours = retimed.grid[(retimed.grid["target_altitude_km"] - 305.0).abs() < 1e-9].iloc[0]
    assert solved.feasible and solved.launch_day.iso()[:10] == "2026-12-02"
    assert solved.payload_kg == pytest.approx(ours["payload_kg"], abs=1e-3)
    assert solved.insertion_time_s == pytest.approx(ours["insertion_time_s"], abs=0.1)


def test_the_grid_day_retimed_is_the_shipped_fit(scenario):
    """The reference grid flown again on its own day gives its own series: exactly when
    flown again on this machine, and within the last bits of the shipped figures, which
    another CPU computed (its compiled ascent kernels put the insertion times 7e-12 s
    away from this machine's; docs/mission.md, "Reproducibility")."""
    reference = find_launch_fit(scenario)
    again = retimed_launch_fit(reference, scenario)
    twice = retimed_launch_fit(again, scenario)
    h = np.linspace(200e3, 500e3, 13)
    for name, series in reference.series.items():
        assert np.array_equal(twice.series[name](h), again.series[name](h)), name
        assert np.allclose(again.series[name](h), series(h), rtol=1e-12, atol=0.0), name


def test_a_day_whose_first_drop_splits_the_grid_keeps_one_crossing(scenario):
    """2027-10-30 (day 333): the first in-plane drop after 0 h comes within the grid's
    spread of drop times, so the stage's own rule would time some altitudes a day later
    than others; the retimed grid keeps them on one crossing, every drop after 0 h."""
    day = day_scenario(scenario, 333)
    fit = retimed_launch_fit(find_launch_fit(scenario), day)
    times, drops = fit.grid["insertion_time_s"], fit.grid["drop_time_s"]
    assert times.max() - times.min() < 600.0 and drops.min() >= 0.0
    assert fit.loo_relative_error("insertion_time_s") < 0.1


def test_no_day_with_a_plan_exits_1_and_says_why(scanned, capsys):
    """A pick no front point meets: the day is recorded without a plan, with the reason
    (its pipeline is the stored one: nothing evaluated), and the command exits 1."""
    args = ["window", str(scanned["config"]), "--days", "1", "--max-time-h", "1", "--json"]
    assert run_command([*args, "--allow-unconverged"]) == 1
    summary = json.loads(capsys.readouterr().out)
    (row,) = summary["rows"]
    assert summary["best_day"] is None and row["status"] == "no plan" and row["plan"] is None
    assert (summary["converged"], summary["verdict"]) == (False, "no day has a plan")
    assert "max_t_total_h = 1" in row["reason"]
    frame = pd.read_parquet(summary["files"]["window.parquet"])
    assert not frame["best"].any() and frame["t_total_h"].isna().all()


def test_bad_input_is_one_line_and_exit_2(capsys, tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [unclosed\n", encoding="utf-8")
    data = yaml.safe_load(DEFAULT_SCENARIO.read_text(encoding="utf-8"))
    data["launch"]["launcher"] = str(REPO / "configs" / "launchers" / "pegasus_xl.yaml")
    data.pop("mission")
    no_mission = tmp_path / "no-mission.yaml"
    no_mission.write_text(yaml.safe_dump(data), encoding="utf-8")
    for args, named in (
        (["window", "--days", "0"], "--days 0"),
        (["window", "--days", "367"], "--days 367"),
        (["window", str(broken), "--days", "2"], str(broken)),
        (["window", str(tmp_path / "missing.yaml"), "--days", "2"], "missing.yaml"),
        (["window", str(no_mission), "--days", "2"], "no mission section"),
        (["window", "--days", "2", "--weights", "1,-1,1"], "--weights"),
    ):
        assert run_command(args) == 2, args
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and named in err, (args, err)


def test_the_flow_and_the_command_give_the_same_days(scanned, prefect_server):
    """``window_flow`` (a task per day on the process runner, one process: the day tasks
    travel to it and back) into a store of its own: the rows of its two days are the
    command's first two, and so is the verdict: its run Failed on the server, the line the
    command prints its message; ``require_converged=False``: Completed, named "Not
    converged" (the window served by the store)."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.objects import StateType

    from flows.verdict import NOT_CONVERGED
    from flows.window import window_flow
    from ovtraj.window.records import window_verdict

    store = scanned["tmp"] / "flow-runs"
    arguments = {
        "config": str(scanned["config"]),
        "days": 2,
        "store": str(store),
        "runner": "processes",
        "workers": 1,
    }
    state = window_flow(**arguments, return_state=True)
    summary = state.result(raise_on_failure=False).result
    assert summary["planned_days"] == 2 and summary["reused"] is False
    rows = json.loads(scanned["again"].stdout)["rows"][:2]
    assert (summary["converged"], summary["verdict"]) == window_verdict(rows)
    allowed = window_flow(**arguments, require_converged=False, return_state=True)
    assert allowed.result()["reused"] is True
    with get_client(sync_client=True) as client:
        failed, completed = (
            client.read_flow_run(s.state_details.flow_run_id).state for s in (state, allowed)
        )
    assert failed.type == StateType.FAILED and failed.message == summary["verdict"]
    assert completed.type == StateType.COMPLETED and completed.name == NOT_CONVERGED
    assert completed.message == summary["verdict"]
    assert [row["verdict"] for row in summary["rows"]] == [row["verdict"] for row in rows]
    from ovtraj.runs import RunStore

    command = pd.read_parquet(_written(scanned["first"].stdout, "table:")[0]).head(2)
    flow = pd.DataFrame(summary["rows"])
    columns = [c for c in WINDOW_SCHEMA.names if c != "best"]  # the best of 2 days, not 3
    # Ids and paths hash the code version too: a checkout edited between the two scans
    # gives other ids for the same results.
    versions = {
        RunStore(root).run(run_id).manifest["code_version"]
        for root, frame in ((scanned["store"], command), (store, flow))
        for run_id in frame["doe_run"]
    }
    if len(versions) > 1:
        columns = [c for c in columns if c not in ("doe_run", "pipeline_id", "plan", "report")]
    pd.testing.assert_frame_equal(
        flow[columns], command[columns], check_dtype=False, check_exact=True
    )
    assert Path(summary["files"]["window.html"]).is_relative_to(store / "windows")


def test_verify_checks_a_stored_window_and_the_pipeline_of_its_day(scanned, tmp_path):
    """`ovtraj verify` takes a window id (its files, day records and the plans they name)
    and a day's pipeline id (checked with the run holding it); a changed file is bad."""
    summary = json.loads(scanned["again"].stdout)
    store = tmp_path / "runs"
    shutil.copytree(scanned["store"], store, symlinks=True)

    def verify(item: str) -> subprocess.CompletedProcess:
        return run_cli("verify", item, "--store", str(store), timeout=300)

    done = verify(summary["window_id"])
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.strip().splitlines()[-1].startswith(f"window {summary['window_id']}: ")
    assert done.stdout.strip().endswith("checked: clean")
    day = store / "windows" / summary["window_id"] / "days" / "0000.json"
    pipeline = json.loads(day.read_text())["pipeline_id"]
    done = verify(pipeline)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"pipeline {pipeline} (in run " in done.stdout and "clean" in done.stdout
    svg = store / "windows" / summary["window_id"] / "window.svg"
    svg.write_bytes(svg.read_bytes().replace(b"<svg", b"<SVG", 1))
    done = verify(summary["window_id"])
    assert done.returncode == 1
    (bad,) = [line for line in done.stdout.splitlines() if line.startswith("bad: ")]
    assert str(svg) in bad
