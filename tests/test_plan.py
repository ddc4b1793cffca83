"""The mission plan (SPEC step 6): building, storing, reading and replaying it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ovtraj.astro.epoch import Epoch
from ovtraj.astro.propagation.reference import propagate_dop853
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.deorbit.result import DeorbitResult
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission.chain import (
    LaunchLeg,
    MissionContext,
    MissionDesign,
    entry_state,
    evaluate,
)
from ovtraj.mission.flight_report import format_flight_report
from ovtraj.mission.fly import fly_plan
from ovtraj.mission.plan import MissionPlan, PlanError
from ovtraj.mission.plan_build import build_plan, plan_and_record
from ovtraj.mission.plan_store import plan_json, read_plan, write_plan
from ovtraj.paths import config_path
from ovtraj.plots.mission import mission_plots
from ovtraj.target_sources import load_scenario

FEASIBLE = MissionDesign(285.06, 326.96, 0.79)
INFEASIBLE = MissionDesign(343.17, 352.06, 1.58)  # the phasing wait exceeds its limit


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(config_path("scenario.yaml"))


@pytest.fixture(scope="module")
def context(scenario):
    fit = find_launch_fit(scenario)
    assert fit is not None, "the reference launch fit is missing (data/reference/launch_fit)"
    return MissionContext(scenario, fit)


@pytest.fixture(scope="module")
def launch_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("launch_solves")


@pytest.fixture(scope="module")
def planned(context, launch_cache):
    return plan_and_record(
        context, FEASIBLE, source={"run_id": "test", "front_index": 3}, launch_cache=launch_cache
    )


@pytest.fixture(scope="module")
def record(planned):
    record = planned[1]
    assert record.feasible, record.reason
    return record


@pytest.fixture(scope="module")
def plan(planned):
    return planned[0]


@pytest.fixture(scope="module")
def replay(plan):
    return fly_plan(plan)


@pytest.fixture(scope="module")
def burn_states(plan, scenario):
    """The OV's state just before each planned impulse, propagated here (scipy DOP853).

    Independent of the chain (heyoka) and of the replay (its own right-hand side).
    """
    earth = scenario.earth
    state = np.r_[plan.launch.insertion_r_eci_m, plan.launch.insertion_v_eci_mps]
    t = plan.launch.insertion_t_s
    states = []
    for burn in plan.impulses():
        state = propagate_dop853(
            state, t, burn.t_s, mu=earth.mu, radius=earth.radius, j2=earth.j2, rtol=1e-12, atol=1e-9
        )
        states.append(state.copy())
        state = state + np.r_[0.0, 0.0, 0.0, burn.dv_eci_mps]
        t = burn.t_s
    return states


def _haversine(lat1, lon1, lat2, lon2, radius):
    lat1, lon1, lat2, lon2 = map(math.radians, (lat1, lon1, lat2, lon2))
    h = (
        math.sin((lat2 - lat1) / 2) ** 2
        + math.cos(lat1) * math.cos(lat2) * math.sin((lon2 - lon1) / 2) ** 2
    )
    return 2 * radius * math.asin(math.sqrt(h))


def _rsw(state):
    r, v = state[:3], state[3:]
    radial = r / np.linalg.norm(r)
    normal = np.cross(r, v) / np.linalg.norm(np.cross(r, v))
    return np.array([radial, np.cross(normal, radial), normal])


def test_replay_lands_within_the_stated_miss_and_near_the_prediction(plan, replay, scenario):
    assert replay.ok, replay.reason
    stated = scenario.reentry.terminal.miss_tolerance_km * 1e3
    assert plan.terminal.stated_miss_m == stated
    # Distances recomputed here from the reported and planned terminal points.
    radius = scenario.earth.radius
    site = scenario.reentry.landing_site
    end = replay.terminal
    miss = _haversine(end["latitude_deg"], end["longitude_deg"], site.latitude_deg,
                      site.longitude_deg, radius)  # fmt: skip
    assert miss == pytest.approx(replay.miss_distance_m, abs=1e-3)
    assert miss <= stated and replay.landed_within_stated_miss
    predicted = plan.terminal
    off = _haversine(end["latitude_deg"], end["longitude_deg"], predicted.latitude_deg,
                     predicted.longitude_deg, radius)  # fmt: skip
    assert off == pytest.approx(replay.prediction_distance_m, abs=1e-3)
    assert off <= 50.0  # measured 2.3 m: the chain's 2 s RK4 against adaptive DOP853
    assert abs(end["altitude_m"] - predicted.altitude_m) < 50.0
    assert end["speed_mps"] == pytest.approx(scenario.reentry.terminal.speed_mps, abs=1e-6)
    assert replay.matches_prediction and replay.passed
    # The replayed entry is where the plan (the deorbit stage) put it.
    assert abs(replay.entry_time_difference_s) < 1e-3
    assert replay.entry_position_difference_m < 1.0
    assert "LANDED" in format_flight_report(replay)


def test_replay_report_is_plain_json_without_nan(replay):
    text = json.dumps(replay.to_dict(), allow_nan=False)
    assert '"landed_within_stated_miss": true' in text


def test_rendezvous_arrival_miss_matches_the_chain(replay, record, scenario):
    chain_miss = record.stages["rendezvous"]["miss_distance_m"]
    epsilon = scenario.tolerances.miss_distance_m
    assert chain_miss < epsilon
    assert replay.rendezvous_arrival_miss_m < epsilon
    # Both are integrator noise around an exact arrival (< 1 cm over 40 h of coasting).
    assert abs(replay.rendezvous_arrival_miss_m - chain_miss) < 0.05


def test_planned_impulses_sum_to_the_chain_total(plan, record):
    magnitudes = [float(np.linalg.norm(b.dv_eci_mps)) for b in plan.impulses()]
    assert len(magnitudes) == 5
    assert sum(magnitudes) == pytest.approx(record.dv_total_mps, rel=1e-12)
    assert [b.dv_mps for b in plan.impulses()] == pytest.approx(magnitudes, rel=1e-12)
    assert plan.totals.dv_total_mps == pytest.approx(record.dv_total_mps, rel=1e-12)
    assert plan.totals.t_total_s == pytest.approx(record.t_total_s, abs=1e-6)
    assert plan.totals.m_load_kg == pytest.approx(record.m_load_kg, rel=1e-12)
    # Epochs in time order, each ISO text agreeing with its seconds from the launch day.
    times = [b.t_s for b in plan.impulses()]
    assert times == sorted(times)
    day = Epoch.from_iso(plan.launch_day_utc)
    for burn in plan.impulses():
        assert Epoch.from_iso(burn.epoch_utc).seconds_since(day) == pytest.approx(
            burn.t_s, abs=1e-5
        )
    assert plan.stay.docking_t_s == plan.rendezvous.burn2.t_s
    assert plan.stay.separation_t_s == plan.transfer.burn1.t_s


def test_replayed_constraint_maxima_are_within_limits_and_match_the_chain(replay, record, scenario):
    limits = scenario.reentry.limits
    row = record.stages["reentry"]
    checks = replay.checks
    pairs = (
        ("max_heat_rate_w_m2", limits.max_heat_rate_kw_m2 * 1e3, row["max_heat_rate_kw_m2"] * 1e3),
        ("max_load_g", limits.max_load_g, row["max_load_g"]),
        ("max_dynamic_pressure_pa", limits.max_dynamic_pressure_kpa * 1e3,
         row["max_dynamic_pressure_kpa"] * 1e3),
    )  # fmt: skip
    for name, limit, chain_value in pairs:
        assert checks[name].value <= limit and checks[name].ok
        assert checks[name].value == pytest.approx(chain_value, rel=0.01), name
    assert checks["min_perigee_altitude_m"].ok
    assert checks["min_perigee_altitude_m"].value > scenario.limits.min_perigee_altitude_km * 1e3
    entry = scenario.deorbit.entry
    assert entry.fpa_min_deg - 1e-4 <= replay.entry["inertial_fpa_deg"] <= entry.fpa_max_deg + 1e-4


def test_local_frame_impulses_agree_with_the_eci_ones(plan, burn_states):
    for burn, state in zip(plan.impulses(), burn_states, strict=True):
        local = _rsw(state) @ np.asarray(burn.dv_eci_mps)
        planned = [burn.dv_radial_mps, burn.dv_along_track_mps, burn.dv_cross_track_mps]
        assert local == pytest.approx(planned, abs=1e-6), burn.name
    # The deorbit burn brakes along the track.
    assert plan.deorbit.burn.dv_along_track_mps < -0.99 * plan.deorbit.burn.dv_mps


def test_plan_holds_the_stages_results(plan, record, scenario, context):
    assert plan.source == {"run_id": "test", "front_index": 3}
    assert plan.scenario == scenario.resolved()
    launch = record.stages["launch"]
    assert plan.launch.insertion_t_s == launch["insertion_time_s"]
    assert plan.launch.payload_kg == launch["payload_kg"]
    r = np.linalg.norm(plan.launch.insertion_r_eci_m) - scenario.earth.radius
    assert r == pytest.approx(FEASIBLE.parking_altitude_km * 1e3, abs=15e3)  # osculating
    programme = plan.launch.programme
    assert set(programme.variables) == set(DESIGN_VARIABLES)
    # The solved launch lies on the fit's branch: its payload within the fit's error.
    fit = context.fit.evaluate(FEASIBLE.parking_altitude_km * 1e3)
    assert plan.launch.payload_kg == pytest.approx(fit["payload_kg"], abs=0.05)
    assert plan.launch.flight_time_s == pytest.approx(fit["flight_time_s"], abs=2.0)
    bank = plan.reentry.bank_profile
    row = record.stages["reentry"]
    assert len(bank.reversals) == row["reversals"]
    assert bank.sigma0_deg == pytest.approx(row["sigma0_deg"], rel=1e-12)
    step = scenario.reentry.integration.step_s
    times = [r.t_from_entry_s / step for r in bank.reversals]
    assert all(abs(t - round(t)) < 1e-9 for t in times)  # reversals at RK4 step starts
    assert [r.sign_after for r in bank.reversals] == [
        -bank.initial_sign * (-1) ** k for k in range(len(bank.reversals))
    ]
    assert plan.terminal.miss_distance_m == pytest.approx(row["miss_distance_km"] * 1e3)


def test_stage_results_reach_the_plan_typed_and_the_entry_state_is_built_once(
    record, plan, context
):
    from ovtraj.reentry import EntryState
    from ovtraj.reentry.result import ReentryResult
    from ovtraj.rendezvous.result import RendezvousResult

    results = record.results
    assert results.missing() == []
    assert isinstance(results.launch, LaunchLeg)
    assert isinstance(results.rendezvous, RendezvousResult)
    assert isinstance(results.transfer, RendezvousResult)
    assert isinstance(results.deorbit, DeorbitResult)
    assert isinstance(results.entry, EntryState)
    assert isinstance(results.reentry, ReentryResult)
    # The hand-off the reentry flew from is the deorbit's, built by one function, and
    # the plan holds exactly it.
    assert entry_state(results.deorbit) == results.entry
    entry = plan.reentry.entry
    assert entry.latitude_deg == math.degrees(results.entry.latitude_rad)
    assert entry.speed_mps == results.entry.speed_mps
    assert entry.heading_deg == math.degrees(results.entry.heading_rad)
    assert plan.launch.payload_kg == results.launch.payload_kg == record.m_load_kg
    assert plan.launch.insertion_r_eci_m == tuple(results.launch.insertion_state[:3])
    # A design that fails early has only the stages it reached.
    failed = evaluate(context, INFEASIBLE)
    assert failed.failed_stage == "rendezvous"
    assert failed.results.missing() == ["transfer", "deorbit", "entry", "reentry"]


def test_the_plan_starts_at_the_drop_and_the_replay_flies_the_ascent(plan, replay, scenario):
    launch = plan.launch
    drop = launch.drop
    earth = scenario.earth
    # The drop state: the configured release point, Mach and path angle on the drop epoch.
    assert drop.t_s == launch.drop_t_s and drop.epoch_utc == launch.drop_epoch_utc
    r = np.asarray(drop.r_eci_m)
    assert np.linalg.norm(r) - earth.radius == pytest.approx(drop.altitude_m, abs=1e-6)
    assert drop.altitude_m == scenario.launch.drop.altitude_km * 1e3
    theta = plan.day.gmst_rad() + earth.omega * drop.t_s
    lon_fixed = math.atan2(r[1], r[0]) - theta
    lat = math.asin(r[2] / np.linalg.norm(r))
    assert math.degrees(lat) == pytest.approx(drop.latitude_deg, abs=1e-9)
    wrapped = (math.degrees(lon_fixed) - drop.longitude_deg + 180.0) % 360.0 - 180.0
    assert wrapped == pytest.approx(0.0, abs=1e-9)
    v_rel = np.asarray(drop.v_eci_mps) - earth.omega * np.array([-r[1], r[0], 0.0])
    from ovtraj.config.physical import default_atmosphere

    sound = default_atmosphere().speed_of_sound(drop.altitude_m)
    assert np.linalg.norm(v_rel) == pytest.approx(drop.mach * sound, rel=1e-3)  # table
    assert launch.drop_t_s + launch.flight_time_s == pytest.approx(launch.insertion_t_s)
    # The replay starts there: the programme flown again reaches the plan's insertion.
    assert replay.start == "drop"
    insertion = replay.insertion
    assert insertion["position_difference_m"] < 1e-6
    assert insertion["velocity_difference_mps"] < 1e-9
    # The same epoch to an ulp of its ~5e4 s (7e-12 s): the plan's sum and the replay's
    # need not round alike in every build of the numerical libraries.
    assert insertion["time_difference_s"] == pytest.approx(0.0, abs=1e-9)
    assert insertion["payload_kg"] == pytest.approx(launch.payload_kg)
    for name in ("ascent_max_dynamic_pressure_pa", "ascent_max_axial_load_g"):
        check = replay.checks[name]
        assert check.ok and check.value > 0.0
    assert replay.checks["ascent_max_dynamic_pressure_pa"].value == pytest.approx(
        launch.max_dynamic_pressure_pa, rel=1e-9
    )


def test_a_programme_the_scenario_does_not_fly_fails_the_replay(plan):
    data = plan.to_dict()
    data["launch"]["programme"]["azimuth_deg"] += 1.0
    report = fly_plan(MissionPlan.model_validate(data))
    assert not report.ok and "azimuth" in report.reason


def test_the_solved_launch_is_cached_by_its_inputs_and_checked_when_read(
    context, launch_cache, plan, monkeypatch
):
    from ovtraj.launch import exact

    (stored,) = [p for p in launch_cache.iterdir() if p.is_dir()]
    assert sorted(f.name for f in stored.iterdir()) == ["launch.json", "meta.json"]
    row = json.loads((stored / "launch.json").read_text())
    assert "wall_time_s" not in row and "match_time_s" not in row  # no timing stored
    assert row["match_iterations"] >= 1  # solved to the chain's insertion

    def no_solve(*_args, **_kwargs):
        raise AssertionError("the cached launch was solved again")

    monkeypatch.setattr(exact, "solve_launch_to_point", no_solve)
    again = build_plan(
        context, FEASIBLE, source={"run_id": "test", "front_index": 3}, launch_cache=launch_cache
    )
    assert again == plan
    # A changed cache file is refused naming it; nothing is solved over it.
    (stored / "launch.json").write_text(json.dumps({**row, "payload_kg": 999.0}))
    with pytest.raises(PlanError, match=r"launch\.json"):
        build_plan(context, FEASIBLE, source={}, launch_cache=launch_cache)


def test_json_and_yaml_round_trip_and_no_overwrite(plan, tmp_path):
    json_path, yaml_path = write_plan(plan, tmp_path, "chosen")
    assert read_plan(json_path) == plan
    assert read_plan(yaml_path) == plan
    assert plan_json(read_plan(yaml_path)) == json_path.read_bytes()
    before = (json_path.read_bytes(), yaml_path.read_bytes())
    assert write_plan(plan, tmp_path, "chosen") == (json_path, yaml_path)  # same: no-op
    other = plan.model_copy(update={"source": {"run_id": "another"}})
    with pytest.raises(PlanError, match="refusing to overwrite"):
        write_plan(other, tmp_path, "chosen")
    assert (json_path.read_bytes(), yaml_path.read_bytes()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chosen.json", "chosen.yaml"]


def test_read_plan_names_the_file_and_the_field(plan, tmp_path):
    data = plan.to_dict()
    data["reentry"]["bank_profile"]["sigma0_deg"] = "steep"
    del data["terminal"]["stated_miss_m"]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(PlanError) as err:
        read_plan(bad)
    text = str(err.value)
    assert str(bad) in text
    assert "reentry.bank_profile.sigma0_deg" in text
    assert "terminal.stated_miss_m" in text
    broken = tmp_path / "broken.yaml"
    broken.write_text("schema_version: [unclosed\n")
    with pytest.raises(PlanError, match=r"broken\.yaml: not valid YAML"):
        read_plan(broken)
    old = tmp_path / "old.json"
    old.write_text(json.dumps({**plan.to_dict(), "schema_version": "ovtraj.mission-plan/0"}))
    with pytest.raises(PlanError, match=r"old\.json: schema_version"):
        read_plan(old)


def test_infeasible_design_raises_naming_the_stage(context, launch_cache):
    with pytest.raises(PlanError, match="rendezvous") as err:
        build_plan(context, INFEASIBLE, source={}, launch_cache=launch_cache)
    assert err.value.stage == "rendezvous"
    assert "wait" in err.value.reason


def test_perturbed_deorbit_burn_misses_the_stated_distance(plan, burn_states):
    along = _rsw(burn_states[-1])[1]
    data = plan.to_dict()
    dv = np.asarray(data["deorbit"]["burn"]["dv_eci_mps"]) + 1.0 * along  # +1 m/s along track
    data["deorbit"]["burn"]["dv_eci_mps"] = dv.tolist()
    report = fly_plan(MissionPlan.model_validate(data))
    assert report.miss_distance_m > plan.terminal.stated_miss_m
    assert not report.landed_within_stated_miss and not report.passed
    assert "NOT within" in format_flight_report(report)


def test_unflyable_plan_is_a_failed_report_not_an_exception(plan):
    data = plan.to_dict()
    data["deorbit"]["burn"]["dv_eci_mps"] = [0.0, 0.0, 0.0]  # never comes down
    report = fly_plan(MissionPlan.model_validate(data))
    assert not report.ok and not report.landed_within_stated_miss
    assert "entry interface" in report.reason
    json.dumps(report.to_dict(), allow_nan=False)


def test_mission_plots_write_three_pngs(record, scenario, tmp_path):
    paths = mission_plots(record.trajectories, scenario, tmp_path, prefix="m")
    assert len(paths) == 3 and len(set(paths)) == 3
    for path in paths:
        data = path.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)


def test_the_plan_launch_inserts_where_the_front_evaluation_starts(context, record, plan):
    """The launch is solved to the chain's own insertion (the plane aimed at the rendezvous):
    the plan's chain starts within the match tolerances of the front's, and flies the same
    totals."""
    settings = context.scenario.mission.insertion.launch_match
    front = evaluate(context, FEASIBLE)
    leg, planned = front.results.launch, record.results.launch
    assert leg.source == "launch fit" and planned.source == "solved launch"
    miss = planned.insertion_state - leg.insertion_state
    assert np.linalg.norm(miss[:3]) <= settings.position_tolerance_m
    assert np.linalg.norm(miss[3:]) <= settings.velocity_tolerance_mps
    assert planned.insertion_time_s == leg.insertion_time_s
    assert abs(planned.flight_time_s - leg.flight_time_s) <= settings.flight_time_tolerance_s
    assert planned.raan_offset_deg == leg.raan_offset_deg and plan.launch.plane_raan_offset_deg
    tolerance = context.scenario.mission.plan.front_tolerance
    assert abs(record.dv_total_mps - front.dv_total_mps) <= tolerance.dv_total_mps
    assert abs(record.t_total_s - front.t_total_s) <= tolerance.t_total_s
    assert abs(record.m_load_kg - front.m_load_kg) <= tolerance.m_load_kg
    # The programme is the payload optimum of that insertion: within the path limits, its
    # payload within the front's tolerance of the launch fit's (the unconstrained optimum).
    launch = context.scenario.launch
    limit_pa = 1e3 * launch.launcher.limits.max_dynamic_pressure_kpa
    slack = 1.0 + launch.insertion_tolerances.path_limit_fraction
    assert plan.launch.max_dynamic_pressure_pa <= limit_pa * slack
    assert plan.launch.payload_kg == pytest.approx(front.m_load_kg, abs=tolerance.m_load_kg)


def test_a_plan_off_its_front_point_is_refused_saying_by_how_much_and_why(record):
    """check_front_point (what `ovtraj plan` and the pipeline run before writing)."""
    from ovtraj.config.mission import FrontTolerance
    from ovtraj.mission.plan_check import PlanMismatch, check_front_point

    tolerance = FrontTolerance(dv_total_mps=1.0, t_total_s=60.0, m_load_kg=0.1)
    front = {"dv_total_mps": record.dv_total_mps, "t_total_s": record.t_total_s}
    front["m_load_kg"] = record.m_load_kg
    check_front_point(record, front, {}, tolerance, "front point 3")  # the same: no error
    stored = {k: dict(v) for k, v in record.stages.items()}
    stored["rendezvous"]["dv_total_mps"] -= 50.0
    stored["rendezvous"]["wait_time_s"] -= 1255.0
    moved = front | {"dv_total_mps": front["dv_total_mps"] - 50.0}
    moved["t_total_s"] -= 86400.0
    with pytest.raises(PlanMismatch) as raised:
        check_front_point(record, moved, stored, tolerance, "front point 3")
    error = raised.value
    assert len(error.differences) == 2
    assert error.differences[0].startswith("dV_total") and "+50" in error.differences[0]
    assert error.differences[1].startswith("T_total") and "+24" in error.differences[1]
    assert any(c.startswith("rendezvous dV") for c in error.causes)
    assert any(c.startswith("phasing wait") for c in error.causes)
    assert "front point 3 does not fly its front values" in str(error)
