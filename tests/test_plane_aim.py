"""Plane management: the launch aimed at the target's plane at the rendezvous.

References: the closed-form J2 nodal regression (Vallado, 4th ed., eq. 9-41) for the
planes' drift apart; the rendezvous stage's own propagated states (heyoka Taylor, not the
aim's secular model) for the residual at the burn; the two-body Hohmann cost for the
price of the plane; the chain's stored values with the target's plane at insertion for the
patent's choice; osculating elements (two-body, ``rv_to_coe``) for the launch target's orbit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ovtraj.astro.elements import rv_to_coe
from ovtraj.astro.j2_elements import secular_rates, state_to_mean
from ovtraj.launch.insertion import circular_insertion_state
from ovtraj.mission import MissionContext, MissionDesign, evaluate, reference
from ovtraj.mission.chain import launch_leg
from ovtraj.mission.plane import aim_insertion

SETTINGS = reference.load_settings()


def _with_insertion(context: MissionContext, **update) -> MissionContext:
    scenario = context.scenario
    insertion = None if update.get("none") else scenario.mission.insertion.model_copy(update=update)
    mission = scenario.mission.model_copy(update={"insertion": insertion})
    return MissionContext(scenario.model_copy(update={"mission": mission}), context.fit)


@pytest.fixture(scope="module")
def aimed():
    return reference.context(SETTINGS)


@pytest.fixture(scope="module")
def designs(aimed):
    return reference.designs(aimed.scenario, SETTINGS)


@pytest.fixture(scope="module")
def aimed_records(aimed, designs):
    return [evaluate(aimed, design) for design in designs]


def _nodal_rate(state, earth) -> float:
    """dOmega/dt [rad/s] of a state's Brouwer mean elements, closed form (Vallado eq. 9-41)."""
    mean = state_to_mean(state[:3], state[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
    e = math.hypot(float(mean.ex), float(mean.ey))
    return secular_rates(
        float(mean.a), e, float(mean.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )[0]


def _rendezvous(records):
    return [
        r.results.rendezvous
        for r in records
        if r.results.rendezvous is not None and r.results.rendezvous.feasible
    ]


def test_the_shipped_scenario_aims_at_the_rendezvous(aimed):
    insertion = aimed.scenario.mission.insertion
    assert insertion.plane == "rendezvous" and insertion.orbit == "launch_target"


def test_an_aimed_rendezvous_costs_its_coplanar_hohmann_within_the_bound(aimed_records):
    bounds = SETTINGS.plane_aim
    rendezvous = _rendezvous(aimed_records)
    assert len(rendezvous) >= 15
    for rdv in rendezvous:
        hohmann = rdv.dv1_two_body_mps + rdv.dv2_two_body_mps
        assert rdv.dv_total_mps / hohmann <= bounds.hohmann_ratio_max
        # J2 costs something over the two-body figure, never less than ~it.
        assert rdv.dv_total_mps / hohmann >= 0.99
        # The residual, measured on the stage's propagated states at its phased burn.
        assert math.degrees(rdv.plane_difference_rad) <= bounds.plane_difference_max_deg


def test_the_aimed_node_is_the_differential_regression_over_the_wait(aimed, aimed_records):
    """Offset = (dOmega_T/dt - dOmega_P/dt) (wait + T_H / 2): the rates in closed form from
    each state's mean elements, the wait the stage's own (refined on the propagated phase,
    minutes from the aim's secular estimate: ~1e-3 deg of node)."""
    earth = aimed.scenario.earth
    checked = 0
    for record in aimed_records:
        rdv, leg = record.results.rendezvous, record.results.launch
        if rdv is None or not rdv.feasible:
            continue
        drift = _nodal_rate(aimed.target_at(leg.insertion_time_s), earth) - _nodal_rate(
            leg.insertion_state, earth
        )
        expected = drift * (rdv.wait_time_s + 0.5 * rdv.transfer_time_two_body_s)
        assert math.radians(leg.raan_offset_deg) == pytest.approx(expected, abs=math.radians(3e-3))
        assert 0.4 < leg.raan_offset_deg < 0.8
        assert leg.aim is not None and leg.aim.converged and leg.aim.iterations <= 8
        checked += 1
    assert checked >= 15


def test_the_patent_plane_drifts_apart_by_the_differential_regression(aimed, designs):
    """The target's plane at insertion (``plane: launch``): by the first burn the planes are
    apart by the difference of the J2 nodal rates over the wait, and the rendezvous pays for
    it well above its Hohmann cost."""
    patent = _with_insertion(aimed, plane="launch")
    earth, i = aimed.scenario.earth, aimed.plane.inclination_rad
    ratios = []
    for design in designs[:8]:
        record = evaluate(patent, design)
        rdv = record.results.rendezvous
        if rdv is None or not rdv.feasible:
            continue
        leg = record.results.launch
        assert leg.raan_offset_deg == 0.0
        drift = abs(
            _nodal_rate(leg.insertion_state, earth)
            - _nodal_rate(patent.target_at(leg.insertion_time_s), earth)
        )
        # Planes of equal inclination whose nodes differ by drift * wait.
        expected = math.degrees(math.asin(math.sin(i) * math.sin(drift * rdv.wait_time_s)))
        assert math.degrees(rdv.plane_difference_rad) == pytest.approx(expected, abs=0.005)
        ratios.append(rdv.dv_total_mps / (rdv.dv1_two_body_mps + rdv.dv2_two_body_mps))
    assert len(ratios) >= 5 and min(ratios) > 1.1


def test_without_an_insertion_section_the_chain_is_the_one_before_issue_43(aimed, designs):
    """``mission.insertion: null`` (a config stored before it, which had no deorbit pass
    cost margin either): the mean circular orbit in the target's plane at insertion, giving
    the chain's values stored before the change."""
    before = _with_insertion(aimed, none=True)
    solver = before.scenario.deorbit.solver.model_copy(update={"pass_cost_margin_mps": None})
    deorbit = before.scenario.deorbit.model_copy(update={"solver": solver})
    before = MissionContext(before.scenario.model_copy(update={"deorbit": deorbit}), before.fit)
    stored, _ = reference.load(
        reference.reference_directory().with_name("mission_chain_plane_at_launch")
    )
    now = reference.values(before, designs[: len(stored)])
    assert reference.differences(stored, now, SETTINGS.tolerances) == []


def test_the_launch_target_is_circular_at_the_altitude_in_the_mean_plane(aimed):
    earth = aimed.scenario.earth
    altitude, u, i, raan = 287.3e3, 0.83, math.radians(51.64), 2.61
    state = circular_insertion_state("launch_target", altitude, u, i, raan, earth)
    r, v = state[:3], state[3:]
    assert np.linalg.norm(r) == pytest.approx(earth.radius + altitude, abs=1e-6)
    assert np.linalg.norm(v) == pytest.approx(math.sqrt(earth.mu / np.linalg.norm(r)), rel=1e-13)
    assert abs(np.dot(r, v)) / (np.linalg.norm(r) * np.linalg.norm(v)) < 1e-13  # horizontal
    osculating = rv_to_coe(r, v, mu=earth.mu)
    assert osculating.e < 1e-12
    mean = state_to_mean(r, v, mu=earth.mu, radius=earth.radius, j2=earth.j2)
    assert float(mean.i) == pytest.approx(i, abs=1e-12)
    assert math.remainder(float(mean.raan) - raan, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    # The J2 short-period terms: the osculating plane is not the mean one.
    assert abs(osculating.i - i) > 1e-5
    # The mean circular orbit's osculating radius there is not R_E + H.
    mean_state = circular_insertion_state("mean_circular", altitude, u, i, raan, earth)
    assert abs(np.linalg.norm(mean_state[:3]) - earth.radius - altitude) > 100.0


def test_the_aim_stops_at_its_iteration_limit_with_the_best_iterate(aimed):
    leg = launch_leg(aimed, MissionDesign(300.0, 350.0, 0.0))
    settings = aimed.scenario.mission.insertion.aim.model_copy(update={"max_iterations": 1})
    t_fit = leg.insertion_time_s - math.radians(leg.raan_offset_deg) / (
        aimed.scenario.earth.omega - aimed.plane.raan_rate_rad_s
    )

    earth = aimed.scenario.earth
    mean = state_to_mean(
        leg.insertion_state[:3],
        leg.insertion_state[3:],
        mu=earth.mu,
        radius=earth.radius,
        j2=earth.j2,
    )

    def insertion_at(offset):
        return t_fit, leg.insertion_state, mean

    once = aim_insertion(insertion_at, aimed.target_at, earth, settings)
    assert not once.converged and once.iterations == 1 and once.raan_offset_rad == 0.0
    # Its residual is the whole offset the planes need: ~0.45 deg of plane at this altitude.
    assert 0.3 < math.degrees(once.plane_difference_rad) < 0.6


def test_the_aim_converges_to_the_node_a_plain_iteration_reaches(aimed):
    """The secant steps reach the plain fixed-point iteration's node, in fewer iterations."""
    design = MissionDesign(287.0, 350.0, 0.0)
    leg = launch_leg(aimed, design)
    assert leg.aim.converged and leg.aim.iterations <= 4
    plain = _with_insertion(aimed)
    earth = aimed.scenario.earth
    offsets, offset = [], 0.0
    t_fit = leg.insertion_time_s - math.radians(leg.raan_offset_deg) / (
        earth.omega - aimed.plane.raan_rate_rad_s
    )
    from ovtraj.launch.insertion import turned_east
    from ovtraj.rendezvous.phasing import secular_phasing

    base = leg.insertion_state
    base_raan = aimed.plane.raan_at(leg.insertion_time_s) + math.radians(leg.raan_offset_deg)
    for _ in range(12):  # x <- aimed(x), by hand
        t = t_fit + offset / (earth.omega - aimed.plane.raan_rate_rad_s)
        state = turned_east(base, aimed.plane.raan_at(t) + offset - base_raan)
        phasing = secular_phasing(state, plain.target_at(t), earth)
        drift = _nodal_rate(plain.target_at(t), earth) - _nodal_rate(state, earth)
        offset = drift * (phasing.wait_s + 0.5 * phasing.transfer.transfer_time_s)
        offsets.append(offset)
    assert abs(offsets[-1] - offsets[-2]) < 1e-12
    assert math.radians(leg.raan_offset_deg) == pytest.approx(offsets[-1], abs=math.radians(2e-7))
