"""The dispersed Monte Carlo of a mission plan, closed and open loop (issue 23)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ovtraj.cli import app
from ovtraj.config import load_scenario
from ovtraj.config.base import model_from_dict
from ovtraj.config.dispersions import DispersionsConfig, default_dispersions
from ovtraj.launch.fit import find_launch_fit
from ovtraj.mission.chain import MissionContext, MissionDesign
from ovtraj.mission.fly import fly_plan
from ovtraj.mission.montecarlo import (
    DispersedFlight,
    draw_run,
    fly_closed_loop,
    fly_open_loop,
    summarise,
)
from ovtraj.mission.plan import build_plan, write_plan
from ovtraj.paths import config_path

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


def test_without_dispersions_both_loops_fly_the_plan(plan):
    nominal = fly_plan(plan)
    zero = draw_run(_scaled(default_dispersions(), 0.0), 0, 0)
    # Open loop with no error is the replay itself, to the last bit.
    undisturbed = fly_plan(plan, perturbation=DispersedFlight(zero))
    assert undisturbed.miss_distance_m == nominal.miss_distance_m
    assert fly_open_loop(plan, zero).landing_miss_m == nominal.miss_distance_m
    # Closed loop re-solves every stage from the (exact) estimate: it lands where the plan
    # says, within the guidance's range tolerance.
    closed = fly_closed_loop(plan, zero, _scaled(default_dispersions(), 0.0))
    assert closed.landed, closed.reason
    assert closed.arrival_miss_m < 1.0
    assert abs(closed.landing_miss_m - plan.terminal.miss_distance_m) < 100.0


def test_the_closed_loop_lands_within_the_stated_miss_where_the_open_loop_cannot(plan_file):
    result = runner.invoke(
        app, ["fly", str(plan_file), "--monte-carlo", "4", "--seed", "3", "--json"]
    )
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    assert row["start"] == "drop" and row["landed_within_stated_miss"] is True
    mc = row["monte_carlo"]
    # The shape: the closed loop's figures at the top, the open loop's beside.
    closed, opened = mc, mc["open_loop"]
    assert mc["loop"] == "closed" and {"runs", "landing_miss_m", "feasible_fraction"} <= set(mc)
    assert closed["runs"] == opened["runs"] == 4
    assert closed["feasible_fraction"] == 1.0 and closed["within_stated_miss_fraction"] == 1.0
    assert closed["landing_miss_m"]["max"] <= mc["stated_miss_m"]
    # The same draws flown without corrections: far off or not down at all (a percentile
    # that falls on a run that did not land is None).
    assert opened["within_stated_miss_fraction"] == 0.0
    median = (opened["landing_miss_m"] or {}).get("p50")
    assert median is None or median > 20 * closed["landing_miss_m"]["p50"]
    assert opened["landed"] + sum(opened["failures"].values()) == 4
    for name, margin in closed["path_limit_margins"].items():
        assert 0.0 < margin["smallest_margin"] < margin["limit"], name


def test_a_run_that_cannot_dock_is_a_failure_with_its_reason(plan):
    config = _scaled(default_dispersions(), 1.0, **{"navigation.position_m": 9000.0})
    outcome = fly_closed_loop(plan, draw_run(config, 0, 0), config)
    assert not outcome.landed and outcome.failed_stage == "rendezvous"
    assert "capture" in outcome.reason or "re-targeting" in outcome.reason
    summary = summarise([outcome], {"max_load_g": 3.5}, 5000.0)
    assert summary["feasible_fraction"] == 0.0 and summary["failures"] == {"rendezvous": 1}
    assert summary["landing_miss_m"] is None
    assert math.isfinite(json.loads(json.dumps(summary))["runs"])


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
    from ovtraj.mission.montecarlo import STORED_RUN_SCHEMA, loop_summaries, monte_carlo
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
    digests = _parquet_digests(run.directory)
    second = plan_monte_carlo_flow(str(plan_file), dispersions=str(dispersions))
    assert second["run_id"] == first["run_id"] and second["simulated_runs"] == 0
    assert _parquet_digests(run.directory) == digests
    stored = json.loads((run.directory / "summary.json").read_text())
    assert {k: stored[k] for k in closed} == closed
