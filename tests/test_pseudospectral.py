"""Pseudospectral optimal entry (seed 001) against independent references.

References written here, not taken from the library:

* closed-form integrals and derivatives of monomials (quadrature and differentiation);
* the roots of the Legendre polynomials (numpy's ``Legendre`` class);
* the brachistochrone: minimum-time descent along a cycloid, ``x = a (phi - sin phi)``,
  ``y = a (1 - cos phi)``, time ``phi_f sqrt(a / g)``, path angle ``theta = phi / 2``
  (Bryson & Ho, *Applied Optimal Control*, 1975, sec. 2.7);
* the double integrator's minimum-energy transfer ``x(0) = 0 -> x(1) = 1`` at rest:
  ``u = 6 - 12 t``, ``J = integral u^2 dt = 12`` (Bryson & Ho sec. 5.3);
* the published case of seed 001 (range 844.15 km, terminal 30 km / 860 m/s / -7 deg).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from pathlib import Path

import casadi as ca
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import yaml
from numpy.polynomial import Legendre
from scipy.optimize import brentq

from ovtraj.config import ConfigError
from ovtraj.config.physical import default_atmosphere
from ovtraj.store.files import StoreError
from ovtraj.studies.optimal_entry import (
    load_optimal_entry,
    optimal_entry_from_dict,
    solve_optimal_entry,
    write_histories,
)
from ovtraj.studies.optimal_entry.atmosphere import us76_atmosphere
from ovtraj.studies.optimal_entry.collocation import (
    collocation_scheme,
    legendre_gauss,
    legendre_gauss_radau,
)
from ovtraj.studies.optimal_entry.feasibility import check_feasibility
from ovtraj.studies.optimal_entry.geometry import GreatCircle
from ovtraj.studies.optimal_entry.nlp import IPOPT_SUCCESS, NlpSettings, solve_nlp
from ovtraj.studies.optimal_entry.ocp import Guess, OptimalControlProblem
from ovtraj.studies.optimal_entry.result import CONTROLS_SCHEMA, STATES_SCHEMA
from ovtraj.studies.optimal_entry.transcription import transcribe

REPO = Path(__file__).resolve().parents[1]
CASE = REPO / "configs" / "cases" / "suborbital_return.yaml"
PUBLISHED_RANGE_KM = 844.15  # seed 001, sec. 3.2
# Keys the CLI prints.
RESULT_KEYS = {
    "objective_value",
    "final_time_s",
    "range_km",
    "crossrange_km",
    "final_latitude_deg",
    "max_load_g",
    "max_dynamic_pressure_kpa",
    "max_heat_rate",
    "nlp_iterations",
    "solve_time_s",
    "feasibility_error_km",
    "converged",
    "status",
    "reason",
}
TIGHT = NlpSettings(
    backend="ipopt", tolerance=1e-10, constraint_tolerance=1e-10, max_iterations=500
)


def monomial_integral(p: int) -> float:
    """integral_{-1}^{1} x^p dx."""
    return (1.0 - (-1.0) ** (p + 1)) / (p + 1)


# -- collocation basics --------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3, 5, 10, 30])
def test_lg_nodes_are_legendre_roots_and_weights_exact_to_2n_minus_1(n):
    nodes, weights = legendre_gauss(n)
    assert np.all(np.abs(Legendre.basis(n)(nodes)) < 1e-12)
    for p in range(2 * n):
        assert weights @ nodes**p == pytest.approx(monomial_integral(p), abs=1e-13)
    # Not exact at degree 2n: P_n^2 integrates to 2 / (2n + 1), its quadrature is ~0.
    quadrature = weights @ Legendre.basis(n)(nodes) ** 2
    assert abs(quadrature - 2.0 / (2 * n + 1)) > 0.01


@pytest.mark.parametrize("n", [2, 3, 5, 10, 30])
def test_lgr_nodes_and_weights_exact_to_2n_minus_2(n):
    nodes, weights = legendre_gauss_radau(n)
    assert nodes[0] == -1.0 and np.all(nodes < 1.0) and np.all(np.diff(nodes) > 0)
    radau = Legendre.basis(n - 1) + Legendre.basis(n)
    assert np.all(np.abs(radau(nodes)) < 1e-12)
    for p in range(2 * n - 1):
        assert weights @ nodes**p == pytest.approx(monomial_integral(p), abs=1e-13)
    # Not exact at degree 2n - 1: q = (P_{n-1} + P_n)^2 / (1 + x) is a polynomial of that
    # degree vanishing at every Radau node (at -1 through the factor 1 + x left in q), with
    # a positive integral (computed with an (n + 1)-point Gauss rule, exact for it).
    gauss_x, gauss_w = np.polynomial.legendre.leggauss(n + 1)
    integral = gauss_w @ (radau(gauss_x) ** 2 / (1.0 + gauss_x))
    q_at_nodes = np.concatenate(([0.0], radau(nodes[1:]) ** 2 / (1.0 + nodes[1:])))
    assert abs(weights @ q_at_nodes - integral) > 0.01


@pytest.mark.parametrize("kind", ["lg", "lgr"])
@pytest.mark.parametrize("n", [3, 8, 30])
def test_differentiation_matrix_exact_on_polynomials(kind, n):
    scheme = collocation_scheme(kind, n)
    rng = np.random.default_rng(n)
    coefficients = rng.normal(size=n + 1)  # degree n: the support has n + 1 points
    poly = np.polynomial.Polynomial(coefficients)
    derivative = scheme.d @ poly(scheme.support)
    expected = poly.deriv()(scheme.collocation)
    assert np.max(np.abs(derivative - expected)) < 1e-9 * np.max(np.abs(expected))
    # The integral form recovers the polynomial from its derivative at the nodes.
    values = poly(scheme.support[0]) + scheme.integration_matrix() @ expected
    assert np.max(np.abs(values - poly(scheme.support[1:]))) < 1e-9 * np.max(np.abs(values))


# -- problems with known optima, through the same transcription and solver -----------

G = 9.81
BRACHISTOCHRONE_END = (2.0, 1.0)  # x, y (y downward) [m]


def brachistochrone(x_f: float, y_f: float) -> OptimalControlProblem:
    """Minimum time from rest at the origin to (x_f, y_f); states x, y, v; control theta."""

    def dynamics(x, u, s, p):
        return ca.vertcat(x[2] * ca.sin(u[0]), x[2] * ca.cos(u[0]), G * ca.cos(u[0]))

    return OptimalControlProblem(
        state_names=("x", "y", "v"),
        control_names=("theta",),
        dynamics=dynamics,
        state_lower=np.array([-10.0, -10.0, -50.0]),
        state_upper=np.array([10.0, 10.0, 50.0]),
        control_lower=np.array([-math.pi]),
        control_upper=np.array([math.pi]),
        initial_lower=np.zeros(3),
        initial_upper=np.zeros(3),
        final_lower=np.array([x_f, y_f, -np.inf]),
        final_upper=np.array([x_f, y_f, np.inf]),
        s0=0.0,
        sf_bounds=(0.1, 10.0),
        state_scale=np.ones(3),
        control_scale=np.ones(1),
        mayer=lambda x0, xf, sf, p: sf,
    )


def cycloid(x_f: float, y_f: float) -> tuple[float, float]:
    """(minimum time [s], cycloid radius a [m]) through the origin and (x_f, y_f)."""
    phi = brentq(
        lambda f: (f - math.sin(f)) / (1.0 - math.cos(f)) - x_f / y_f, 1e-6, 2 * math.pi - 1e-6
    )
    a = y_f / (1.0 - math.cos(phi))
    return phi * math.sqrt(a / G), a


@pytest.mark.parametrize(("kind", "nodes", "segments"), [("lg", 16, 1), ("lgr", 10, 3)])
def test_brachistochrone_minimum_time(kind, nodes, segments):
    tr = transcribe(brachistochrone(*BRACHISTOCHRONE_END), kind, nodes, segments)
    guess = Guess(
        s=np.array([0.0, 1.0]),
        x=np.array([[0.0, 0.0, 0.0], [*BRACHISTOCHRONE_END, 4.0]]),
        u=np.array([[1.0], [1.0]]),
        sf=1.0,
    )
    sol = solve_nlp(tr, tr.initial_point(guess), TIGHT)
    assert sol.converged, sol.status
    d = tr.unpack(sol.w)
    t_min, a = cycloid(*BRACHISTOCHRONE_END)
    assert d.sf == pytest.approx(t_min, abs=1e-4)
    theta = d.s_colloc * math.sqrt(G / a) / 2.0
    assert np.max(np.abs(d.u[:, 0] - theta)) < 1e-4
    assert d.x[-1, :2] == pytest.approx(BRACHISTOCHRONE_END, abs=1e-8)


def double_integrator() -> OptimalControlProblem:
    """min integral u^2 dt, x'' = u, from (0, 0) to (1, 0) in 1 s."""
    return OptimalControlProblem(
        state_names=("x", "v"),
        control_names=("u",),
        dynamics=lambda x, u, s, p: ca.vertcat(x[1], u[0]),
        state_lower=np.array([-10.0, -10.0]),
        state_upper=np.array([10.0, 10.0]),
        control_lower=np.array([-100.0]),
        control_upper=np.array([100.0]),
        initial_lower=np.zeros(2),
        initial_upper=np.zeros(2),
        final_lower=np.array([1.0, 0.0]),
        final_upper=np.array([1.0, 0.0]),
        s0=0.0,
        sf_bounds=(1.0, 1.0),
        state_scale=np.ones(2),
        control_scale=np.ones(1),
        lagrange=lambda x, u, s, p: u[0] ** 2,
    )


@pytest.mark.parametrize("backend", ["ipopt", "slsqp", "trust-constr"])
def test_double_integrator_minimum_energy(backend):
    tr = transcribe(double_integrator(), "lg", 6, 1)
    guess = Guess(s=np.array([0.0, 1.0]), x=np.zeros((2, 2)), u=np.zeros((2, 1)), sf=1.0)
    sol = solve_nlp(
        tr,
        tr.initial_point(guess),
        NlpSettings(backend, tolerance=1e-10, constraint_tolerance=1e-8, max_iterations=500),
    )
    assert sol.converged, sol.status
    assert sol.objective == pytest.approx(12.0, abs=1e-4)
    d = tr.unpack(sol.w)
    assert np.max(np.abs(d.u[:, 0] - (6.0 - 12.0 * d.s_colloc))) < 1e-4


# -- the published case ----------------------------------------------------------------


@pytest.fixture(scope="module")
def published():
    return load_optimal_entry(CASE)


@pytest.fixture(scope="module")
def energy_result(published):
    return solve_optimal_entry(published)  # the config's choice: energy, LG, 30 nodes


@pytest.fixture(scope="module")
def time_result(published):
    return solve_optimal_entry(published, independent="time")


@pytest.fixture
def case_data():
    with open(CASE, encoding="utf-8") as fh:
        return copy.deepcopy(yaml.safe_load(fh))


def test_published_case_is_posed_as_printed(published):
    # The figures of seed 001, sec. 3.1, as the solver sees them (SI).
    assert published.initial_state[0] == 70e3 and published.initial_state[3] == 2500.0
    assert math.degrees(published.initial_state[1]) == pytest.approx(100.0)
    assert math.degrees(published.initial_state[2]) == pytest.approx(30.0)
    assert published.mass == 6853.0 and published.nodes_per_segment == 30
    assert published.omega == 0.0 and published.independent == "energy"
    assert published.final_lower[[0, 3]] == pytest.approx([30e3, 860.0])
    assert published.final_upper[[0, 3]] == pytest.approx([30e3, 860.0])
    assert math.degrees(published.final_lower[4]) == pytest.approx(-7.0)


def test_published_case_optimum(energy_result, published):
    r = energy_result
    assert r.converged, r.reason
    assert r.final_altitude_km == pytest.approx(30.0, abs=1e-6)
    assert r.final_speed_mps == pytest.approx(860.0, abs=1e-5)
    assert r.final_fpa_deg == pytest.approx(-7.0, abs=1e-6)
    assert r.max_load_g <= published.max_load_g * (1 + 1e-6)
    assert r.max_dynamic_pressure_kpa <= published.max_dynamic_pressure / 1e3 * (1 + 1e-6)
    assert r.max_heat_rate <= published.max_heat_rate / 1e3 * (1 + 1e-6)
    # Lost constants (reference area, heat-rate law; docs/optimal_entry.md) limit the
    # comparison with the published range to a few percent.
    assert abs(r.range_km / PUBLISHED_RANGE_KM - 1.0) < 0.03
    # The seed's optimum flies with zero bank (sec. 3.2): so does ours.
    assert np.max(np.abs(r.controls["bank_deg"])) < 1e-3
    assert abs(r.crossrange_km) < 1e-3


def test_energy_and_time_formulations_agree(energy_result, time_result):
    assert energy_result.converged and time_result.converged
    assert energy_result.independent == "energy" and time_result.independent == "time"
    relative = abs(time_result.objective_value / energy_result.objective_value - 1.0)
    assert relative < 0.005
    assert time_result.final_time_s == pytest.approx(energy_result.final_time_s, rel=0.005)


def test_feasibility_check_on_published_case(energy_result, published):
    assert {r.interpolation for r in energy_result.feasibility} == {"linear", "cubic"}
    for report in energy_result.feasibility:
        assert report.status == "completed"
        assert report.position_error_km < 1.0, report
        assert report.angle_error_deg < 0.1, report
    assert energy_result.feasibility_error_km < 1.0
    assert energy_result.feasibility_error_deg < 0.1
    # The check is sensitive: one degree more angle of attack misses by far more.
    c, s = energy_result.controls, energy_result.states
    final = s.iloc[-1]
    final_state = np.array(
        [
            final["altitude_km"] * 1e3,
            math.radians(final["longitude_deg"]),
            math.radians(final["latitude_deg"]),
            final["speed_mps"],
            math.radians(final["fpa_deg"]),
            math.radians(final["heading_deg"]),
        ]
    )
    wrong = check_feasibility(
        published,
        c["time_s"].to_numpy(),
        np.radians(c["alpha_deg"].to_numpy() + 1.0),
        np.radians(c["bank_deg"].to_numpy()),
        float(final["time_s"]),
        final_state,
        "cubic",
    )
    assert wrong.position_error_km > 5.0


def test_result_row_and_histories(energy_result, tmp_path):
    row = energy_result.to_row()
    assert RESULT_KEYS <= set(row)
    json.dumps(row)  # plain types only
    assert row["converged"] is True and row["reason"] is None
    assert row["objective_value"] == pytest.approx(row["range_km"])
    paths = write_histories(energy_result, tmp_path)
    states = pd.read_parquet(paths["states"])
    controls = pd.read_parquet(paths["controls"])
    assert len(states) == 32 and len(controls) == 30  # LG: 30 nodes plus both ends
    assert np.all(np.diff(states["time_s"]) > 0)
    assert states["time_s"].iloc[-1] == pytest.approx(energy_result.final_time_s)
    assert paths["plot"].stat().st_size > 10_000
    # The declared schemas, whatever the problem: columns it lacks are null.
    assert pq.read_schema(paths["states"]).equals(STATES_SCHEMA)
    assert pq.read_schema(paths["controls"]).equals(CONTROLS_SCHEMA)
    for name, schema in (("states", STATES_SCHEMA), ("controls", CONTROLS_SCHEMA)):
        table = pq.read_table(paths[name])
        absent = [c for c in schema.names if c not in getattr(energy_result, name)]
        assert all(table.column(c).null_count == table.num_rows for c in absent)
        assert table.column("time_s").null_count == 0
    # The same histories again: nothing changes; others under the same names: refused,
    # or, content-named, stored beside them.
    stored = paths["states"].read_bytes()
    assert write_histories(energy_result, tmp_path) == paths
    shifted = energy_result.states.assign(altitude_km=energy_result.states["altitude_km"] + 1e-3)
    other = dataclasses.replace(energy_result, states=shifted)
    with pytest.raises(StoreError, match=r"_states\.parquet: already stored with other content"):
        write_histories(other, tmp_path)
    assert paths["states"].read_bytes() == stored
    named = write_histories(other, tmp_path, content_named=True)
    assert named["states"].parent.parent == tmp_path
    assert named["states"].parent.name.startswith(
        paths["states"].name.removesuffix("_states.parquet")
    )
    assert write_histories(other, tmp_path, content_named=True) == named
    assert write_histories(energy_result, tmp_path, content_named=True) != named


def test_rate_limit_is_respected(case_data, energy_result):
    case_data["controls"]["alpha"]["max_rate_deg_s"] = 0.4
    result = solve_optimal_entry(optimal_entry_from_dict(case_data))
    assert result.converged, result.reason
    rate = result.controls["alpha_rate_deg_s"].abs().max()
    assert rate <= 0.4 + 1e-5  # IPOPT relaxes bounds by ~1e-8 (bound_relax_factor)
    # The free optimum swings alpha faster than that, so the limit costs range.
    free_rate = np.max(
        np.abs(np.diff(energy_result.controls["alpha_deg"]))
        / np.diff(energy_result.controls["time_s"])
    )
    assert free_rate > 0.4
    assert result.range_km < energy_result.range_km


def test_crossrange_and_heat_load_objectives(case_data, energy_result):
    case_data["transcription"]["nodes_per_segment"] = 20
    case_data["objective"] = "max_crossrange"
    cross = solve_optimal_entry(optimal_entry_from_dict(case_data))
    case_data["objective"] = "min_heat_load"
    heat = solve_optimal_entry(optimal_entry_from_dict(case_data))
    assert cross.converged and heat.converged
    assert cross.objective_value == pytest.approx(cross.final_latitude_deg)
    # Heading east from 30 N, the left (north) turn raises the final latitude.
    assert cross.final_latitude_deg > energy_result.final_latitude_deg + 1.0
    assert cross.crossrange_km > 100.0
    assert heat.heat_load_mj_m2 < energy_result.heat_load_mj_m2
    assert heat.final_time_s < energy_result.final_time_s


# -- refusals and failures -------------------------------------------------------------


def _set(data, path, value):
    keys = path.split(".")
    for key in keys[:-1]:
        data = data[key]
    data[keys[-1]] = value


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        (
            {"terminal.speed_mps": {"value": 3000.0}, "state_bounds.speed_mps": [100.0, 4000.0]},
            "terminal.altitude_km, terminal.speed_mps: the lowest terminal energy",
        ),
        ({"controls.alpha": {"lower_deg": 35.0, "upper_deg": 8.0}}, "controls.alpha: empty"),
        ({"controls.bank": {"lower_deg": 10.0, "upper_deg": -10.0}}, "controls.bank: empty"),
        ({"initial.altitude_km": 80.0}, "initial.altitude_km = 80: outside state_bounds"),
        ({"terminal.fpa_deg": {"value": -30.0}}, "terminal.fpa_deg: [-30, -30] does not meet"),
        ({"vehicle.mass_kg": -1.0}, "vehicle.mass_kg = -1.0: out of range"),
        ({"state_bounds.speed_mps": [0.0, 3000.0]}, "state_bounds.speed_mps: the energy"),
        ({"guess.alpha_deg": 40.0}, "guess.alpha_deg = 40: outside controls.alpha"),
        ({"terminal.speed_mps": {"lower": 900.0, "upper": 800.0}}, "terminal.speed_mps: empty"),
        ({"objective": "max_range"}, "objective = 'max_range'"),
        ({"vehicle.wingspan_m": 5.0}, "vehicle.wingspan_m: unknown key"),
        ({"solver.barrier_strategy": "fast"}, "solver.barrier_strategy = 'fast'"),
    ],
)
def test_bad_configs_are_refused_naming_the_field(case_data, changes, fragment):
    for path, value in changes.items():
        _set(case_data, path, value)
    with pytest.raises(ConfigError) as err:
        optimal_entry_from_dict(case_data, "case.yaml")
    assert fragment in str(err.value)
    assert "case.yaml" in str(err.value)


def test_infeasible_nlp_returns_ipopt_status(case_data):
    # The heat rate at the initial state (~80 kW/m^2) already exceeds this limit.
    case_data["path"]["heat_rate"]["max_kw_m2"] = 50.0
    case_data["solver"]["max_iterations"] = 300
    result = solve_optimal_entry(optimal_entry_from_dict(case_data))
    assert result.converged is False
    assert result.status not in IPOPT_SUCCESS
    assert result.status in {
        "Infeasible_Problem_Detected",
        "Restoration_Failed",
        "Maximum_Iterations_Exceeded",
        "Search_Direction_Becomes_Too_Small",
    }
    assert result.status in result.reason
    assert result.to_row()["converged"] is False


# -- pieces ----------------------------------------------------------------------------


def test_nlp_us76_equals_library():
    library = default_atmosphere()
    nlp = us76_atmosphere(library, 150e3, 1000.0)
    h = ca.SX.sym("h")
    f = ca.Function("atm", [h], list(nlp.evaluate(h)))
    z = np.concatenate((np.linspace(0.0, 86e3, 347)[:-1], np.linspace(86e3, 150e3, 65)))
    rho, sound = (np.asarray(v, dtype=float).ravel() for v in f(z.reshape(1, -1)))
    assert np.max(np.abs(rho / library.density(z) - 1.0)) < 1e-12
    below = z < 86e3
    assert np.max(np.abs(sound[below] / library.speed_of_sound(z[below]) - 1.0)) < 1e-12
    assert np.max(np.abs(sound / library.speed_of_sound(z) - 1.0)) < 2e-3


def test_downrange_and_crossrange_angles():
    east_on_equator = GreatCircle(0.0, 0.0, math.pi / 2)
    downrange, crossrange = east_on_equator.angles(np.radians(10.0), np.radians(3.0))
    # On a meridian-free geometry: the foot of the point is at 10 deg of longitude.
    assert downrange == pytest.approx(np.radians(10.0), abs=1e-12)
    assert crossrange == pytest.approx(np.radians(3.0), abs=1e-12)  # left of east is north
    north = GreatCircle(np.radians(100.0), np.radians(30.0), 0.0)
    d, c = north.angles(np.radians(100.0), np.radians(35.0))
    assert d == pytest.approx(np.radians(5.0), abs=1e-12) and c == pytest.approx(0.0, abs=1e-12)
