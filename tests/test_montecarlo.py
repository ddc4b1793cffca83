"""The dispersed Monte Carlo of a mission plan, closed and open loop."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.cli.mission import _format_monte_carlo
from ovtraj.config.base import model_from_dict
from ovtraj.config.dispersions import DispersionsConfig, default_dispersions
from ovtraj.config.io_limits import io_limits
from ovtraj.formatting import duration
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission.chain import MissionContext, MissionDesign
from ovtraj.mission.fly import fly_plan
from ovtraj.mission.montecarlo_draw import DispersedFlight, draw_run
from ovtraj.mission.montecarlo_flight import fly_closed_loop, fly_open_loop
from ovtraj.mission.montecarlo_outcome import CORRECTIONS, IMPULSES, MANOEUVRES, RunOutcome
from ovtraj.mission.montecarlo_statistics import planned_dv, summarise
from ovtraj.mission.plan_build import build_plan
from ovtraj.mission.plan_store import read_plan, write_plan
from ovtraj.mission.sky_flight import format_fidelity_report
from ovtraj.paths import config_path
from ovtraj.target_sources import load_scenario

FEASIBLE = MissionDesign(285.06, 326.96, 0.79)
runner = CliRunner()


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    scenario = load_scenario(config_path("scenario.yaml"))
    context = MissionContext(scenario, find_launch_fit(scenario))
    cache = tmp_path_factory.mktemp("launch_solves")
    return build_plan(context, FEASIBLE, source={"run_id": "mc"}, launch_cache=cache)


@pytest.fixture(scope="module")
def plan_file(plan, tmp_path_factory):
    return write_plan(plan, tmp_path_factory.mktemp("plan"), "chosen")[0]


@pytest.fixture(scope="module")
def undispersed(plan):
    """Both loops flown with every error zero: (closed, open) outcomes."""
    config = _scaled(default_dispersions(), 0.0)
    zero = draw_run(config, 0, 0)
    return fly_closed_loop(plan, zero, config), fly_open_loop(plan, zero)


def _scaled(config: DispersionsConfig, factor: float, **overrides) -> DispersionsConfig:
    """The config with every 1-sigma figure multiplied by ``factor``."""
    data = config.model_dump()
    for group in ("drop", "stages", "navigation", "burns", "entry"):
        data[group] = {
            k: v if k == "minimum_factor" else v * factor for k, v in data[group].items()
        }
    data["closed_loop"]["accelerometer_fraction"] *= factor  # a measurement's error
    for path, value in overrides.items():
        group, key = path.split(".")
        data[group][key] = value
    return model_from_dict(DispersionsConfig, data, "test")


def test_a_run_draws_the_same_errors_whatever_the_batch():
    config = default_dispersions()
    a, b = draw_run(config, 5, 3), draw_run(config, 5, 3)
    assert a.thrust_scale == b.thrust_scale and a.density_scale == b.density_scale
    np.testing.assert_array_equal(a.navigation["deorbit"], b.navigation["deorbit"])
    other = draw_run(config, 5, 4)
    assert other.thrust_scale != a.thrust_scale and other.density_scale != a.density_scale
    # 1-sigma normal: over many runs the scales' spread is the configured sigma.
    density = np.array([draw_run(config, 1, k).density_scale for k in range(400)])
    assert np.std(density) == pytest.approx(config.entry.density_fraction, rel=0.15)


def test_without_dispersions_both_loops_fly_the_plan(plan, undispersed):
    nominal = fly_plan(plan)
    zero = draw_run(_scaled(default_dispersions(), 0.0), 0, 0)
    # Open loop with no error is the replay itself, to the last bit.
    undisturbed = fly_plan(plan, perturbation=DispersedFlight(zero))
    assert undisturbed.miss_distance_m == nominal.miss_distance_m
    closed, opened = undispersed
    assert opened.landing_miss_m == nominal.miss_distance_m
    # Closed loop re-solves every stage from the (exact) estimate: it lands where the plan
    # says, within the guidance's range tolerance.
    assert closed.landed, closed.reason
    assert closed.arrival_miss_m < 1.0
    assert abs(closed.landing_miss_m - plan.terminal.miss_distance_m) < 100.0


def test_the_closed_loop_lands_within_the_stated_miss_where_the_open_loop_cannot(
    plan_file, tmp_path, monkeypatch
):
    monkeypatch.setenv("OVTRAJ_HOME", str(tmp_path / "home"))
    result = runner.invoke(
        app, ["fly", str(plan_file), "--monte-carlo", "4", "--seed", "3", "--json"]
    )
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    assert row["start"] == "drop" and row["landed_within_stated_miss"] is True
    mc = row["monte_carlo"]
    # Stored in the workspace's run store (the shipped dispersions name no other), its
    # summary the report shown.
    assert mc["directory"] == str(tmp_path / "home" / "runs" / mc["run_id"])
    stored = json.loads((tmp_path / "home" / "runs" / mc["run_id"] / "summary.json").read_text())
    assert stored == {k: v for k, v in mc.items() if k in stored}
    assert set(mc) - set(stored) == {"directory", "simulated_runs", "plots", "failed_batches"}
    # The shape: the closed loop's figures at the top, the open loop's beside.
    closed, opened = mc, mc["open_loop"]
    assert mc["loop"] == "closed" and {"runs", "landing_miss_m", "feasible_fraction"} <= set(mc)
    assert closed["runs"] == opened["runs"] == 4
    assert closed["feasible_fraction"] == 1.0 and closed["within_stated_miss_fraction"] == 1.0
    # Its time estimate said first, on stderr (the JSON on stdout stays whole).
    assert result.stderr.splitlines()[0].startswith("--monte-carlo 4: about ")
    assert closed["landing_miss_m"]["max"] <= mc["stated_miss_m"]
    # The same draws flown without corrections: far off or not down at all (a percentile
    # that falls on a run that did not land is None).
    assert opened["within_stated_miss_fraction"] == 0.0
    median = (opened["landing_miss_m"] or {}).get("p50")
    assert median is None or median > 20 * closed["landing_miss_m"]["p50"]
    assert opened["landed"] + sum(opened["failures"].values()) == 4
    for name, margin in closed["path_limit_margins"].items():
        assert 0.0 < margin["smallest_margin"] < margin["limit"], name
    # The dV spent, both loops, against the plan file's impulses.
    impulses = read_plan(plan_file).impulses()
    for s in (closed, opened):
        dv = s["dv_mps"]
        assert list(dv) == ["total", *MANOEUVRES]
        for impulse in impulses:
            assert dv[impulse.name]["planned"] == impulse.dv_mps
        assert dv["total"]["planned"] == sum(i.dv_mps for i in impulses)
        assert dv[CORRECTIONS]["planned"] == 0.0
        for name, figures in dv.items():
            if figures["runs"]:
                assert figures["p50"] <= figures["p95"] <= figures["max"], name
                assert figures["p95_minus_planned"] == figures["p95"] - figures["planned"]
    # Every closed run docks and flies every manoeuvre; the open loop executes each impulse
    # it reaches (no correction: 0).
    assert all(figures["runs"] == 4 for figures in closed["dv_mps"].values())
    assert opened["dv_mps"]["rendezvous burn 1"]["runs"] == 4
    assert opened["dv_mps"][CORRECTIONS]["max"] in (0.0, None)
    # The corrections and the re-solved deorbit cost dV beyond the plan.
    assert closed["dv_mps"][CORRECTIONS]["p50"] > 0.0
    # Printed with its units beside the landing miss (what `fly --monte-carlo` shows).
    text = _format_monte_carlo(mc)
    assert text.count("dV spent") == 2 and text.count("total: ") == 2
    assert f"deorbit burn: {closed['dv_mps']['deorbit burn']['p50']:.2f} / " in text


def test_without_dispersions_both_loops_spend_the_planned_dv(plan, undispersed):
    closed, opened = undispersed
    assert [impulse.name for impulse in plan.impulses()] == list(IMPULSES)
    assert list(closed.dv_mps) == list(opened.dv_mps) == list(MANOEUVRES)
    # The closed loop re-solves each manoeuvre from the exact estimate of the plan's own
    # state (the replayed insertion is the plan's to the bit), so each impulse differs from
    # the plan's only by the numerics: the replay's DOP853 arcs (rtol 1e-12, atol 1e-9
    # m/s) against the chain's heyoka ones, and the deorbit cut-off's root finder (scale
    # within 1e-10: 7.6e-9 m/s of a 76 m/s burn). Measured: at most 5.7e-9 m/s (rendezvous
    # burn 2, 1.5e-10 relative), the total 4e-9 m/s; 1e-7 m/s leaves 13x over the larger
    # bound, far below any modelling slip (an error not zeroed, a correction fired: mm/s).
    # No correction fires: from the exact estimate the predicted arrival miss is the
    # plan's (1e-8 m), within the 1 m correction tolerance.
    for impulse in plan.impulses():
        assert closed.dv_mps[impulse.name] == pytest.approx(impulse.dv_mps, abs=1e-7)
        # The open loop executes the stored vector unchanged: its norm, to the last bits.
        assert opened.dv_mps[impulse.name] == pytest.approx(impulse.dv_mps, rel=1e-14)
    assert closed.dv_mps[CORRECTIONS] == opened.dv_mps[CORRECTIONS] == 0.0
    for outcome in undispersed:
        assert outcome.dv_total_mps == sum(outcome.dv_mps[name] for name in MANOEUVRES)
        assert outcome.dv_total_mps == pytest.approx(plan.totals.dv_total_mps, abs=1e-7)


def test_the_dv_summary_counts_the_runs_that_flew_each_manoeuvre(plan):
    planned = planned_dv(plan)
    assert planned == {
        "total": sum(i.dv_mps for i in plan.impulses()),
        **{i.name: i.dv_mps for i in plan.impulses()},
        CORRECTIONS: 0.0,
    }
    runs = []
    for k, scale in enumerate((1.01, 1.03, 1.02, 0.99)):
        run = RunOutcome(run=k, loop="closed", landed=True, landing_miss_m=100.0)
        for name in MANOEUVRES:
            run.spend(name, np.array([planned[name] * scale, 0.0, 0.0]))
        runs.append(run)
    stopped = RunOutcome(run=4, loop="closed", landed=False, failed_stage="transfer")
    stopped.spend("rendezvous burn 1", np.array([0.0, 50.0, 0.0]))
    stopped.spend(CORRECTIONS, np.array([0.3, 0.0, 0.0]), np.array([0.0, 0.4, 0.0]))
    assert stopped.dv_mps[CORRECTIONS] == pytest.approx(0.7) and stopped.dv_total_mps is None
    dv = summarise([*runs, stopped], {}, 5000.0, planned)["dv_mps"]
    json.dumps(dv, allow_nan=False)
    assert list(dv) == ["total", *MANOEUVRES]
    total = dv["total"]
    assert total["runs"] == 4 and total["planned"] == planned["total"]
    # numpy's "higher" percentiles: each one a run's value.
    assert total["p50"] == pytest.approx(1.02 * planned["total"])
    assert total["p95"] == total["max"] == pytest.approx(1.03 * planned["total"])
    assert total["p95_minus_planned"] == pytest.approx(0.03 * planned["total"])
    assert dv["rendezvous burn 1"]["runs"] == 5 and dv["rendezvous burn 1"]["max"] == 50.0
    assert dv[CORRECTIONS]["max"] == pytest.approx(0.7)
    assert dv[CORRECTIONS]["p95_minus_planned"] == pytest.approx(0.7)
    # Without the plan's figures (and with no run at all) the section keeps its shape.
    empty = summarise([stopped], {}, 5000.0)["dv_mps"]
    assert empty["deorbit burn"] == {
        "runs": 0,
        "p50": None,
        "p95": None,
        "max": None,
        "planned": None,
        "p95_minus_planned": None,
    }
    assert empty["rendezvous burn 1"]["p50"] == 50.0 and empty["total"]["runs"] == 0


def test_a_run_that_cannot_dock_is_a_failure_with_its_reason(plan):
    config = _scaled(default_dispersions(), 1.0, **{"navigation.position_m": 9000.0})
    outcome = fly_closed_loop(plan, draw_run(config, 0, 0), config)
    assert not outcome.landed and outcome.failed_stage == "rendezvous"
    assert "capture" in outcome.reason or "re-targeting" in outcome.reason
    summary = summarise([outcome], {"max_load_g": 3.5}, 5000.0)
    assert summary["feasible_fraction"] == 0.0 and summary["failures"] == {"rendezvous": 1}
    assert summary["landing_miss_m"] is None
    assert math.isfinite(json.loads(json.dumps(summary, allow_nan=False))["runs"])
    # It spent the rendezvous burns' dV (the arrival impulse came before the miss was
    # known), not the transfer's nor the deorbit's: no total.
    assert set(outcome.dv_mps) == {"rendezvous burn 1", CORRECTIONS, "rendezvous burn 2"}
    assert outcome.dv_total_mps is None and summary["dv_mps"]["total"]["runs"] == 0
    assert summary["dv_mps"]["transfer burn 1"]["p95"] is None


def test_a_monte_carlo_beyond_the_configured_runs_is_refused_with_its_estimate(plan_file):
    limits = io_limits()
    runs = limits.fly_monte_carlo_max_runs + 1
    result = runner.invoke(app, ["fly", str(plan_file), "--monte-carlo", str(runs)])
    estimate = duration(runs * limits.fly_monte_carlo_j2_s_per_run)
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr.splitlines() == [
        f"--monte-carlo {runs}: about {estimate} in this process "
        f"({limits.fly_monte_carlo_j2_s_per_run:g} s a run: fly_monte_carlo_j2_s_per_run of "
        f"configs/io_limits.yaml): more than fly_monte_carlo_max_runs = "
        f"{limits.fly_monte_carlo_max_runs}; give --allow-long-run to fly it, or run the "
        "Monte Carlo flow (flows/mission_monte_carlo.py) on several workers"
    ]


def test_bad_dispersions_are_refused_naming_the_field(plan_file, tmp_path):
    data = yaml.safe_load(config_path("dispersions.yaml").read_text())
    data["burns"]["pointing_deg"] = -1.0
    bad = tmp_path / "dispersions.yaml"
    bad.write_text(yaml.safe_dump(data))
    result = runner.invoke(
        app, ["fly", str(plan_file), "--monte-carlo", "2", "--dispersions", str(bad)]
    )
    assert result.exit_code == 2 and "burns.pointing_deg" in result.output
    data["burns"]["pointing_deg"] = 0.5
    data["closed_loop"]["rendezvous_corrections"] = [0.8, 0.5]
    bad.write_text(yaml.safe_dump(data))
    result = runner.invoke(
        app, ["fly", str(plan_file), "--monte-carlo", "2", "--dispersions", str(bad)]
    )
    assert result.exit_code == 2 and "rendezvous_corrections" in result.output


def _parquet_digests(directory):
    import hashlib
    from pathlib import Path

    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(Path(directory).rglob("*.parquet"))
    }


def test_the_flow_stores_every_run_and_a_second_run_flies_nothing(
    prefect_server, plan, plan_file, tmp_path
):
    import pyarrow.parquet as pq

    from flows.mission_monte_carlo import plan_monte_carlo_flow
    from ovtraj.mission.montecarlo import monte_carlo
    from ovtraj.mission.montecarlo_outcome import STORED_RUN_SCHEMA
    from ovtraj.mission.montecarlo_statistics import loop_summaries
    from ovtraj.mission.montecarlo_store import PlanMonteCarloRun

    data = yaml.safe_load(config_path("dispersions.yaml").read_text())
    data["execution"].update(
        runs=3, seed=4, batch_size=2, workers=2, task_runner="threads", store=str(tmp_path)
    )
    dispersions = tmp_path / "dispersions.yaml"
    dispersions.write_text(yaml.safe_dump(data))
    first = plan_monte_carlo_flow(str(plan_file), dispersions=str(dispersions))
    assert first["status"] == "complete" and first["simulated_runs"] == 3
    run = PlanMonteCarloRun(first["directory"])
    parts = sorted((run.directory / "runs").glob("part-*.parquet"))
    assert len(parts) == 2  # runs 0-1 and 2
    for part in parts:
        assert pq.read_schema(part).remove_metadata().equals(STORED_RUN_SCHEMA)
    frame = run.results()
    assert len(frame) == 6 and sorted(set(frame["loop"])) == ["closed", "open"]
    assert len(run.timing()) == 6  # the wall times live in the batch markers only
    closed = {k: first[k] for k in loop_summaries(plan, run.results())["closed"]}
    assert closed["landed"] == 3 and closed["within_stated_miss_fraction"] == 1.0
    # The stored rows are the library's: the same draws give the same landings.
    pairs = monte_carlo(plan, model_from_dict(DispersionsConfig, data, "test"), 3, 4)
    assert [c.landing_miss_m for c, _ in pairs] == frame[frame["loop"] == "closed"][
        "landing_miss_m"
    ].tolist()
    assert loop_summaries(plan, frame)["closed"] == closed
    assert loop_summaries(plan, frame)["open"] == first["open_loop"]
    # The dV each run spent, stored per manoeuvre: the library's, the total their sum (a
    # run that stopped before a manoeuvre: null for it and for the total).
    columns = list(MANOEUVRES.values())
    assert [c.dv_mps for c, _ in pairs] == [
        {name: row[column] for name, column in MANOEUVRES.items()}
        for _, row in frame[frame["loop"] == "closed"].iterrows()
    ]
    for _, row in frame.iterrows():
        if row[columns].notna().all():
            assert row["dv_total_mps"] == pytest.approx(row[columns].sum(), abs=1e-9)
        else:
            assert math.isnan(row["dv_total_mps"])
    assert frame["dv_total_mps"].notna().any()
    for s in (closed, first["open_loop"]):
        assert set(s["dv_mps"]) == {"total", *MANOEUVRES}
    digests = _parquet_digests(run.directory)
    second = plan_monte_carlo_flow(str(plan_file), dispersions=str(dispersions))
    assert second["run_id"] == first["run_id"] and second["simulated_runs"] == 0
    assert _parquet_digests(run.directory) == digests
    stored = json.loads((run.directory / "summary.json").read_text())
    assert {k: stored[k] for k in closed} == closed


# --- the plan flown under the high-fidelity sky ------------------------------------------


def test_the_plan_flown_under_the_high_fidelity_sky_lands_and_reports_its_extra_dv(
    plan_file, tmp_path
):
    mine = tmp_path / "my_force_model.yaml"  # the user's file: the report names it
    mine.write_text(config_path("force_model.yaml").read_text())
    result = runner.invoke(
        app, ["fly", str(plan_file), "--fidelity", "high", "--force-model", str(mine), "--json"]
    )
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    assert row["force_model_file"] == str(mine.resolve())
    assert row["fidelity"] == "high" and row["landed_within_stated_miss"] is True
    planned, j2, high = row["plan"], row["closed_loop_j2"], row["closed_loop_high_fidelity"]
    impulses = read_plan(plan_file).impulses()
    assert planned["dv_total_mps"] == sum(i.dv_mps for i in impulses)
    # Under the J2 sky the closed loop corrects nothing: it flies the plan's impulses
    # (re-solved from exact estimates, to the solvers' tolerances).
    for impulse in impulses:
        assert j2["dv_mps"][impulse.name] == pytest.approx(impulse.dv_mps, abs=0.05)
    assert j2["dv_mps"][CORRECTIONS] == 0.0
    # Under the high-fidelity sky the phasing drifts (drag, the field beyond J2): the
    # loop re-targets and corrects, and the report says what that costs beyond the plan.
    assert high["landed"] and high["dv_total_mps"] == pytest.approx(
        sum(high["dv_mps"].values()), abs=1e-9
    )
    assert row["extra_dv_mps"] == pytest.approx(high["dv_total_mps"] - planned["dv_total_mps"])
    assert high["dv_mps"][CORRECTIONS] > 0.0
    assert 0.0 < high["arrival_miss_m"] <= default_dispersions().closed_loop.docking_capture_m
    assert high["landing_miss_m"] <= planned["stated_miss_m"]
    assert all(margin > 0.0 for margin in high["path_limit_margins"].values())
    # The whole model as flown is in the report: a reader can fly it again.
    assert row["force_model"]["gravity"] == {"model": "egm2008", "degree": 20, "order": 20}
    text = format_fidelity_report(row)  # what `fly --fidelity high` prints (no flight twice)
    assert "closed loop, high fidelity" in text
    assert f"(force model: {mine.resolve()})" in text.splitlines()[0]
    assert f"{high['dv_mps']['deorbit burn']:.2f}" in text
    assert f"extra dV under the high-fidelity sky: {row['extra_dv_mps']:+.2f} m/s" in text


def test_a_high_fidelity_flight_the_data_or_the_plan_cannot_support_is_one_line(
    plan_file, tmp_path
):
    data = json.loads(plan_file.read_text())
    del data["scenario"]["vehicle"]["body"]
    bodiless = tmp_path / "bodiless.json"
    bodiless.write_text(json.dumps(data))
    result = runner.invoke(app, ["fly", str(bodiless), "--fidelity", "high"])
    assert result.exit_code == 2 and result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1 and "vehicle.body" in result.stderr
    # The bundled space weather ends before the shipped campaign (2026-12).
    settings = yaml.safe_load(config_path("force_model.yaml").read_text())
    settings["space_weather"]["source"] = "bundled"
    bundled = tmp_path / "bundled.yaml"
    bundled.write_text(yaml.safe_dump(settings))
    result = runner.invoke(
        app, ["fly", str(plan_file), "--fidelity", "high", "--force-model", str(bundled)]
    )
    assert result.exit_code == 2 and "space_weather.source" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_the_flow_flies_the_high_fidelity_monte_carlo_as_the_library_does(
    prefect_server, plan, plan_file, tmp_path
):
    from flows.mission_monte_carlo import plan_monte_carlo_flow
    from ovtraj.config.force_model import default_force_model
    from ovtraj.mission.montecarlo import monte_carlo
    from ovtraj.mission.montecarlo_store import PlanMonteCarloRun, plan_monte_carlo_id

    data = yaml.safe_load(config_path("dispersions.yaml").read_text())
    data["execution"].update(
        runs=1, seed=5, batch_size=1, workers=1, task_runner="serial", store=str(tmp_path)
    )
    dispersions = tmp_path / "dispersions.yaml"
    dispersions.write_text(yaml.safe_dump(data))
    summary = plan_monte_carlo_flow(str(plan_file), dispersions=str(dispersions), fidelity="high")
    assert summary["status"] == "complete" and summary["fidelity"] == "high"
    config = model_from_dict(DispersionsConfig, data, "test")
    # Its own run: the J2 Monte Carlo of the same inputs keeps its id.
    run = PlanMonteCarloRun(summary["directory"])
    j2_id = plan_monte_carlo_id(
        plan.to_dict(), config.results_content(), 1, 5, run.info["code_version"]
    )
    assert summary["run_id"] != j2_id
    pairs = monte_carlo(plan, config, 1, 5, force_model=default_force_model())
    frame = run.results()
    assert [c.landing_miss_m for c, _ in pairs] == frame[frame["loop"] == "closed"][
        "landing_miss_m"
    ].tolist()
    assert [c.dv_total_mps for c, _ in pairs] == frame[frame["loop"] == "closed"][
        "dv_total_mps"
    ].tolist()


# --- the stored Monte Carlo's summary: sealed, and never shown when it is not authentic ---


def test_an_edited_summary_is_never_shown_the_report_is_built_again_from_the_batches(
    plan, tmp_path, monkeypatch
):
    """With a store key, a Monte Carlo run's ``summary.json`` is sealed; one edited without
    the key (the catalog's and history's p95 landing miss and dV margin) is refused by the
    reader, which builds the report again from the sealed batches, and `ovtraj verify`
    names it as tampered."""
    import secrets

    from ovtraj.mission.montecarlo import simulate_batch
    from ovtraj.mission.montecarlo_store import PlanMonteCarloRun
    from ovtraj.store.seals import STORE_KEY_ENV
    from ovtraj.tracking.catalog import refresh

    key = secrets.token_hex(32)
    monkeypatch.setenv(STORE_KEY_ENV, key)
    config = default_dispersions()
    run = PlanMonteCarloRun.create(
        tmp_path,
        plan=plan.to_dict(),
        dispersions=config.results_content(),
        runs=2,
        seed=3,
        code="test",
    )
    run.write_batch(0, simulate_batch(plan, config, [0, 1], 3))
    run.write_summary({**run.report(), "simulated_runs": 2})
    truth = run.report()
    assert truth["status"] == "complete" and truth["stored_runs"] == 2
    assert len(json.loads((run.directory / "summary.json").read_bytes())["hmac"]) == 64

    def mc_row() -> dict:
        frame = refresh(tmp_path).frame
        return frame[frame["kind"] == "monte_carlo"].iloc[0].to_dict()

    row = mc_row()
    assert row["mc_landing_miss_p95_m"] == truth["landing_miss_m"]["p95"]
    done = runner.invoke(app, ["verify", run.id, "--store", str(tmp_path)])
    assert done.exit_code == 0 and done.stdout.strip().endswith("checked: clean"), done.output

    path = run.directory / "summary.json"
    forged = json.loads(path.read_bytes())
    forged["landing_miss_m"]["p95"] = 1.0
    forged["dv_mps"]["total"]["p95_minus_planned"] = 0.01
    path.write_text(json.dumps(forged))
    shown = run.summary()
    assert shown["landing_miss_m"]["p95"] == truth["landing_miss_m"]["p95"] != 1.0
    assert {k: shown[k] for k in truth} == truth
    row = mc_row()
    assert row["mc_landing_miss_p95_m"] == truth["landing_miss_m"]["p95"]
    assert row["mc_dv_margin_p95_mps"] == truth["dv_mps"]["total"]["p95_minus_planned"]
    done = runner.invoke(app, ["verify", run.id, "--store", str(tmp_path)])
    assert done.exit_code == 1
    (line,) = [x for x in done.stdout.splitlines() if x.startswith("tampered: ")]
    assert str(path) in line


# --- the one driver: where the batches fly changes nothing stored ---------------------------


@pytest.mark.slow  # two spawned processes import the package (tens of seconds here)
def test_a_pool_of_processes_stores_what_this_process_stores(plan, tmp_path):
    """The driver's batches on the library's process pool store the same bytes as the
    command's flights in its own process (a failed batch there would say so)."""
    from ovtraj.runs.monte_carlo_pool import PoolFlier
    from ovtraj.runs.plan_monte_carlo import PICTURES, PlanMonteCarlo
    from ovtraj.runs.runners import RunnerChoice
    from ovtraj.store.environment_block import unstamped
    from ovtraj.store.monte_carlo import drive_monte_carlo

    def stored(runner: str) -> tuple[dict, dict[str, bytes]]:
        study = PlanMonteCarlo(
            plan=plan,
            dispersions=default_dispersions(),
            runs=3,
            seed=6,
            root=tmp_path / runner,
            code="test",
            batch_size=2,
        )
        counted = []
        flier = PoolFlier(RunnerChoice(runner, 2), on_run=lambda: counted.append(1))
        report = drive_monte_carlo(study, flier)
        assert report["failed_batches"] == [] and len(counted) == 3, report["failed_batches"]
        directory = Path(report["directory"])
        files = {
            str(p.relative_to(directory)): p.read_bytes()
            for p in sorted(directory.rglob("*"))
            if p.is_file() and "locks" not in p.relative_to(directory).parts
        }
        return report, files

    here, ours = stored("serial")
    pooled, theirs = stored("processes")
    assert here["run_id"] == pooled["run_id"] and here["simulated_runs"] == 3
    assert sorted(ours) == sorted(theirs)
    assert {"runs/part-00000.parquet", "runs/part-00002.parquet"} <= set(ours)
    assert {f"plots/{name}.png" for name in PICTURES} <= set(ours)
    for name in ours:
        if name.endswith((".parquet", ".png")) or name in ("config.json", "summary.json"):
            assert ours[name] == theirs[name], name
        else:  # the records but for when they were written and how long each run took
            drop = ("created_utc", "timing")
            mine, other = (
                {k: v for k, v in unstamped(json.loads(x)).items() if k not in drop}
                for x in (ours[name], theirs[name])
            )
            assert mine == other, name
