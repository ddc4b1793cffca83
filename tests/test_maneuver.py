"""Quick orbit manoeuvre of an upper stage (seed 003).

Small DE populations and generation counts come from the config (overridden here);
every reference figure is computed independently in the test (closed forms, a Lambert
arc by shooting with scipy's DOP853, a textbook example) or printed in a publication.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from ovtraj.astro.elements import rv_to_coe
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.config import ConfigError
from ovtraj.studies.maneuver import (
    burn_duration,
    comparison_rows,
    dv_budget_seed,
    load_maneuver,
    maneuver_from_dict,
    rocket_capacity,
    solve_maneuver,
)
from ovtraj.studies.maneuver.de import improved_de
from ovtraj.studies.maneuver.lambert import lambert
from ovtraj.studies.maneuver.thrust import Burn, fly
from tests.conftest import REPO

CASE = REPO / "configs" / "cases" / "upper_stage_rendezvous.yaml"
# Keys `ovtraj maneuver --json` must carry.
MANEUVER_KEYS = {
    "time_of_flight_s",
    "impulse_epochs_s",
    "impulse_dv_mps",
    "total_dv_mps",
    "dv_budget_mps",
    "burns",
    "final_position_error_m",
    "final_velocity_error_mps",
    "converged",
    "reason",
}
BURN_KEYS = {"start_s", "duration_s", "dv_mps", "mass_before_kg", "mass_after_kg"}


def case_data(**overrides: object) -> dict:
    """The published case as a mapping, with ``section__key`` overrides."""
    data = yaml.safe_load(CASE.read_text(encoding="utf-8"))
    data = copy.deepcopy(data)
    for name, value in overrides.items():
        section, key = name.split("__")
        data[section][key] = value
    return data


def small(**overrides: object) -> dict:
    """A quick search: fewer generations than the seed's 2000."""
    return case_data(**{"optimizer__generations": 150, **overrides})


# --------------------------------------------------------------------------- budget
def test_budget_formula_gives_the_published_3613_4_mps():
    """Seed eq. 14 for the published stage: 3613.4 m/s (sec. 3.1)."""
    assert dv_budget_seed(133.4e3, 450.0, 30400.0, 4354.2) == pytest.approx(3613.4, abs=0.1)
    problem = load_maneuver(CASE)
    assert problem.dv_budget_mps == pytest.approx(3613.4, abs=0.1)
    # The rocket equation over the same 450 s: c ln(m0 / (m0 - F t / c)).
    burnt = 133.4e3 * 450.0 / 4354.2
    assert problem.dv_capacity_mps == pytest.approx(4354.2 * math.log(30400.0 / (30400.0 - burnt)))


def test_burn_duration_inverts_the_rocket_equation():
    """Eq. 15: burning dt from m0 gives c ln(m0 / (m0 - F dt / c)) = |dv|."""
    for dv in (1.0, 820.942, 2500.0):
        dt = float(burn_duration(dv, 30400.0, 133.4e3, 4354.2))
        m1 = 30400.0 - 133.4e3 * dt / 4354.2
        assert 4354.2 * math.log(30400.0 / m1) == pytest.approx(dv, rel=1e-12)


# --------------------------------------------------------------------------- Lambert
def test_lambert_reproduces_curtis_example_5_2():
    """Curtis, Orbital Mechanics for Engineering Students, Example 5.2 (printed digits)."""
    r1 = np.array([5000.0, 10000.0, 2100.0]) * 1e3
    r2 = np.array([-14600.0, 2500.0, 7000.0]) * 1e3
    sol = lambert(r1, r2, 3600.0, mu=398600e9, h_ref=np.cross(r1, r2))
    assert sol.ok[0]
    np.testing.assert_allclose(sol.v1[0] / 1e3, [-5.9925, 1.9254, 3.2456], atol=6e-5)
    np.testing.assert_allclose(sol.v2[0] / 1e3, [-3.3125, -4.1966, -0.38529], atol=6e-5)


def _two_body(_t: float, y: np.ndarray, mu: float) -> np.ndarray:
    r = y[:3]
    return np.r_[y[3:], -mu * r / np.linalg.norm(r) ** 3]


def _shoot_lambert(r1, r2, tof, v_guess, mu):
    """Lambert by shooting: v1 such that a DOP853 two-body arc ends at r2 (scipy only)."""

    def miss(v):
        y = solve_ivp(
            _two_body, (0.0, tof), np.r_[r1, v], method="DOP853", rtol=1e-12, atol=1e-6, args=(mu,)
        ).y[:, -1]
        return (y[:3] - r2) / 1e3

    v1 = fsolve(miss, v_guess, xtol=1e-13)
    end = solve_ivp(
        _two_body, (0.0, tof), np.r_[r1, v1], method="DOP853", rtol=1e-12, atol=1e-6, args=(mu,)
    ).y[:, -1]
    assert np.linalg.norm(end[:3] - r2) < 1e-3
    return v1, end[3:]


def test_two_impulse_rendezvous_matches_an_independent_lambert_solution(earth):
    """n = 2, minimum time: both impulses are those of the Lambert arc at the found t_f,
    solved independently by shooting; the budget binds, and 1 % sooner costs more."""
    data = small(maneuver__impulses=2)
    data["maneuver"]["budget"] = {"dv_limit": "rocket_equation", "burn_time_limit": False}
    data["finite_burn"]["enabled"] = False
    problem = maneuver_from_dict(data)
    result = solve_maneuver(problem)
    assert result.converged, result.reason
    tof = result.time_of_flight_s
    mu = earth.mu
    prop = OrbitPropagator(earth, tol=1e-13, j2=False)
    chaser, target = problem.chaser_state, prop.propagate(problem.target_state, 0.0, tof).state

    def lambert_dv(t_f: float) -> tuple[np.ndarray, np.ndarray]:
        goal = prop.propagate(problem.target_state, 0.0, t_f).state
        guess = chaser[3:] + (goal[:3] - chaser[:3]) / t_f
        v1, v2 = _shoot_lambert(chaser[:3], goal[:3], t_f, guess, mu)
        return v1 - chaser[3:], goal[3:] - v2

    dv1, dv2 = lambert_dv(tof)
    np.testing.assert_allclose(result.impulse_vectors_eci_mps[0], dv1, atol=1e-3)
    np.testing.assert_allclose(result.impulse_vectors_eci_mps[1], dv2, atol=1e-3)
    assert np.linalg.norm(target[:3] - chaser[:3]) > 1e6  # a real transfer, not a no-op
    limit = problem.dv_capacity_mps
    assert result.total_dv_mps == pytest.approx(limit, rel=2e-3)
    sooner = lambert_dv(0.99 * tof)
    assert np.linalg.norm(sooner[0]) + np.linalg.norm(sooner[1]) > limit


def test_coplanar_circular_transfer_converges_to_hohmann(earth):
    """Minimum dv, no time limit to speak of: the two-impulse optimum is Hohmann's."""
    r1, r2 = 7000e3, 9000e3
    mu = earth.mu
    t_h = math.pi * math.sqrt((0.5 * (r1 + r2)) ** 3 / mu)
    hohmann = math.sqrt(mu / r1) * (math.sqrt(2 * r2 / (r1 + r2)) - 1) + math.sqrt(mu / r2) * (
        1 - math.sqrt(2 * r1 / (r1 + r2))
    )
    circular = {"eccentricity": 0.0, "inclination_deg": 28.5, "raan_deg": 40.0}
    circular.update(arg_perigee_deg=0.0, mean_anomaly_deg=0.0)
    data = case_data(
        chaser__semi_major_axis_km=r1 / 1e3,
        target__semi_major_axis_km=r2 / 1e3,
        maneuver__impulses=2,
        maneuver__end_condition="transfer",
        maneuver__objective="min_dv",
        maneuver__time_of_flight_bounds_s=[0.2 * t_h, 3.0 * t_h],
        optimizer__population_per_variable=10,
        optimizer__generations=150,
    )
    data["chaser"].update(circular)
    data["target"].update(circular)
    data["finite_burn"]["enabled"] = False
    result = solve_maneuver(maneuver_from_dict(data))
    assert result.converged, result.reason
    assert result.total_dv_mps == pytest.approx(hohmann, rel=1e-5)
    assert result.total_dv_mps >= hohmann * (1 - 1e-9)  # Hohmann is the optimum
    assert result.time_of_flight_s == pytest.approx(t_h, rel=0.02)


# --------------------------------------------------------------------------- finite burns
def test_zero_duration_burn_leaves_the_orbit_unchanged(earth):
    problem = load_maneuver(CASE)
    args = dict(earth=earth, j2=True, thrust_n=133.4e3, isp_n_s_kg=4354.2, tol=1e-13)
    burn = Burn(300.0, 0.0, np.array([0.3, -0.2, 0.9]))
    flight = fly(problem.chaser_state, 30400.0, [burn], 1500.0, **args)
    coast = OrbitPropagator(earth, tol=1e-13, j2=True).propagate(problem.chaser_state, 0.0, 1500.0)
    assert flight.ok
    np.testing.assert_allclose(flight.state[:3], coast.state[:3], atol=1e-6)
    np.testing.assert_allclose(flight.state[3:], coast.state[3:], atol=1e-9)
    assert flight.mass_kg == 30400.0
    assert flight.burns[0].dv_mps == 0.0


def test_finite_burn_dv_matches_the_rocket_equation(earth):
    """The integrated integral of F / m equals c ln(m0 / m1), m1 = m0 - F t / c (1e-6)."""
    problem = load_maneuver(CASE)
    args = dict(earth=earth, j2=True, thrust_n=133.4e3, isp_n_s_kg=4354.2, tol=1e-13)
    burns = [Burn(0.0, 171.0, np.array([1.0, 0.2, 0.1])), Burn(500.0, 186.1, np.array([0, 1, 0]))]
    flight = fly(problem.chaser_state, 30400.0, burns, 1438.0, **args)
    mass = 30400.0
    for burn in flight.burns:
        m1 = mass - 133.4e3 * burn.duration_s / 4354.2
        assert burn.mass_before_kg == pytest.approx(mass, rel=1e-12)
        assert burn.mass_after_kg == pytest.approx(m1, rel=1e-12)
        assert burn.dv_mps == pytest.approx(4354.2 * math.log(mass / m1), rel=1e-6)
        mass = m1
    # The published first burn: 171.0 s from 30 400 kg leaves 25 161.058 kg (Table 1).
    assert flight.burns[0].mass_after_kg == pytest.approx(25161.058, abs=0.01)


# --------------------------------------------------------------------------- published case
@pytest.fixture(scope="module")
def published():
    problem = maneuver_from_dict(case_data(optimizer__generations=300), "test")
    return problem, solve_maneuver(problem)


def test_published_case_beats_the_seed(published):
    """Shorter than the published 1438.0 s within t_e = 450 s of burning (so within the
    3613.4 m/s budget) and a final position error under 10 m after the correction."""
    problem, result = published
    pub = problem.config.published
    assert result.converged, result.reason
    assert result.time_of_flight_s < pub.time_of_flight_s
    assert result.final_position_error_m < 10.0
    assert result.final_velocity_error_mps < 0.01
    assert result.total_burn_time_s <= problem.max_burn_time_s + 1e-6
    assert result.finite_total_dv_mps <= problem.dv_budget_mps
    assert len(result.burns) == 3
    assert result.burns[0].start_s == 0.0
    assert result.burns[-1].end_s == pytest.approx(result.time_of_flight_s, abs=1e-9)
    for before, after in zip(result.burns, result.burns[1:], strict=False):
        assert after.start_s >= before.end_s - 1e-6
        assert after.mass_before_kg == pytest.approx(before.mass_after_kg)
    quantities = [row[0] for row in comparison_rows(problem, result)]
    assert "time of flight [s]" in quantities


def _powered(_t, y, mu, radius, j2, thrust, isp, u):
    """Gravity with J2 (Vallado eq. 8-30), thrust along u, mass flow: written for the test."""
    r = y[:3]
    rn = np.linalg.norm(r)
    k = 1.5 * j2 * mu * radius**2 / rn**5
    z2 = 5.0 * r[2] ** 2 / rn**2
    acc = -mu * r / rn**3 - k * r * np.array([1 - z2, 1 - z2, 3 - z2])
    return np.r_[y[3:6], acc + thrust / y[6] * u, -thrust / isp]


def test_finite_result_flown_again_independently_ends_within_the_reported_error(published, earth):
    problem, result = published
    args = (earth.mu, earth.radius, earth.j2)
    opts = dict(method="DOP853", rtol=1e-12, atol=1e-7)
    y = np.r_[problem.chaser_state, problem.initial_mass_kg]
    t = 0.0
    for burn in result.burns:
        for t_next, thrust in ((burn.start_s, 0.0), (burn.end_s, problem.thrust_n)):
            if t_next > t:
                u = np.array(burn.direction_eci)
                sol = solve_ivp(
                    _powered, (t, t_next), y, args=(*args, thrust, problem.isp_n_s_kg, u), **opts
                )
                y, t = sol.y[:, -1], t_next
    tof = result.time_of_flight_s
    if tof > t:
        y = solve_ivp(_powered, (t, tof), y, args=(*args, 0.0, 1.0, np.zeros(3)), **opts).y[:, -1]
    target = solve_ivp(
        _powered,
        (0.0, tof),
        np.r_[problem.target_state, 1.0],
        args=(*args, 0.0, 1.0, np.zeros(3)),
        **opts,
    ).y[:, -1]
    miss = np.linalg.norm(y[:3] - target[:3])
    assert miss <= result.final_position_error_m + 0.05
    assert miss < 10.0
    assert np.linalg.norm(y[3:6] - target[3:6]) <= result.final_velocity_error_mps + 1e-4
    assert y[6] == pytest.approx(result.final_mass_kg, rel=1e-10)


def test_result_rows_carry_the_cli_fields(published):
    _, result = published
    doc = json.loads(result.json())
    assert MANEUVER_KEYS <= set(doc)
    assert all(BURN_KEYS <= set(burn) for burn in doc["burns"])
    assert len(doc["impulse_epochs_s"]) == 3
    row = result.to_row()
    assert all(not isinstance(v, (list, dict)) for v in row.values())
    assert row["burn1_start_s"] == 0.0


# --------------------------------------------------------------------------- other modes
def test_j2_impulse_plan_meets_the_target_when_flown_again():
    """Under J2 the exact last leg (aim-point iteration) holds to the metre (free
    impulses in local RSW axes this time)."""
    data = small(maneuver__dynamics="j2", maneuver__impulse_frame="rsw", optimizer__generations=60)
    data["finite_burn"]["enabled"] = False
    result = solve_maneuver(maneuver_from_dict(data))
    assert result.converged, result.reason
    assert result.impulsive_position_error_m < 0.01
    assert result.impulsive_velocity_error_mps < 1e-5


def test_interception_and_transfer_end_conditions(earth):
    inter = solve_maneuver(
        maneuver_from_dict(small(maneuver__end_condition="interception", optimizer__generations=60))
    )
    assert inter.converged, inter.reason
    assert inter.final_position_error_m < 1.0
    assert inter.final_velocity_error_mps is None  # velocity is free in an interception
    assert inter.relative_speed_mps > 100.0

    problem = maneuver_from_dict(
        small(maneuver__end_condition="transfer", optimizer__generations=60)
    )
    transfer = solve_maneuver(problem)
    assert transfer.converged, transfer.reason
    # Eq. 7 checked on the classical elements of both final states.
    final = np.array(transfer.final_state_eci)
    target = (
        OrbitPropagator(earth, tol=1e-13, j2=True)
        .propagate(problem.target_state, 0.0, transfer.time_of_flight_s)
        .state
    )
    ours = rv_to_coe(final[:3], final[3:], mu=earth.mu)
    theirs = rv_to_coe(target[:3], target[3:], mu=earth.mu)
    assert ours.a == pytest.approx(theirs.a, abs=1.0)
    assert ours.e == pytest.approx(theirs.e, abs=1e-7)
    for angle in ("i", "raan", "argp"):
        assert getattr(ours, angle) == pytest.approx(getattr(theirs, angle), abs=1e-6)


def test_scipy_de_solves_the_same_problem():
    data = small(optimizer__method="scipy", optimizer__generations=60)
    data["finite_burn"]["enabled"] = False
    result = solve_maneuver(maneuver_from_dict(data))
    assert result.converged, result.reason
    assert result.optimizer == "scipy"
    assert result.time_of_flight_s < 1438.0


# --------------------------------------------------------------------------- IDE
def test_ide_is_reproducible_and_keeps_every_trial_inside_the_bounds():
    lower, upper = np.array([-1.0, 0.0, 2.0]), np.array([1.0, 5.0, 3.0])
    seen = []

    def evaluate(x):
        seen.append(x.copy())
        f = np.sum((x - np.array([0.3, 4.0, 2.5])) ** 2, axis=1)
        return f, (x[:, :1] - 0.5)  # x0 <= 0.5

    # F = 2 throws most mutants out of the box: eq. 10 must draw them back inside.
    kwargs = dict(population=12, scale_factor=2.0, crossover_probability=0.9, generations=40)
    a = improved_de(evaluate, lower, upper, seed=7, **kwargs)
    points = np.vstack(seen)
    assert np.all(points >= lower) and np.all(points <= upper)
    b = improved_de(evaluate, lower, upper, seed=7, **kwargs)
    c = improved_de(evaluate, lower, upper, seed=8, **kwargs)
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    assert a.feasible and a.evaluations == 12 * 41
    best = improved_de(
        evaluate, lower, upper, seed=7, **{**kwargs, "scale_factor": 0.5, "generations": 300}
    )
    np.testing.assert_allclose(best.x, [0.3, 4.0, 2.5], atol=1e-3)


# --------------------------------------------------------------------------- refusals
def test_budget_too_small_comes_back_unconverged_with_the_best_violation():
    data = small(stage__max_burn_time_s=60.0, optimizer__generations=40)
    result = solve_maneuver(maneuver_from_dict(data))
    assert not result.converged
    assert result.constraint_violation > 0.0
    assert "no feasible impulse plan" in result.reason and "best violation" in result.reason
    assert result.burns == []
    json.dumps(result.to_json())  # reportable as is


@pytest.mark.parametrize(
    ("section", "key", "value", "message"),
    [
        (
            "optimizer",
            "crossover_probability",
            1.5,
            "optimizer.crossover_probability = 1.5: out of range, allowed [0, 1]",
        ),
        ("maneuver", "impulses", 7, "maneuver.impulses = 7: out of range, allowed [2, 6]"),
        ("stage", "thrust_n", -1.0, "stage.thrust_n = -1.0: out of range, allowed (0, 1e+08] N"),
        ("target", "eccentricity", 1.2, "target.eccentricity = 1.2: out of range, allowed [0, 1)"),
        ("stage", "max_burn_time_s", 2000.0, "max_burn_time_s = 2000"),
        ("maneuver", "time_of_flight_bounds_s", [500.0, 100.0], "need 0 < lower < upper"),
        ("maneuver", "end_condition", "docking", "maneuver.end_condition = 'docking'"),
        ("chaser", "semi_major_axis_km", 6000.0, "chaser: perigee radius 5994.0 km"),
    ],
)
def test_bad_config_values_are_refused_naming_the_field(section, key, value, message):
    data = case_data(**{f"{section}__{key}": value})
    with pytest.raises(ConfigError) as err:
        maneuver_from_dict(data, "test")
    assert message in str(err.value)


def test_unknown_key_is_refused():
    data = case_data()
    data["optimizer"]["mutation"] = 0.5
    with pytest.raises(ConfigError, match=r"optimizer\.mutation: unknown key"):
        maneuver_from_dict(data)


def test_rocket_capacity_is_what_t_e_of_eq_15_burns_allow():
    """Eq. 13 with eq. 15: impulses summing to the capacity burn exactly t_e."""
    cap = rocket_capacity(133.4e3, 450.0, 30400.0, 4354.2)
    assert float(burn_duration(cap, 30400.0, 133.4e3, 4354.2)) == pytest.approx(450.0)
