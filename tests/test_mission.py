"""The whole-mission chain: stages composed, totals from the stages' own rows."""

from __future__ import annotations

import pytest

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import STAGES, MissionContext, MissionDesign, evaluate


@pytest.fixture(scope="module")
def context(scenario) -> MissionContext:
    fit = find_launch_fit(scenario)
    assert fit is not None, "the reference launch fit must match the default scenario"
    return MissionContext(scenario, fit)


@pytest.fixture(scope="module")
def feasible(context):
    return evaluate(context, MissionDesign(262.9, 345.8, 15.2))


def test_feasible_chain_runs_every_stage(feasible):
    assert feasible.feasible, feasible.reason
    assert feasible.failed_stage is None and feasible.reason is None
    assert list(feasible.stages) == list(STAGES)
    assert all(row["feasible"] for row in feasible.stages.values())
    assert feasible.stages["rendezvous"]["kind"] == "rendezvous"
    assert feasible.stages["transfer"]["kind"] == "transfer"


def test_totals_are_the_sums_of_the_stage_rows(feasible, context):
    s = feasible.stages
    dv = s["rendezvous"]["dv_total_mps"] + s["transfer"]["dv_total_mps"] + s["deorbit"]["dv_mps"]
    assert feasible.dv_total_mps == pytest.approx(dv, rel=1e-12)
    fitted = context.fit.evaluate(262.9e3)
    assert feasible.m_load_kg == pytest.approx(fitted["payload_kg"], rel=1e-12)
    # T_total: drop to terminal interface, rebuilt from the stages' epochs.
    day = context.day
    drop = day.plus_seconds(s["launch"]["drop_time_s"])
    deorbit_epoch = day.plus_seconds(s["transfer"]["burn2_t_s"])
    terminal = deorbit_epoch.plus_seconds(s["deorbit"]["entry_time_s"]).plus_seconds(
        s["reentry"]["flight_time_s"]
    )
    assert feasible.t_total_s == pytest.approx(terminal.seconds_since(drop), abs=1e-3)


def test_stages_hand_over_times_and_states(feasible, context, scenario):
    s = feasible.stages
    stay_s = 3600.0 * (scenario.mission.stay_h + 15.2)
    assert s["transfer"]["t0_s"] == pytest.approx(s["rendezvous"]["burn2_t_s"] + stay_s)
    assert s["rendezvous"]["t0_s"] == pytest.approx(s["launch"]["insertion_time_s"])
    # The launch aims at the target's plane at the rendezvous (tests/test_plane_aim.py: the
    # node offset is the differential J2 regression over the wait): at the first burn the
    # planes nearly coincide.
    assert 0.4 < s["launch"]["raan_offset_deg"] < 0.8
    assert abs(s["rendezvous"]["plane_difference_deg"]) < 0.01
    # The reentry starts where and when the deorbit entered.
    assert s["reentry"]["entry_epoch_utc"][:19] == s["deorbit"]["entry_epoch_utc"][:19]
    assert s["reentry"]["miss_distance_km"] <= scenario.reentry.terminal.miss_tolerance_km


def test_a_failing_stage_ends_the_chain_with_its_reason(context):
    # A parking orbit close to the target's needs a phasing wait over the limit.
    record = evaluate(context, MissionDesign(348.3, 318.3, 18.5))
    assert not record.feasible
    assert record.failed_stage == "rendezvous" and "wait" in record.reason
    assert list(record.stages) == ["launch", "rendezvous"]
    assert record.t_total_s is None and record.dv_total_mps is None


def test_parking_altitude_outside_the_fit_is_a_launch_failure(context):
    record = evaluate(context, MissionDesign(600.0, 345.0, 0.0))
    assert not record.feasible and record.failed_stage == "launch"
    assert "payload_kg" in record.reason and "600" in record.reason
