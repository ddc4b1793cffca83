"""Finite-thrust deorbit burn by osculating-element prediction (seed 004).

References written here, not taken from the library:

* the propagated entry state (heyoka Taylor integration of the coast from the burn state to
  the entry radius) for the on-board prediction, with the accuracy the seed claims: strategy
  2 keeps the entry flight-path angle within 0.0015 deg (prediction error only, sec. 4) and
  strategy 1 the along-track error within 3.5 km;
* a direct numerical intersection of two coplanar ellipses (sign changes of
  r_0(u) - r_f(u) on a grid, refined by ``scipy.optimize.brentq``);
* the two-body impulsive deorbit written from energy and angular momentum conservation
  (Curtis 2014, sec. 2.4-2.5) for the high-thrust, J2-free limit;
* the seed's published figures for the iteration (5 iterations to 0.01 deg), the delta-v
  (~88 m/s at burn angle 0, ~97 m/s at +-27 deg, the entry speed 1.5 m/s faster there) and
  the Monte Carlo (strategy 1 < 3.5 km, strategy 2 <= 0.0015 deg).
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from scipy.optimize import brentq

from ovtraj.astro.elements import argument_of_latitude
from ovtraj.astro.entry_prediction import predict_entry, state_perigee_radius
from ovtraj.astro.frames import flight_path_angle
from ovtraj.astro.propagation import ArgumentOfLatitudeCrossing
from ovtraj.config import ConfigError
from ovtraj.studies.deorbit_burn import (
    SIMULATIONS,
    burn_angle_study,
    deorbit_burn_from_dict,
    load_deorbit_burn,
    monte_carlo_summary,
    run_monte_carlo,
    solve_deorbit_burn,
)
from ovtraj.studies.deorbit_burn.flight import initial_state
from ovtraj.studies.deorbit_burn.intersection import intersection_coefficients, intersection_roots
from ovtraj.studies.deorbit_burn.montecarlo import STORED_RUN_SCHEMA, draw_dispersion
from ovtraj.studies.deorbit_burn.solve import BurnSolver
from ovtraj.studies.deorbit_burn.store import MonteCarloRun, monte_carlo_run_id
from tests.conftest import REPO

CASE = REPO / "configs" / "cases" / "shuttle_deorbit.yaml"
# Seed 004 sec. 4: strategy 2 entry fpa dispersion <= 0.0015 deg, strategy 1 along-track < 3.5 km.
SEED_FPA_DEG = 0.0015
SEED_ALONG_TRACK_KM = 3.5


def _data() -> dict:
    return yaml.safe_load(CASE.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def problem():
    return load_deorbit_burn(CASE)


@pytest.fixture(scope="module")
def nominal(problem):
    return solve_deorbit_burn(problem)


# --------------------------------------------------------------------------------------------
# Prediction of the entry state from osculating elements
# --------------------------------------------------------------------------------------------
def test_prediction_matches_the_propagated_entry_within_the_seed_accuracy(problem, nominal):
    """States along the converged burn, around the cut-off (entry fpa -0.9 to -1.3 deg).

    Verified tolerance: the seed's 0.0015 deg in fpa and 3.5 km along track (we measure
    ~2e-4 deg and ~0.5 km); the speed within 0.05 m/s (measured ~0.005 m/s). The two-body
    conic through the same states misses both seed bounds, so the J2 terms are what matters.
    """
    solver = BurnSolver(problem)
    sim = solver.simulator
    thrust = solver.nominal_thrust(math.radians(nominal.burn_angle_deg))
    state0 = initial_state(problem, problem.waiting)
    coast = sim.coast.propagate(
        state0, 0.0, 1e4, events=[ArgumentOfLatitudeCrossing(math.radians(nominal.u_open_deg))]
    )
    arc = sim.powered.burn(
        np.r_[coast.state, problem.vehicle.mass_kg],
        coast.t,
        coast.t + nominal.burn_duration_s + 100.0,
        thrust,
    )
    times = np.linspace(arc.t0, arc.t1, 120)
    states = arc.states(times)
    r_e = problem.entry.radius_m
    low = state_perigee_radius(states[:, :3], states[:, 3:6], problem.earth.mu) <= r_e
    truth = []
    for t, s in zip(times[low], states[low], strict=True):
        end = sim.coast.propagate(s[:6], t, t + 1e4, events=[sim.entry_event])
        assert end.status == "terminal_event"
        r, v = end.state[:3], end.state[3:]
        truth.append(
            (float(argument_of_latitude(r, v)), float(flight_path_angle(r, v)), np.linalg.norm(v))
        )
    truth = np.array(truth)
    window = (np.degrees(truth[:, 1]) < -0.9) & (np.degrees(truth[:, 1]) > -1.3)
    assert window.sum() >= 10

    def errors(earth):
        pred = predict_entry(
            states[low, :3], states[low, 3:6], earth=earth, entry_radius=r_e, iterations=2
        )
        du = (pred.u_rad - truth[:, 0] + math.pi) % (2 * math.pi) - math.pi
        return (
            np.abs(du[window]) * r_e / 1e3,
            np.degrees(np.abs(pred.fpa_rad - truth[:, 1]))[window],
            np.abs(pred.speed_mps - truth[:, 2])[window],
        )

    along, fpa, speed = errors(problem.earth)
    assert along.max() < SEED_ALONG_TRACK_KM
    assert fpa.max() < SEED_FPA_DEG
    assert speed.max() < 0.05
    along2, fpa2, _ = errors(replace(problem.earth, j2=0.0))
    assert along2.min() > SEED_ALONG_TRACK_KM and fpa2.min() > SEED_FPA_DEG


# --------------------------------------------------------------------------------------------
# Intersection of the waiting and transfer orbits (seed eq. 6)
# --------------------------------------------------------------------------------------------
def _numerical_intersections(p0, e0, w0, pf, ef, wf):
    def gap(u):
        return p0 / (1 + e0 * math.cos(u - w0)) - pf / (1 + ef * math.cos(u - wf))

    grid = np.linspace(0.0, 2 * math.pi, 4001)
    values = np.array([gap(u) for u in grid])
    roots = []
    for k in range(len(grid) - 1):
        if values[k] == 0.0:
            roots.append(grid[k])
        elif values[k] * values[k + 1] < 0.0:
            roots.append(brentq(gap, grid[k], grid[k + 1], xtol=1e-14))
    return sorted(r % (2 * math.pi) for r in roots)


def test_intersection_equation_agrees_with_a_numerical_intersection():
    rng = np.random.default_rng(4)
    met = missed = 0
    for _ in range(60):
        a0, af = rng.uniform(6.5e6, 7.2e6, size=2)
        e0, ef = rng.uniform(0.0, 0.08, size=2)
        w0, wf = rng.uniform(0.0, 2 * math.pi, size=2)
        p0, pf = a0 * (1 - e0**2), af * (1 - ef**2)
        k = intersection_coefficients(
            p0, e0 * math.cos(w0), e0 * math.sin(w0), pf, ef * math.cos(wf), ef * math.sin(wf)
        )
        roots = intersection_roots(k)
        expected = _numerical_intersections(p0, e0, w0, pf, ef, wf)
        if roots is None:
            assert expected == []
            missed += 1
            continue
        met += 1
        assert len(expected) == 2
        for ours, ref in zip(sorted(roots), expected, strict=True):
            assert abs(ours - ref) < 1e-9
    assert met >= 10 and missed >= 10  # both branches exercised


# --------------------------------------------------------------------------------------------
# Two-body, high-thrust limit
# --------------------------------------------------------------------------------------------
def _impulsive_reference(problem):
    """Tangent-free single impulse from the circular orbit onto the entry ellipse."""
    mu = problem.earth.mu
    r0 = float(problem.waiting.a)
    entry = problem.entry
    re, ve, ge = entry.radius_m, entry.speed_mps, entry.fpa_rad
    h = re * ve * math.cos(ge)
    energy = ve**2 / 2 - mu / re
    vt = h / r0
    vr = -math.sqrt(2 * (energy + mu / r0) - vt**2)  # descending branch, nearer the entry
    vc = math.sqrt(mu / r0)
    p = h * h / mu
    e = math.sqrt(1 + 2 * energy * h * h / mu**2)
    f_burn = 2 * math.pi - math.acos((p / r0 - 1) / e)
    f_entry = 2 * math.pi - math.acos((p / re - 1) / e)
    return {
        "dv": math.hypot(vr, vt - vc),
        "angle": math.atan2(vr, vc - vt),
        "u": (entry.u_rad - (f_entry - f_burn)) % (2 * math.pi),
    }


def _two_body(thrust_scale: float, grid_step_s: float):
    data = _data()
    data["earth"]["include_j2"] = False
    data["vehicle"]["thrust_per_engine_n"] *= thrust_scale
    data["guidance"]["prediction"].update(
        grid_step_s=grid_step_s, cutoff_time_tolerance_s=grid_step_s * 1e-3
    )
    return deorbit_burn_from_dict(data, "two-body")


def test_without_j2_and_with_a_short_burn_the_solution_tends_to_the_impulsive_one():
    gaps = []
    for scale, step in ((1.0, 5.0), (1000.0, 0.02)):
        problem = _two_body(scale, step)
        ref = _impulsive_reference(problem)
        result = solve_deorbit_burn(problem)
        assert result.converged, result.reason
        assert math.radians(result.burn_angle_deg) == pytest.approx(ref["angle"], abs=1e-9)
        rate = math.sqrt(problem.earth.mu / float(problem.waiting.a) ** 3)
        centre = math.radians(result.u_open_deg) + 0.5 * rate * result.burn_duration_s
        gaps.append(
            (
                abs(result.dv_mps - ref["dv"]),
                abs(math.degrees((centre - ref["u"] + math.pi) % (2 * math.pi) - math.pi)),
                abs(result.entry_speed_error_mps),
            )
        )
    long_burn, short_burn = gaps
    assert short_burn[0] < 0.02 and short_burn[1] < 0.01 and short_burn[2] < 0.02
    assert all(s < g for s, g in zip(short_burn, long_burn, strict=True))
    assert long_burn[0] > 0.5  # the finite burn costs more: the limit is a real one


# --------------------------------------------------------------------------------------------
# The published case: iteration, strategies, burn-angle study
# --------------------------------------------------------------------------------------------
def test_published_case_converges_by_eq_27_within_the_published_iterations(problem, nominal):
    config = problem.config
    assert nominal.converged and nominal.single_burn_feasible
    assert nominal.iterations <= config.published.iterations
    assert abs(nominal.entry_u_error_deg) <= config.guidance.u_tolerance_deg
    assert abs(nominal.entry_fpa_error_deg) < SEED_FPA_DEG  # strategy 2: prediction error only
    history = nominal.history_frame()
    assert len(history) == nominal.iterations
    errors = history["entry_u_error_deg"].abs().to_numpy()
    assert np.all(np.diff(errors) < 0.0)
    # Seed eq. 27, step by step.
    gain = config.guidance.gain_ku
    u_open, u_err = history["u_open_deg"].to_numpy(), history["entry_u_error_deg"].to_numpy()
    np.testing.assert_allclose(u_open[1:], u_open[:-1] - gain * u_err[:-1], atol=1e-9)
    row = nominal.to_row()
    for key in (
        "iterations",
        "u_open_deg",
        "burn_duration_s",
        "dv_mps",
        "burn_angle_deg",
        "entry_u_error_deg",
        "entry_fpa_error_deg",
        "entry_speed_error_mps",
        "converged",
        "reason",
    ):
        assert key in row
    # The burn lowers the orbit: Tsiolkovsky's delta-v of the burn time's propellant.
    vehicle = problem.vehicle
    mass_after = vehicle.mass_kg - vehicle.mass_flow(problem.earth.g0) * nominal.burn_duration_s
    dv = vehicle.isp_s * problem.earth.g0 * math.log(vehicle.mass_kg / mass_after)
    assert nominal.dv_mps == pytest.approx(dv, rel=1e-9)


def test_strategy_1_meets_the_entry_u_from_the_same_plan(problem, nominal):
    result = solve_deorbit_burn(problem, strategy=1)
    assert result.converged and result.strategy == 1
    assert result.u_open_deg == pytest.approx(nominal.u_open_deg, abs=1e-12)
    assert abs(result.along_track_error_km) < SEED_ALONG_TRACK_KM
    assert abs(result.prediction_u_error_deg) < 0.01


def test_burn_angle_study_is_symmetric_and_cheapest_at_zero(problem):
    angle = problem.config.published.zero_speed_error_burn_angle_deg
    study = burn_angle_study(problem, [-angle, 0.0, angle])
    assert study["converged"].all()
    dv = study.set_index("burn_angle_deg")["dv_mps"]
    speed = study.set_index("burn_angle_deg")["entry_speed_error_mps"]
    assert dv[0.0] < dv[angle] and dv[0.0] < dv[-angle]
    assert abs(dv[angle] - dv[-angle]) < 0.2  # mirror burns; J2 breaks the symmetry slightly
    assert speed[angle] > speed[0.0] and speed[-angle] > speed[0.0]


def test_delta_v_and_speed_rise_match_the_seeds_published_figures(problem):
    """Seed 004 sec. 2.5: ~88 m/s at burn angle 0, ~97 m/s at +-27 deg, and an entry speed
    error 1.5 m/s larger at +-27 deg than at 0; each within the case's
    ``published.approximate_tolerance_mps`` (m/s: "~88 m/s" read as 88 +- 1 m/s, the seed
    printing whole m/s; configs/cases/shuttle_deorbit.yaml). Measured 87.48, 96.61 and
    96.46 m/s, a rise of 1.52 m/s (docs/deorbit_burn.md)."""
    published = problem.config.published
    tolerance = published.approximate_tolerance_mps
    angle = published.zero_speed_error_burn_angle_deg
    study = burn_angle_study(problem, [-angle, 0.0, angle]).set_index("burn_angle_deg")
    assert study["converged"].all()
    dv, speed_error = study["dv_mps"], study["entry_speed_error_mps"]
    print(
        f"dv {dv[-angle]:.2f} / {dv[0.0]:.2f} / {dv[angle]:.2f} m/s at -{angle:g} / 0 / +{angle:g}"
    )
    assert abs(dv[0.0] - published.dv_burn_angle_0_mps) <= tolerance
    assert abs(dv[-angle] - published.dv_burn_angle_27_mps) <= tolerance
    assert abs(dv[angle] - published.dv_burn_angle_27_mps) <= tolerance
    rise = (speed_error[-angle] + speed_error[angle]) / 2.0 - speed_error[0.0]
    assert abs(rise - published.speed_error_increase_mps) <= tolerance


# --------------------------------------------------------------------------------------------
# No single-burn solution, bad configuration
# --------------------------------------------------------------------------------------------
def test_waiting_orbit_above_the_transfer_apoapsis_is_reported_not_raised(problem, nominal):
    apoapsis_km = nominal.transfer_mean_apoapsis_altitude_km
    data = _data()
    data["waiting_orbit"]["altitude_km"] = apoapsis_km + 2.0
    result = solve_deorbit_burn(deorbit_burn_from_dict(data))
    assert not result.converged and not result.single_burn_feasible
    assert "no single-burn solution" in result.reason
    assert result.iterations == 0 and math.isnan(result.dv_mps)
    assert result.to_row()["dv_mps"] is None
    data["waiting_orbit"]["altitude_km"] = apoapsis_km - 2.0  # seed eq. 4 holds again
    assert BurnSolver(deorbit_burn_from_dict(data)).impulsive is not None


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        (("guidance", "gain_ku"), 1.5, "guidance.gain_ku = 1.5: out of range, allowed [0.1, 0.9]"),
        (("vehicle", "mass_kg"), -95000.0, "vehicle.mass_kg = -95000.0: out of range"),
        (("entry", "fpa_deg"), 1.1, "entry.fpa_deg = 1.1: out of range, allowed (-30, 0) deg"),
        (
            ("monte_carlo", "dispersions", "eccentricity", "bound"),
            0.2,
            "monte_carlo.dispersions.eccentricity.bound = 0.2: out of range, allowed [0, 0.1)",
        ),
    ],
)
def test_bad_values_are_refused_naming_the_field_and_range(path, value, expected):
    data = _data()
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ConfigError) as err:
        deorbit_burn_from_dict(data, "case.yaml")
    assert expected in str(err.value)


def test_unknown_keys_and_strategies_are_refused():
    data = _data()
    data["guidance"]["strategy"] = 3
    data["guidance"]["gain"] = 0.5
    with pytest.raises(ConfigError) as err:
        deorbit_burn_from_dict(data)
    text = str(err.value)
    assert "guidance.strategy = 3" in text and "guidance.gain: unknown key" in text


# --------------------------------------------------------------------------------------------
# Monte Carlo
# --------------------------------------------------------------------------------------------
def test_dispersions_are_seeded_per_run_and_inside_their_bounds(problem):
    config = problem.config.monte_carlo.dispersions
    draws = [draw_dispersion(config, 11, run) for run in range(200)]
    assert draw_dispersion(config, 11, 7) == draws[7]
    assert draw_dispersion(config, 12, 7) != draws[7]
    assert max(abs(d.delta_a_m) for d in draws) <= config.semi_major_axis.bound_km * 1e3
    assert max(math.hypot(d.delta_ex, d.delta_ey) for d in draws) <= config.eccentricity.bound
    assert max(abs(d.thrust_fraction) for d in draws) <= config.thrust.bound_fraction
    # Uniform: the largest of 200 draws comes close to the bound.
    assert max(abs(d.mass_fraction) for d in draws) > 0.95 * config.mass.bound_fraction
    data = _data()
    data["monte_carlo"]["dispersions"]["thrust"].update(distribution="normal", sigma_level=3.0)
    normal = deorbit_burn_from_dict(data).config.monte_carlo.dispersions
    thrust = np.array([draw_dispersion(normal, 11, run).thrust_fraction for run in range(2000)])
    assert thrust.std() == pytest.approx(normal.thrust.bound_fraction / 3.0, rel=0.1)


def test_monte_carlo_runs_do_not_depend_on_batching(problem):
    whole = run_monte_carlo(problem, 3, [1, 2], seed=5)
    tail = run_monte_carlo(problem, 1, [1, 2], seed=5, first_run=2)
    assert list(whole["run"]) == [0, 0, 1, 1, 2, 2] and list(whole["strategy"]) == [1, 2] * 3
    np.testing.assert_allclose(
        tail["along_track_error_km"].to_numpy(),
        whole[whole["run"] == 2]["along_track_error_km"].to_numpy(),
        rtol=0,
        atol=1e-9,
    )
    summary = monte_carlo_summary(whole).set_index("strategy")
    assert summary.loc[1, "along_track_error_km_max_abs"] < SEED_ALONG_TRACK_KM
    assert summary.loc[2, "entry_fpa_error_deg_max_abs"] < SEED_FPA_DEG


def test_run_id_hashes_what_changes_the_rows_and_nothing_else(problem):
    resolved = problem.resolved()
    base = monte_carlo_run_id(resolved, 10, [1, 2], 5, "v1")
    assert base == monte_carlo_run_id(copy.deepcopy(resolved), 10, [1, 2], 5, "v1")
    execution = copy.deepcopy(resolved)
    execution["monte_carlo"].update(batch_size=3, workers=1, store="elsewhere")
    execution["published"]["iterations"] = 4
    assert monte_carlo_run_id(execution, 10, [1, 2], 5, "v1") == base
    physics = copy.deepcopy(resolved)
    physics["monte_carlo"]["dispersions"]["thrust"]["bound_fraction"] = 0.05
    ids = {
        base,
        monte_carlo_run_id(physics, 10, [1, 2], 5, "v1"),
        monte_carlo_run_id(resolved, 11, [1, 2], 5, "v1"),
        monte_carlo_run_id(resolved, 10, [2], 5, "v1"),
        monte_carlo_run_id(resolved, 10, [1, 2], 6, "v1"),
        monte_carlo_run_id(resolved, 10, [1, 2], 5, "v2"),
    }
    assert len(ids) == 6


def _flow_config(tmp: Path, **monte_carlo) -> str:
    data = _data()
    data["monte_carlo"].update(task_runner="threads", workers=2, **monte_carlo)
    path = tmp / "case.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


def _digest(directory: Path) -> dict[str, str]:
    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob("*.parquet"))
    }


@pytest.fixture(scope="module")
def ten_runs(prefect_server, tmp_path_factory):
    """The flow on 10 runs (batches of 5), run twice on the same store."""
    from flows.deorbit_monte_carlo import deorbit_monte_carlo_flow

    tmp = tmp_path_factory.mktemp("mc")
    config = _flow_config(tmp, runs=10, batch_size=5, store=str(tmp / "runs"))
    before = copy.deepcopy(SIMULATIONS)
    first = deorbit_monte_carlo_flow(config)
    middle = copy.deepcopy(SIMULATIONS)
    digest = _digest(Path(first["directory"]))
    second = deorbit_monte_carlo_flow(config)
    return {
        "config": config,
        "first": first,
        "second": second,
        "runs": (middle["runs"] - before["runs"], SIMULATIONS["runs"] - middle["runs"]),
        "flights": SIMULATIONS["flights"] - middle["flights"],
        "digest": digest,
    }


def test_monte_carlo_flow_publishes_its_plots_themselves(ten_runs):
    """The plots artifact carries every PNG as a data URI (a remote UI shows it)."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import ArtifactFilter, ArtifactFilterKey

    from ovtraj.plots.embed import png_data_uri

    plots = ten_runs["first"]["plots"]
    assert plots
    with get_client(sync_client=True) as client:
        found = client.read_artifacts(
            artifact_filter=ArtifactFilter(
                key=ArtifactFilterKey(any_=["deorbit-monte-carlo-plots"])
            )
        )
    assert any(all(png_data_uri(p) in (a.data or "") for p in plots) for a in found)


def test_monte_carlo_flow_stores_every_run_with_the_schema(ten_runs):
    first = ten_runs["first"]
    run = MonteCarloRun(Path(first["directory"]))
    assert first["status"] == "complete" and run.info["status"] == "complete"
    parts = sorted((run.directory / "runs").glob("part-*.parquet"))
    assert len(parts) == 2
    for part in parts:
        assert pq.read_schema(part).remove_metadata().equals(STORED_RUN_SCHEMA)
    frame = run.results()
    assert len(frame) == 20 and frame["ok"].all()
    assert sorted(set(frame["run"])) == list(range(10))
    assert frame.groupby("run")["strategy"].apply(list).tolist() == [[1, 2]] * 10
    stats = {row["strategy"]: row for row in first["statistics"]}
    assert stats[1]["along_track_error_km_max_abs"] < SEED_ALONG_TRACK_KM
    assert stats[2]["entry_fpa_error_deg_max_abs"] < SEED_FPA_DEG
    # Strategy 2 trades the entry u for the angle: its along-track spread is much wider.
    assert stats[2]["along_track_error_km_std"] > 10 * stats[1]["along_track_error_km_std"]
    for path in first["plots"]:
        assert Path(path).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (run.directory / "summary.json").is_file()


def test_second_identical_flow_run_simulates_nothing(ten_runs):
    assert ten_runs["runs"] == (10, 0) and ten_runs["flights"] == 0
    assert ten_runs["second"]["run_id"] == ten_runs["first"]["run_id"]
    assert ten_runs["second"]["simulated_runs"] == 0
    assert _digest(Path(ten_runs["first"]["directory"])) == ten_runs["digest"]


def test_the_library_driver_stores_the_flows_run_without_prefect(ten_runs, tmp_path):
    """The flow is the library's driver with its batches as tasks: the same study flown in
    this process stores the same run (id, parts, plots, summary but for where it is)."""
    from ovtraj.runs.monte_carlo_pool import PoolFlier
    from ovtraj.runs.runners import RunnerChoice
    from ovtraj.store.monte_carlo import drive_monte_carlo
    from ovtraj.studies.deorbit_burn.stored_monte_carlo import DeorbitMonteCarlo

    flown = ten_runs["first"]
    theirs = Path(flown["directory"])
    study = DeorbitMonteCarlo(
        load_deorbit_burn(ten_runs["config"]),
        runs=10,
        strategies=flown["strategies"],
        seed=flown["seed"],
        root=tmp_path,
        code=MonteCarloRun(theirs).info["code_version"],
        batch_size=5,
    )
    report = drive_monte_carlo(study, PoolFlier(RunnerChoice("serial", 1)))
    ours = Path(report["directory"])
    assert report["run_id"] == flown["run_id"] and report["failed_batches"] == []
    where = {"directory", "plots", "failed_batches"}
    assert {k: v for k, v in report.items() if k not in where} == {
        k: v for k, v in flown.items() if k not in where
    }
    assert [Path(p).name for p in report["plots"]] == [Path(p).name for p in flown["plots"]]
    for name in (
        "config.json",
        *_digest(theirs),
        *(f"plots/{Path(p).name}" for p in flown["plots"]),
    ):
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name


def test_the_command_stores_the_library_drivers_run(tmp_path):
    """`ovtraj deorbit-burn CONFIG --monte-carlo N` flies the flow's study by the one driver
    in its own process (the flow is that driver with its batches as tasks: the test
    above), so it stores the run the library driver stores: the same id, parts, plots and
    summary but for where it is, in the config's ``monte_carlo.store``. Four runs in
    batches of three give two parts, enough to see the batches; the command again flies
    nothing and says where the run and its pictures are."""
    from typer.testing import CliRunner

    from ovtraj.cli import app
    from ovtraj.runs.monte_carlo_pool import PoolFlier
    from ovtraj.runs.runners import RunnerChoice
    from ovtraj.store.monte_carlo import drive_monte_carlo
    from ovtraj.studies.deorbit_burn.stored_monte_carlo import DeorbitMonteCarlo

    runs = 4
    config = _flow_config(tmp_path, batch_size=3, store="command")  # beside the config
    command = ["deorbit-burn", config, "--monte-carlo", str(runs)]
    before = SIMULATIONS["runs"]
    done = CliRunner().invoke(app, [*command, "--json"])
    assert done.exit_code == 0, done.output
    doc = json.loads(done.stdout)
    assert SIMULATIONS["runs"] - before == runs
    mc = doc["monte_carlo_run"]
    ours = tmp_path.resolve() / "command" / mc["run_id"]
    assert mc["directory"] == str(ours) and mc["simulated_runs"] == runs
    assert mc["status"] == "complete" and mc["strategies"] == [1, 2]
    settings = load_deorbit_burn(config).config.monte_carlo
    study = DeorbitMonteCarlo(
        load_deorbit_burn(config),
        runs=runs,
        strategies=[1, 2],
        seed=settings.seed,
        root=tmp_path / "driver",
        code=MonteCarloRun(ours).info["code_version"],
        batch_size=3,
    )
    report = drive_monte_carlo(study, PoolFlier(RunnerChoice("serial", 1)))
    theirs = Path(report["directory"])
    assert report["run_id"] == mc["run_id"] and report["failed_batches"] == []
    # The command's statistics and dispersion figures are the stored run's.
    assert doc["monte_carlo"] == report["statistics"]
    figures = {row["figure"]: row for row in doc["published"]}
    assert [figures[row["figure"]] for row in report["published"]] == report["published"]
    where = {"directory", "plots", "statistics", "published", "failed_batches"}
    assert mc == {k: v for k, v in report.items() if k not in where} | {
        "directory": str(ours),
        "plots": [str(ours / "plots" / Path(p).name) for p in report["plots"]],
    }
    parts = _digest(ours)
    assert list(parts) == ["runs/part-00000.parquet", "runs/part-00003.parquet"]
    assert parts == _digest(theirs)
    for name in ("config.json", *(f"plots/{Path(p).name}" for p in report["plots"])):
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name
    stored = [json.loads((d / "summary.json").read_text()) for d in (ours, theirs)]
    assert [Path(p).name for p in stored[0]["plots"]] == [Path(p).name for p in report["plots"]]
    assert [{k: v for k, v in s.items() if k not in ("directory", "plots")} for s in stored] == [
        {k: v for k, v in stored[1].items() if k not in ("directory", "plots")}
    ] * 2
    # Again: nothing flown, the parts unchanged, the run and its pictures printed.
    before = SIMULATIONS["runs"]
    again = CliRunner().invoke(app, command)
    assert again.exit_code == 0, again.output
    assert SIMULATIONS["runs"] == before and _digest(ours) == parts
    assert f"monte carlo run {mc['run_id']} (0 flown now, the rest stored): {ours}" in again.stdout
    for path in mc["plots"]:
        assert f"  picture: {path}" in again.stdout


def test_a_deleted_run_is_simulated_again_although_its_tasks_are_cached(prefect_server, tmp_path):
    from flows.deorbit_monte_carlo import deorbit_monte_carlo_flow

    config = _flow_config(tmp_path, runs=2, batch_size=1, strategies=[2], store=str(tmp_path))
    first = deorbit_monte_carlo_flow(config)
    shutil.rmtree(first["directory"])
    before = SIMULATIONS["runs"]
    second = deorbit_monte_carlo_flow(config)  # same run id, cached tasks, no files
    assert second["run_id"] == first["run_id"] and SIMULATIONS["runs"] - before == 2
    assert second["stored_runs"] == 2 and second["status"] == "complete"
