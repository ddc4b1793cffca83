"""A long lifting entry from near-orbital speed, posed by YAML alone.

Betts' Space Shuttle maximum cross-range problem (*Practical Methods for Optimal
Control*, 2nd ed., SIAM 2010, sec. 6.1), with and without its heating limit: the
published optima (final latitude 34.1412 deg at 2008.59 s; 30.6255 deg at 2198.67 s
with q <= 70 BTU/ft^2/s) against both of our formulations, which must also agree with
each other within 0.1 % of the objective. Then honest convergence (a coarse mesh whose
re-flight misses is not ``converged``), the mesh refinement's pieces, and the energy
formulation's refusal.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from ovtraj.paths import config_path
from ovtraj.studies.optimal_entry import load_optimal_entry, solve_optimal_entry
from ovtraj.studies.optimal_entry.flight import fly
from ovtraj.studies.optimal_entry.mesh import refined_edges
from ovtraj.studies.optimal_entry.solve import _energy_refusal
from ovtraj.studies.optimal_entry.transcription import transcribe

# Betts (2010), sec. 6.1: (final latitude [deg], final time [s]).
PUBLISHED = {
    "shuttle_crossrange.yaml": (34.1412, 2008.59),
    "shuttle_crossrange_heating.yaml": (30.6255, 2198.67),
}


@pytest.fixture(scope="module", params=sorted(PUBLISHED))
def solved(request):
    problem = load_optimal_entry(config_path(f"cases/{request.param}"))
    return (
        request.param,
        problem,
        {form: solve_optimal_entry(problem, independent=form) for form in ("energy", "time")},
    )


def test_both_formulations_reach_the_published_optimum(solved):
    case, problem, results = solved
    latitude, final_time = PUBLISHED[case]
    for form, result in results.items():
        assert result.converged, f"{form}: {result.reason}"
        assert result.final_latitude_deg == pytest.approx(latitude, abs=0.005), form
        assert result.final_time_s == pytest.approx(final_time, abs=2.0), form
        assert result.final_altitude_km == pytest.approx(24.384, abs=1e-6)
        assert result.final_speed_mps == pytest.approx(762.0, abs=1e-3)
        assert result.final_fpa_deg == pytest.approx(-5.0, abs=1e-6)
        # Converged means flown: one reconstruction of the controls lands within tolerance.
        tolerance = problem.config.feasibility.tolerance_km
        assert min(r.position_error_km for r in result.feasibility) <= tolerance
    energy, time = results["energy"], results["time"]
    assert abs(energy.objective_value / time.objective_value - 1.0) < 1e-3


def test_the_heating_limit_binds_and_is_kept(solved):
    _, problem, results = solved
    if problem.max_heat_rate is None:  # the variant without a heat-rate law computes none
        assert all(result.max_heat_rate == 0.0 for result in results.values())
        return
    for result in results.values():
        # 70 BTU/ft^2/s on the nodes, and within 1 % on the independent re-flight.
        assert result.max_heat_rate == pytest.approx(problem.max_heat_rate / 1e3, rel=1e-6)
        flown = min(result.feasibility, key=lambda r: r.position_error_km)
        assert flown.max_heat_rate_kw_m2 <= 1.01 * problem.max_heat_rate / 1e3


def test_energy_time_is_a_state_that_runs_forwards(solved):
    _, _, results = solved
    states = results["energy"].states
    assert np.all(np.diff(states["time_s"].to_numpy()) >= 0.0)
    assert states["time_s"].iloc[0] == 0.0


def test_a_coarse_mesh_that_does_not_fly_is_not_converged():
    """The issue's false convergence: 10 x 5 nodes from a -45 deg bank, no refinement."""
    problem = load_optimal_entry(config_path("cases/shuttle_crossrange_heating.yaml"))
    mesh = problem.config.transcription.model_copy(update={"max_refinements": 0})
    coarse = dataclasses.replace(
        problem, config=problem.config.model_copy(update={"transcription": mesh})
    )
    result = solve_optimal_entry(coarse, independent="time")
    assert result.status == "Solve_Succeeded"  # IPOPT is satisfied ...
    assert not result.converged  # ... but its controls do not fly to its end point
    assert "re-flight" in result.reason and "tolerance_km" in result.reason
    assert min(r.position_error_km for r in result.feasibility) > 1.0
    assert result.refinements == 0 and result.segments == 10


def test_refinement_splits_the_segments_over_their_share():
    edges = np.linspace(0.0, 1.0, 5)
    errors = np.array([0.01, 0.6, 0.02, np.inf])
    new = refined_edges(edges, errors, tolerance_km=1.0, max_segments=10)
    np.testing.assert_allclose(new, [0.0, 0.25, 0.375, 0.5, 0.75, 0.875, 1.0])
    # All under their share: the worst quarter is split all the same.
    new = refined_edges(edges, np.array([0.1, 0.2, 0.05, 0.01]), 1.0, 10)
    np.testing.assert_allclose(new, [0.0, 0.25, 0.375, 0.5, 0.75, 1.0])
    # A terminal miss 10x the segments' summed errors: each share is 10x smaller.
    small = np.array([0.01, 0.03, 0.02, 0.04])
    np.testing.assert_allclose(
        refined_edges(edges, small, 1.0, 10, terminal_error_km=1.0),
        [0.0, 0.25, 0.375, 0.5, 0.75, 0.875, 1.0],  # 0.03 and 0.04 exceed 1 / 4 / 10
    )
    np.testing.assert_allclose(  # without it: none over 0.25, the worst quarter only
        refined_edges(edges, small, 1.0, 10), [0.0, 0.25, 0.5, 0.75, 0.875, 1.0]
    )
    # No room left.
    assert refined_edges(edges, errors, 1.0, 4) is None
    # Room for one: the worst goes first.
    np.testing.assert_allclose(
        refined_edges(edges, errors, 1.0, 5), [0.0, 0.25, 0.5, 0.75, 0.875, 1.0]
    )


def test_unequal_segments_place_the_points_inside_their_edges():
    problem = load_optimal_entry(config_path("cases/shuttle_crossrange.yaml"))
    from ovtraj.studies.optimal_entry.formulation import formulate
    from ovtraj.studies.optimal_entry.guess import guess_trajectory

    form = formulate(problem, "time", guess_trajectory(problem))
    edges = np.array([0.0, 0.1, 0.15, 0.6, 1.0])
    tr = transcribe(form.ocp, "lgr", 4, edges=edges)
    assert tr.segments == 4
    np.testing.assert_allclose(tr.segment_edges, edges)
    for k, points in enumerate(tr.segment_points):
        inside = tr.point_fraction[points]
        assert inside[0] == pytest.approx(edges[k]) and inside[-1] == pytest.approx(edges[k + 1])
    with pytest.raises(ValueError, match="increase from 0 to 1"):
        transcribe(form.ocp, "lgr", 4, edges=np.array([0.0, 0.5, 0.4, 1.0]))


def test_meshes_of_one_problem_share_its_node_functions_and_they_equal_its_rates():
    import casadi as ca

    from ovtraj.studies.optimal_entry.formulation import formulate
    from ovtraj.studies.optimal_entry.guess import guess_trajectory

    problem = load_optimal_entry(config_path("cases/shuttle_crossrange_heating.yaml"))
    ocp = formulate(problem, "time", guess_trajectory(problem)).ocp
    coarse = transcribe(ocp, "lgr", 4, 3)
    fine = transcribe(ocp, "lgr", 4, edges=np.array([0.0, 0.2, 0.5, 0.7, 1.0]))
    assert coarse.ocp.node_functions is fine.ocp.node_functions
    x = np.array([60e3, 0.2, 0.1, 6000.0, -0.01, 1.2])
    u = np.array([math.radians(30.0), math.radians(-50.0)])
    node = ocp.node_functions
    xs, us, ss, ps = ca.SX.sym("x", 6), ca.SX.sym("u", 2), ca.SX.sym("s"), ca.SX.sym("p", 0)
    direct = ca.Function("direct", [xs, us, ss, ps], [ocp.dynamics(xs, us, ss, ps)])
    args = (x, u, 100.0, np.zeros(0))
    np.testing.assert_array_equal(np.asarray(node.dynamics(*args)), np.asarray(direct(*args)))
    path = ca.Function("path", [xs, us, ss, ps], [ocp.path(xs, us, ss, ps)])
    np.testing.assert_array_equal(np.asarray(node.path(*args)), np.asarray(path(*args)))
    assert np.asarray(node.path(*args)).size >= 1  # the heat rate row is there


def test_a_segment_flown_from_its_start_continues_the_whole_flight():
    problem = load_optimal_entry(config_path("cases/shuttle_crossrange.yaml"))
    controls = lambda t: (math.radians(20.0), math.radians(-30.0))  # noqa: E731
    settings = problem.config.feasibility
    tol = {"rtol": settings.relative_tolerance, "atol": settings.absolute_tolerance}
    whole = fly(problem, controls, 600.0, **tol)
    half = fly(problem, controls, 300.0, **tol)
    rest = fly(problem, controls, 600.0, start=(300.0, half.y[-1]), **tol)
    assert rest.t[0] == 300.0 and rest.t[-1] == pytest.approx(600.0)
    np.testing.assert_allclose(rest.y[-1], whole.y[-1], rtol=1e-7, atol=1e-6)


def test_the_energy_formulation_refuses_what_it_cannot_pose():
    forwards = pd.DataFrame({"time_s": [0.0, 10.0, 30.0]})
    assert _energy_refusal(np.array([5.0, 8.0]), forwards) is None
    reason = _energy_refusal(np.array([5.0, -1.0]), forwards)
    assert "energy to decrease" in reason and "independent: time" in reason
    backwards = pd.DataFrame({"time_s": [0.0, 10.0, 7.0]})
    assert "decreases between state points" in _energy_refusal(np.array([1.0, 1.0]), backwards)


@pytest.mark.parametrize(
    "case", ["shuttle_crossrange_heating.yaml", "suborbital_return.yaml"]
)  # exponential and US76 atmospheres, with and without a heat-rate law
def test_compiled_flight_equals_the_numpy_model_under_scipy(case):
    """The numba re-flight against flight.py's numpy model integrated by scipy's DOP853:
    the same points and states, for splined and piecewise-linear controls and a terminal
    energy."""
    from ovtraj.studies.optimal_entry import flight
    from ovtraj.studies.optimal_entry.feasibility import control_table
    from ovtraj.studies.optimal_entry.flight_kernel import ControlTable, fly_compiled
    from ovtraj.studies.optimal_entry.guess import target_energy

    problem = load_optimal_entry(config_path(f"cases/{case}"))
    t = np.linspace(0.0, 400.0, 30)
    alpha = np.radians(20.0 + 5.0 * np.sin(t / 100.0))
    bank = np.radians(-30.0 + 10.0 * np.cos(t / 50.0))
    for kind in ("cubic", "linear"):
        table = control_table(t, alpha, bank, kind, problem.control_lower, problem.control_upper)
        options = {"rtol": 1e-10, "atol": 1e-10, "breaks": t if kind == "linear" else None}
        compiled = fly_compiled(problem, table, 400.0, **options)
        reference = flight.fly(problem, lambda x, table=table: table(x), 400.0, **options)
        assert compiled.status == reference.status == "completed"
        assert compiled.t[-1] == reference.t[-1] == 400.0
        # Same method and step control; step sequences may part on rounding, ends agree.
        assert abs(len(compiled.t) - len(reference.t)) <= 0.1 * len(reference.t)
        np.testing.assert_allclose(compiled.y[-1], reference.y[-1], rtol=1e-9, atol=1e-4)
        model = flight.PointMass(problem)
        heat = [
            model.path_values(y[0], y[3], table(s)[0]).heat_rate
            for s, y in zip(compiled.t, compiled.y, strict=True)
        ]
        np.testing.assert_allclose(compiled.path[:, 0], heat, rtol=1e-12, atol=1e-9)
    stop = target_energy(problem)
    constant = ControlTable.constant(math.radians(15.0), 0.0)
    compiled = fly_compiled(problem, constant, 5000.0, rtol=1e-8, atol=1e-8, stop_energy=stop)
    reference = flight.fly(
        problem, lambda x: constant(x), 5000.0, rtol=1e-8, atol=1e-8, stop_energy=stop
    )
    assert compiled.status == reference.status == "terminal energy"
    assert compiled.t[-1] == pytest.approx(reference.t[-1], abs=1e-2)  # integration error
    assert problem.energy(compiled.y[-1, 0], compiled.y[-1, 3]) == pytest.approx(stop, rel=1e-9)


def test_a_compiled_flight_with_nan_controls_fails_instead_of_hanging():
    from ovtraj.studies.optimal_entry.flight_kernel import ControlTable, fly_compiled

    problem = load_optimal_entry(config_path("cases/shuttle_crossrange.yaml"))
    nan = ControlTable.constant(math.nan, 0.0)
    flown = fly_compiled(problem, nan, 100.0, rtol=1e-8, atol=1e-8)
    assert flown.status.startswith("integration failed")
    assert flown.t[-1] < 100.0


@pytest.mark.parametrize(
    ("case", "method", "independent"),
    [
        ("suborbital_return.yaml", "lg", "energy"),
        ("suborbital_return.yaml", "lgr", "time"),
        ("shuttle_crossrange_heating.yaml", "lgr", "energy"),
        ("shuttle_crossrange_heating.yaml", "lg", "time"),
    ],
)
def test_the_blockwise_constraint_jacobian_equals_casadis_whole_one(case, method, independent):
    """IPOPT gets the Jacobian block by block (constant linear terms, then the nonlinear
    ones); it must be CasADi's Jacobian of the whole constraint vector, entry for entry."""
    import casadi as ca

    from ovtraj.studies.optimal_entry.formulation import formulate
    from ovtraj.studies.optimal_entry.guess import guess_trajectory

    problem = load_optimal_entry(config_path(f"cases/{case}"))
    trajectory = guess_trajectory(problem)
    form = formulate(problem, independent, trajectory)
    tr = transcribe(form.ocp, method, 5, 3)
    w = tr.initial_point(form.guess(trajectory))
    w = w + 1e-3 * np.random.default_rng(1).standard_normal(w.shape) * np.abs(w)
    g, blockwise = tr.jacobian()(w, [])
    whole = ca.Function("whole", [tr.nlp["x"]], [ca.jacobian(tr.nlp["g"], tr.nlp["x"])])(w)
    np.testing.assert_allclose(
        np.array(g).ravel(), np.array(ca.Function("g", [tr.nlp["x"]], [tr.nlp["g"]])(w)).ravel()
    )
    np.testing.assert_allclose(
        np.array(ca.densify(blockwise)), np.array(ca.densify(whole)), rtol=1e-12, atol=1e-12
    )


def test_the_compiled_us76_equals_the_librarys_from_the_ground_to_its_top():
    """The re-flight's US76 (both regions: the closed form below 86 km, the density nodes
    and temperature segments above) against ovtraj.astro.atmosphere."""
    from ovtraj.config.physical import default_atmosphere
    from ovtraj.studies.optimal_entry.flight_kernel import _us76, _us76_arrays

    atmosphere = default_atmosphere()
    scalars, arrays = _us76_arrays(atmosphere)
    altitudes = np.r_[np.linspace(0.0, atmosphere.top_altitude_m, 2001), 11019.0, 86000.0]
    compiled = np.array([_us76(float(z), scalars, *arrays) for z in altitudes])
    np.testing.assert_allclose(compiled[:, 0], atmosphere.density(altitudes), rtol=1e-12)
    np.testing.assert_allclose(compiled[:, 1], atmosphere.speed_of_sound(altitudes), rtol=1e-12)
