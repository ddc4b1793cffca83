"""Rendezvous stage (patent step 102) against independent references."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from ovtraj.astro.elements import coe_to_rv, rv_to_coe, rv_to_nonsingular
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.astro.propagation.reference import propagate_dop853
from ovtraj.rendezvous import (
    RendezvousInput,
    TransferInput,
    circular_transfer,
    hohmann,
    lead_angle,
    rendezvous_input,
    solve_rendezvous,
)
from tests.conftest import REQUIRED_KEYS, build_scenario

KM = 1e3


# --- two-body Hohmann ------------------------------------------------------


def test_hohmann_vallado_example_6_1():
    """Vallado, 4th ed., Example 6-1: 191.34411 km to 35781.34857 km (LEO to GEO)."""
    mu, re = 398600.4418e9, 6378.137e3
    t = hohmann(re + 191.34411 * KM, re + 35781.34857 * KM, mu)
    assert t.dv1_mps / KM == pytest.approx(2.457038, rel=1e-5)
    assert t.dv2_mps / KM == pytest.approx(1.478187, rel=1e-5)
    assert t.total_dv_mps / KM == pytest.approx(3.935224, rel=1e-5)
    assert t.transfer_time_s / 3600 == pytest.approx(5.256713, rel=1e-5)


def test_hohmann_downwards_mirrors_upwards(earth):
    up = hohmann(7000 * KM, 8000 * KM, earth.mu)
    down = hohmann(8000 * KM, 7000 * KM, earth.mu)
    assert down.dv1_mps == pytest.approx(-up.dv2_mps)
    assert down.dv2_mps == pytest.approx(-up.dv1_mps)
    assert down.transfer_time_s == pytest.approx(up.transfer_time_s)


def test_hohmann_refuses_nonsense():
    with pytest.raises(ValueError, match="must be positive"):
        hohmann(-1.0, 7e6, 3.986e14)


def test_lead_angle_by_numerical_two_body_propagation(earth):
    """Place the target at the lead angle, fly the Hohmann arc with an integrator: they meet."""
    r1, r2 = earth.radius + 300 * KM, earth.radius + 420 * KM
    transfer = hohmann(r1, r2, earth.mu)
    lead = lead_angle(transfer, math.sqrt(earth.mu / r2**3))
    inc = math.radians(51.6)
    rc, vc = coe_to_rv(r1, 0.0, inc, 0.3, 0.0, 0.7, mu=earth.mu)
    rt, vt = coe_to_rv(r2, 0.0, inc, 0.3, 0.0, 0.7 + lead, mu=earth.mu)
    chaser = np.r_[rc, vc + transfer.dv1_mps * vc / np.linalg.norm(vc)]
    prop = OrbitPropagator(earth, tol=1e-12, j2=False)
    arrival_c = prop.propagate(chaser, 0.0, transfer.transfer_time_s).state
    arrival_t = prop.propagate(np.r_[rt, vt], 0.0, transfer.transfer_time_s).state
    assert np.linalg.norm(arrival_c[:3] - arrival_t[:3]) < 1e-3
    speed_gap = np.linalg.norm(arrival_t[3:]) - np.linalg.norm(arrival_c[3:])
    assert speed_gap == pytest.approx(transfer.dv2_mps, abs=1e-6)


# --- the stage ----------------------------------------------------------------


@pytest.fixture(scope="module")
def default_result(scenario):
    return solve_rendezvous(rendezvous_input(scenario))


def test_default_scenario_meets_epsilon_dis(scenario, default_result):
    r = default_result
    assert r.feasible, r.reason
    assert r.miss_distance_m <= scenario.tolerances.miss_distance_m
    assert 0.0 < r.wait_time_s <= scenario.rendezvous.max_wait_time_s
    # Going up: the target leads; J2 moves the lead by a fraction of a degree.
    assert 0.0 < r.lead_angle_rad < math.radians(10.0)
    assert abs(r.lead_angle_rad - r.lead_angle_two_body_rad) < math.radians(1.0)
    # The J2 answer costs more than the ideal two-body Hohmann, but not absurdly more.
    two_body = r.dv1_two_body_mps + r.dv2_two_body_mps
    assert two_body < r.dv_total_mps < 1.3 * two_body


def test_reported_burns_reach_the_target_with_a_second_integrator(scenario, earth, default_result):
    """Re-fly the reported manoeuvre with DOP853 from the scenario's initial states."""
    r, inp = default_result, rendezvous_input(scenario)
    args = {"mu": earth.mu, "radius": earth.radius, "j2": earth.j2, "rtol": 1e-13, "atol": 1e-7}
    chaser_at_burn = propagate_dop853(inp.chaser_state, 0.0, r.burn1.t_s, **args)
    chaser_at_burn[3:] += r.burn1.eci_mps
    chaser = propagate_dop853(chaser_at_burn, r.burn1.t_s, r.burn2.t_s, **args)
    target = propagate_dop853(inp.target_state, 0.0, r.burn2.t_s, **args)
    assert np.linalg.norm(chaser[:3] - target[:3]) < scenario.tolerances.miss_distance_m
    chaser[3:] += r.burn2.eci_mps
    assert np.linalg.norm(chaser[3:] - target[3:]) < 1e-3


def test_impulses_in_both_frames_agree(default_result):
    for burn in (default_result.burn1, default_result.burn2):
        assert np.linalg.norm(burn.rsw_mps) == pytest.approx(burn.magnitude_mps, rel=1e-12)
        # Raising the orbit: both burns are mostly along-track and prograde.
        assert burn.rsw_mps[1] > 0.5 * burn.magnitude_mps


def test_row_and_trajectory_table(default_result):
    row = default_result.to_row()
    assert REQUIRED_KEYS <= row.keys()
    assert json.loads(json.dumps(row)) == row
    assert not any(isinstance(v, float) and not math.isfinite(v) for v in row.values())
    table = default_result.trajectory
    assert set(table["phase"]) == {"wait", "transfer"}
    assert np.all(np.diff(table["t_s"]) >= 0)
    assert table["range_m"].iloc[-1] < 10.0
    assert table["t_s"].iloc[-1] == pytest.approx(default_result.burn2.t_s)


def test_row_and_table_round_trip_through_parquet(default_result, tmp_path):
    rows = pd.DataFrame([default_result.to_row()])
    rows.to_parquet(tmp_path / "row.parquet")
    again = pd.read_parquet(tmp_path / "row.parquet")
    assert again.iloc[0]["dv1_mps"] == pytest.approx(default_result.burn1.magnitude_mps)
    default_result.trajectory.to_parquet(tmp_path / "trajectory.parquet")
    table = pd.read_parquet(tmp_path / "trajectory.parquet")
    assert len(table) == len(default_result.trajectory)
    assert not table.isna().any().any()  # a rendezvous has its target all along


def test_two_body_limit_recovers_hohmann_exactly(scenario):
    """With J2 = 0 the stage must return the closed-form Hohmann transfer and lead angle."""
    data = scenario.resolved()
    data["earth"]["j2"] = 0.0
    data["parking_orbit"]["element_set"] = "osculating"
    data["target"]["orbit"].update(eccentricity=0.0, arg_perigee_deg=0.0, true_anomaly_deg=20.0)
    flat = build_scenario(data)
    r = solve_rendezvous(rendezvous_input(flat))
    assert r.feasible, r.reason
    ideal = hohmann(
        flat.earth.radius + flat.parking_orbit.altitude_km * KM,
        flat.target.orbit.semi_major_axis_km * KM,
        flat.earth.mu,
    )
    assert r.burn1.magnitude_mps == pytest.approx(ideal.dv1_mps, rel=1e-6)
    assert r.burn2.magnitude_mps == pytest.approx(ideal.dv2_mps, rel=1e-6)
    assert r.transfer_time_s == pytest.approx(ideal.transfer_time_s, rel=1e-6)
    assert r.lead_angle_rad == pytest.approx(r.lead_angle_two_body_rad, abs=1e-6)
    assert r.plane_difference_rad == pytest.approx(0.0, abs=1e-9)


def _random_coplanar_input(scenario, rng) -> RendezvousInput:
    earth = scenario.earth
    h1, h2 = rng.uniform(200, 900, 2) * KM
    while abs(h1 - h2) < 80 * KM:  # close altitudes need weeks of phasing
        h1, h2 = rng.uniform(200, 900, 2) * KM
    inc, raan = math.radians(rng.uniform(5, 98)), rng.uniform(0, 2 * math.pi)
    u1, u2 = rng.uniform(0, 2 * math.pi, 2)
    rc, vc = coe_to_rv(earth.radius + h1, 0.0, inc, raan, 0.0, u1, mu=earth.mu)
    rt, vt = coe_to_rv(earth.radius + h2, 0.0, inc, raan, 0.0, u2, mu=earth.mu)
    settings = scenario.rendezvous.model_copy(update={"max_wait_time_s": 20 * 86400.0})
    return RendezvousInput(
        epoch=scenario.epoch,
        t0_s=0.0,
        chaser_state=np.r_[rc, vc],
        target_state=np.r_[rt, vt],
        settings=settings,
        miss_tolerance_m=scenario.tolerances.miss_distance_m,
        max_impulse_mps=1000.0,
        integrator_tol=scenario.tolerances.integrator,
        earth=earth,
    )


@pytest.mark.parametrize("seed", range(6))
def test_random_coplanar_pairs_meet_epsilon_dis(scenario, seed):
    inp = _random_coplanar_input(scenario, np.random.default_rng(seed))
    r = solve_rendezvous(inp)
    assert r.feasible, r.reason
    assert r.miss_distance_m <= scenario.tolerances.miss_distance_m
    # Independent check of the arrival with the second integrator.
    earth = scenario.earth
    args = {"mu": earth.mu, "radius": earth.radius, "j2": earth.j2, "rtol": 1e-13, "atol": 1e-7}
    c = propagate_dop853(inp.chaser_state, 0.0, r.burn1.t_s, **args)
    c[3:] += r.burn1.eci_mps
    c = propagate_dop853(c, r.burn1.t_s, r.burn2.t_s, **args)
    t = propagate_dop853(inp.target_state, 0.0, r.burn2.t_s, **args)
    assert np.linalg.norm(c[:3] - t[:3]) < 2 * scenario.tolerances.miss_distance_m


def test_a_given_target_coast_is_used_where_it_covers_and_agrees(scenario):
    """A shared target ephemeris (the mission chain's) gives the result of the stage's own
    target propagation; one that does not reach back to t0 is ignored, one too short is
    extended by the stage's own propagation."""
    inp = rendezvous_input(scenario)
    prop = OrbitPropagator(scenario.earth, tol=scenario.tolerances.integrator)
    alone = solve_rendezvous(inp)
    assert alone.feasible, alone.reason
    # The target's trajectory from 1000 s before t0, on the input's time axis.
    before = prop.propagate(inp.target_state, inp.t0_s, inp.t0_s - 1000.0).state
    long = prop.propagate(before, inp.t0_s - 1000.0, inp.t0_s + 5 * 86400.0, dense=True)
    short = prop.propagate(before, inp.t0_s - 1000.0, inp.t0_s + 600.0, dense=True)
    late = prop.propagate(inp.target_state, inp.t0_s + 60.0, inp.t0_s + 5 * 86400.0, dense=True)
    for coast in (long, short, late):
        shared = solve_rendezvous(RendezvousInput(**{**inp.__dict__, "target_coast": coast}))
        assert shared.feasible, shared.reason
        assert shared.dv_total_mps == pytest.approx(alone.dv_total_mps, abs=1e-4)
        assert shared.burn2.t_s == pytest.approx(alone.burn2.t_s, abs=1e-2)
        assert shared.miss_distance_m <= scenario.tolerances.miss_distance_m


# --- cases the stage does not handle: infeasible with a reason, never raised ------


def _solve(data):
    return solve_rendezvous(rendezvous_input(build_scenario(data)))


def test_plane_difference_is_refused(scenario_data):
    scenario_data["parking_orbit"]["inclination_offset_deg"] = 5.0
    r = _solve(scenario_data)
    assert not r.feasible
    assert "plane difference 5.0" in r.reason and "max_plane_difference_deg" in r.reason
    row = r.to_row()
    assert row["dv1_mps"] is None and row["miss_distance_m"] is None


def test_wait_longer_than_allowed(scenario_data):
    scenario_data["rendezvous"]["max_wait_time_s"] = 600.0
    r = _solve(scenario_data)
    assert not r.feasible and "phasing needs a wait" in r.reason


def test_elliptic_target_is_refused(scenario_data):
    scenario_data["target"]["orbit"]["eccentricity"] = 0.02  # perigee ~280 km, e > 0.01
    r = _solve(scenario_data)
    assert not r.feasible and "not near-circular" in r.reason


def test_impulse_above_the_vehicle_limit(scenario_data):
    scenario_data["vehicle"]["max_impulse_mps"] = 20.0
    r = _solve(scenario_data)
    assert not r.feasible and "exceeds the OV's maximum 20 m/s" in r.reason
    assert r.burn1 is not None  # the solution is still reported


def test_same_orbit_never_phases(scenario):
    inp = rendezvous_input(scenario)
    prop = OrbitPropagator(scenario.earth, tol=scenario.tolerances.integrator)
    ahead = prop.propagate(inp.target_state, 0.0, 600.0).state  # same orbit, 10 min ahead
    same = RendezvousInput(
        **{**inp.__dict__, "chaser_state": inp.target_state, "target_state": ahead}
    )
    r = solve_rendezvous(same)
    assert not r.feasible
    assert "same period" in r.reason or "phasing needs a wait" in r.reason


def test_numerical_failure_is_infeasible_not_raised(scenario, monkeypatch):
    """A J2 flow that cannot be integrated (e.g. a trajectory through the Earth's centre)."""

    def fail(self, state0, t0, t1):
        raise FloatingPointError("variational propagation failed: err_nf_state")

    monkeypatch.setattr(OrbitPropagator, "propagate_with_stm", fail)
    r = solve_rendezvous(rendezvous_input(scenario))
    assert not r.feasible
    assert "numerical failure" in r.reason and "err_nf_state" in r.reason
    assert r.to_row()["dv1_mps"] is None


def test_malformed_state_is_a_clear_error(scenario):
    inp = rendezvous_input(scenario)
    bad = RendezvousInput(**{**inp.__dict__, "chaser_state": np.full(6, np.nan)})
    with pytest.raises(ValueError, match="chaser_state must be a finite ECI state"):
        solve_rendezvous(bad)


# --- transfer to a circular orbit with no target ------------------------------


@pytest.mark.parametrize("altitude_km", [420.0, 250.0])
def test_circular_transfer_ends_on_a_circular_orbit(scenario, altitude_km):
    inp = rendezvous_input(scenario)
    r = circular_transfer(
        TransferInput(
            epoch=inp.epoch,
            t0_s=0.0,
            chaser_state=inp.target_state if altitude_km < 300 else inp.chaser_state,
            target_altitude_m=altitude_km * KM,
            settings=inp.settings,
            miss_tolerance_m=inp.miss_tolerance_m,
            max_impulse_mps=inp.max_impulse_mps,
            integrator_tol=inp.integrator_tol,
            earth=inp.earth,
            burn_time_s=1000.0,
        )
    )
    assert r.feasible, r.reason
    assert r.wait_time_s == pytest.approx(1000.0)
    # Before the burn there is no (virtual) target: missing values, never NaN.
    table = r.trajectory
    before = table["t_s"] < r.burn1.t_s
    assert before.any() and table.loc[before, "range_m"].isna().all()
    assert not np.isnan(table.loc[~before, "range_m"].to_numpy(dtype=float)).any()
    earth = scenario.earth
    # Orbit-average of the osculating elements over a day, by numerical integration:
    # the mean semi-major axis must be the requested one, the eccentricity ~0.
    prop = OrbitPropagator(earth, tol=1e-12)
    times = r.burn2.t_s + np.linspace(0.0, 86400.0, 8641)
    states = prop.propagate_grid(r.final_state, r.burn2.t_s, times)
    a = np.asarray(rv_to_coe(states[:, :3], states[:, 3:], mu=earth.mu).a)
    ns = rv_to_nonsingular(states[:, :3], states[:, 3:], mu=earth.mu)
    assert np.mean(a) - earth.radius == pytest.approx(altitude_km * KM, abs=50.0)
    # Osculating e of a mean-circular LEO orbit is ~1e-3 (J2); its average vanishes.
    assert math.hypot(np.mean(ns.ex), np.mean(ns.ey)) < 1e-4


# --- the correction's derivatives --------------------------------------------


@pytest.mark.parametrize("free_epoch", [False, True])
def test_correction_derivatives_match_central_differences_of_propagations(earth, free_epoch):
    """The compiled candidate terms (cost gradient and miss Jacobian from the STM and the
    J2 field) against central differences of the same quantities, each point flown
    again with a Taylor integrator: the transfer time, the burn epoch and the impulse."""
    from ovtraj.rendezvous.correction import _transfer_terms

    prop = OrbitPropagator(earth, tol=1e-14)
    chaser0 = coe_to_rv(
        earth.radius + 300 * KM, 1e-4, math.radians(51.6), 0.3, 0.0, 0.0, mu=earth.mu
    )
    target0 = coe_to_rv(
        earth.radius + 420 * KM, 1e-4, math.radians(51.6), 0.3, 0.0, 0.4, mu=earth.mu
    )
    chaser0, target0 = np.concatenate(chaser0), np.concatenate(target0)
    burn0, hohmann_s, dv_scale = 600.0, 2760.0, 60.0
    n = 5 if free_epoch else 4
    to_scaled = np.array([dv_scale] * 3 + [hohmann_s] * 2)[:n]

    def fly(x):
        burn = burn0 + (x[4] * hohmann_s if free_epoch else 0.0)
        arrival = burn + x[3] * hohmann_s
        after = prop.propagate(chaser0, 0.0, burn).state + np.r_[0.0, 0.0, 0.0, x[:3] * dv_scale]
        final, stm = prop.propagate_with_stm(after, burn, arrival)
        target = prop.propagate(target0, 0.0, arrival).state
        return final, stm, target

    def terms(x):
        final, stm, target = fly(x)
        grav = (earth.mu, earth.radius, earth.j2)
        cost, grad, d_miss, *_ = _transfer_terms(
            x[None], final[None], stm[None], target[None], dv_scale, to_scaled, *grav
        )
        return cost[0], grad[0], d_miss[0], final[:3] - target[:3]

    x = np.array([0.9, 0.05, -0.02, 1.02, 0.01][:n])
    _, grad, d_miss, _ = terms(x)
    step = 1e-6
    for j in range(n):
        e = np.zeros(n)
        e[j] = step
        cost_hi, _, _, miss_hi = terms(x + e)
        cost_lo, _, _, miss_lo = terms(x - e)
        assert (cost_hi - cost_lo) / (2 * step) == pytest.approx(grad[j], rel=1e-6, abs=1e-9)
        # The miss moves by ~1e3 km per unit of a scaled variable: 0.1 m of it is 1e-10.
        np.testing.assert_allclose(
            (miss_hi - miss_lo) / (2 * step), d_miss[:, j], rtol=1e-6, atol=0.1
        )
