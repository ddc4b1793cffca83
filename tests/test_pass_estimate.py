"""The closed-form pass estimate and the pass model of T_total.

References: the deorbit stage's own forecast, which integrates the orbit under J2 and finds
the latitude crossings by events (a second method), and the mission chain's T_total on the
reference designs (stored in ``data/reference/mission_chain/``), each predicted by the model
calibrated on the other designs (held out from its own calibration).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ovtraj.astro.epoch import Epoch
from ovtraj.deorbit.inputs import deorbit_input
from ovtraj.deorbit.pass_estimate import first_pass_s
from ovtraj.deorbit.stage import burn_estimate, first_burn_time_s, forecast_of
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import evaluate, reference
from ovtraj.paths import config_path
from ovtraj.pipeline.pass_model import PassModel
from ovtraj.target_sources import load_scenario
from ovtraj.target_state import circular_orbit_state

# Crossing times: mean vs osculating argument of latitude under J2 (~1e-3 rad, ~1 s) and
# the crossing found by an event on the integrated orbit.
CROSSING_TOLERANCE_S = 30.0


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(config_path("scenario.yaml"))


def _stage_first_pass(scenario, state0, epoch):
    """The first pass the deorbit stage would try: in the region, burn not too early."""
    inp = deorbit_input(scenario, state0=state0, epoch=epoch)
    forecast = forecast_of(inp)
    for track_pass in forecast.in_region:
        estimate = burn_estimate(inp, track_pass.state, inp.entry.fpa_target_rad)
        if first_burn_time_s(track_pass, estimate) + inp.solver.burn_window_s >= 0.0:
            return track_pass.crossing_t_s, inp
    return math.nan, inp


def test_the_closed_form_pass_is_the_integrated_forecasts(scenario):
    rng = np.random.default_rng(21)
    epoch = Epoch.from_iso(scenario.launch.launch_date_utc)
    inclination = math.radians(scenario.target.orbit.inclination_deg)
    agreed, cases = 0, 12
    for _ in range(cases):
        altitude = rng.uniform(300e3, 380e3)
        raan, u = rng.uniform(0.0, 2 * math.pi, size=2)
        state0 = circular_orbit_state(
            altitude, inclination, raan, u, element_set="mean", earth=scenario.earth
        )
        integrated, inp = _stage_first_pass(scenario, state0, epoch)
        closed = first_pass_s(
            0.0,
            u,
            raan,
            inclination,
            scenario.earth.radius + altitude,
            entry=inp.entry,
            earth=scenario.earth,
            earth_angle_at_zero_rad=epoch.gmst_rad(),
            horizon_s=inp.horizon_s,
            burn_window_s=inp.solver.burn_window_s,
        )[0]
        assert np.isfinite(integrated) and np.isfinite(closed)
        agreed += abs(closed - integrated) <= CROSSING_TOLERANCE_S
    # A crossing at the box's edge can fall on either side; the rest agree.
    assert agreed >= cases - 1


def test_an_orbit_that_never_reaches_the_entry_latitude_has_no_pass(scenario):
    inp = deorbit_input(scenario, state0=np.ones(6), epoch=Epoch.from_iso(scenario.epoch_utc))
    low = abs(inp.entry.latitude_rad) - 0.1
    times = first_pass_s(
        [0.0, 100.0],
        0.0,
        0.0,
        low,
        scenario.earth.radius + 350e3,
        entry=inp.entry,
        earth=scenario.earth,
        earth_angle_at_zero_rad=0.0,
        horizon_s=inp.horizon_s,
        burn_window_s=inp.solver.burn_window_s,
    )
    assert times.shape == (2,) and np.isnan(times).all()


def test_the_pass_model_gives_the_chains_t_total_on_the_reference_designs(scenario):
    settings = reference.load_settings()
    context = reference.context(settings)
    designs = reference.designs(context.scenario, settings)
    stored, _ = reference.load()
    waits, totals = [], []
    for design in designs:
        record = evaluate(context, design)
        waits.append((record.stages.get("rendezvous") or {}).get("wait_time_s", np.nan))
        totals.append(record.t_total_s if record.feasible else np.nan)
    totals = np.array(totals, dtype=float)
    assert np.allclose(totals, stored["t_total_s"], atol=1.0, equal_nan=True)
    table = np.array(
        [[d.parking_altitude_km, d.preparation_altitude_km, d.separation_delay_h] for d in designs]
    )
    fit = find_launch_fit(scenario)
    model = PassModel.of(scenario, fit.series["insertion_time_s"], fit.series["flight_time_s"])
    shift = scenario.mission.surrogate.pass_forecast.longitude_shift_deg
    assert model.longitude_shift_rad == pytest.approx(math.radians(shift))  # the scenario's
    waits = np.array(waits, float)
    # The offset is the descent and entry after the pass: about half an hour.
    assert 0.3 * 3600 <= model.calibrated(table, waits, totals).offset_s <= 0.7 * 3600
    predicted = _held_out_t_total_s(model, table, waits, totals)
    feasible = np.isfinite(totals)
    error_h = np.abs(predicted - totals)[feasible] / 3600.0
    # T_total steps by whole days; a regressor of the design missed it by 12-29 h (median,
    # docs/optimize.md). The pass model places the step: within 0.1 h on every feasible
    # design (the hypercube's 17 and the two where the deorbit passes over a dear pass),
    # each held out from the calibration that predicts it.
    assert int(feasible.sum()) == int(stored["feasible"].sum()) == 19
    print(f"held out: worst {error_h.max():.3f} h")  # measured 0.020 h
    assert (error_h <= 0.1).all(), error_h
    unshifted = replace(model, longitude_shift_rad=0.0)
    error_h = np.abs(_held_out_t_total_s(unshifted, table, waits, totals) - totals)[feasible]
    print(f"held out, without the longitude shift: worst {error_h.max() / 3600.0:.3f} h")
    # Without the shift all 19 are placed here too (measured worst 0.02 h); it still decides
    # passes at the entry box's edge elsewhere (docs/optimize.md), so fewer are required.
    assert int((error_h / 3600.0 <= 0.1).sum()) >= 14, error_h / 3600.0
    # Every design, the infeasible ones too (none is held out: their T_total is unknown).
    everywhere = model.calibrated(table, waits, totals).t_total_s(table, waits)
    waited = np.isfinite(waits)  # a design infeasible before its wait has none
    assert waited.sum() >= 19
    assert (everywhere[waited] >= 3600.0 * (scenario.mission.stay_h + table[waited, 2])).all()


def _held_out_t_total_s(
    model: PassModel, table: np.ndarray, waits: np.ndarray, totals: np.ndarray
) -> np.ndarray:
    """Each design's T_total [s] by the model calibrated on the other designs' totals
    alone (its own left out: NaN, which calibration skips)."""
    predicted = np.full(len(totals), np.nan)
    for k in range(len(totals)):
        others = totals.copy()
        others[k] = np.nan
        predicted[k] = model.calibrated(table, waits, others).t_total_s(table, waits)[k]
    return predicted


def test_a_design_with_no_pass_in_the_horizon_is_given_the_horizons_end(scenario):
    fit = find_launch_fit(scenario)
    model = PassModel.of(scenario, fit.series["insertion_time_s"], fit.series["flight_time_s"])
    assert PassModel.from_dict(model.to_dict()) == model
    # A one-minute horizon holds no pass: T_total ends with the horizon, so an hour more
    # of t_dsp is exactly an hour more of T_total, and it is before the real first pass.
    blind = PassModel(**{**model.to_dict(), "horizon_s": 60.0})
    designs = np.array([[300.0, 350.0, 5.0], [300.0, 350.0, 6.0]])
    wait = np.full(2, 1.0e5)
    ends = blind.t_total_s(designs, wait)
    assert np.isfinite(ends).all()
    assert ends[1] - ends[0] == pytest.approx(3600.0, abs=1e-6)
    assert (ends < model.t_total_s(designs, wait)).all()


def test_a_longitude_shift_moves_the_entry_box_the_other_way(scenario):
    """Adding s to every crossing's longitude is checking them against the box moved by -s."""
    epoch = Epoch.from_iso(scenario.launch.launch_date_utc)
    inp = deorbit_input(scenario, state0=np.ones(6), epoch=epoch)
    inclination = math.radians(scenario.target.orbit.inclination_deg)
    rng = np.random.default_rng(5)
    u0, raan0 = rng.uniform(0.0, 2 * math.pi, size=(2, 40))
    common = {
        "earth": scenario.earth,
        "earth_angle_at_zero_rad": epoch.gmst_rad(),
        "horizon_s": inp.horizon_s,
        "burn_window_s": inp.solver.burn_window_s,
    }
    radius = scenario.earth.radius + 350e3
    for shift in (math.radians(0.4), math.radians(-2.0)):
        moved = replace(inp.entry, longitude_rad=inp.entry.longitude_rad - shift)
        orbits = (0.0, u0, raan0, inclination, radius)
        shifted = first_pass_s(*orbits, entry=inp.entry, longitude_shift_rad=shift, **common)
        np.testing.assert_allclose(
            shifted,
            first_pass_s(*orbits, entry=moved, **common),
            rtol=0,
            atol=1e-6,
        )
        unshifted = first_pass_s(*orbits, entry=inp.entry, **common)
        assert not np.array_equal(shifted, unshifted, equal_nan=True)
