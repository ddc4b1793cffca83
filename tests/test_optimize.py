"""NSGA-II, the hypervolume, the infill picks and the front pick.

References: closed-form hypervolumes of boxes; a bi-objective problem whose Pareto set
is known in closed form (the segment between the two objectives' minimisers, for any
increasing function of the squared distances); hand-made fronts.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.stats import qmc

from ovtraj.optimize import (
    MISSION_OBJECTIVES,
    Normalisation,
    hypervolume,
    non_dominated,
    nsga2_front,
    spread_picks,
)
from ovtraj.pipeline import Pick, PipelineError, pick_front_point

A = np.array([0.2, 0.3, 0.7])
B = np.array([0.8, 0.6, 0.2])


def _objectives(units: np.ndarray) -> np.ndarray:
    """f1 = |x - A|^2, f2 = exp(|x - B|^2 / 2) - 1: Pareto set = segment A-B."""
    f1 = np.sum((units - A) ** 2, axis=1)
    f2 = np.exp(0.5 * np.sum((units - B) ** 2, axis=1)) - 1.0
    return np.column_stack([f1, f2])


def _distance_to_segment(points: np.ndarray) -> np.ndarray:
    d = B - A
    t = np.clip((points - A) @ d / (d @ d), 0.0, 1.0)
    return np.linalg.norm(points - (A + t[:, None] * d), axis=1)


def _exact_front(n: int) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    return _objectives(A + t[:, None] * (B - A))


def test_hypervolume_of_boxes_in_closed_form():
    assert hypervolume(np.array([[0.5, 0.5, 0.5]])) == pytest.approx(0.125, abs=1e-12)
    # Two boxes: 0.5*1*1 + 1*0.5*1 - overlap 0.5*0.5*1.
    two = np.array([[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]])
    assert hypervolume(two) == pytest.approx(0.75, abs=1e-12)
    # Points at or beyond the reference point add nothing; a dominated point adds nothing.
    assert hypervolume(np.array([[1.0, 0.2, 0.2], [1.5, 0.0, 0.0]])) == 0.0
    assert hypervolume(np.vstack([two, [[0.6, 0.6, 0.6]]])) == pytest.approx(0.75, abs=1e-12)
    assert hypervolume(np.zeros((0, 3))) == 0.0


def test_non_dominated_on_a_hand_made_table():
    values = np.array([[1, 5], [2, 2], [3, 3], [5, 1], [2, 2], [4, 4]], dtype=float)
    assert non_dominated(values).tolist() == [0, 1, 3, 4]


def test_normalisation_maps_ideal_to_zero_reference_to_one_and_back(scenario):
    norm = Normalisation.mission(scenario.mission.optimize)
    both = np.vstack([norm.ideal, norm.reference])
    assert np.allclose(norm.normalise(both), [[0, 0, 0], [1, 1, 1]])
    values = np.array([[300000.0, 220.0, 400.0]])
    assert np.allclose(norm.physical(norm.normalise(values)), values)
    # M_load is maximised: more payload is a smaller normalised value.
    assert norm.normalise([[0, 0, 405.0]])[0, 2] < norm.normalise([[0, 0, 395.0]])[0, 2]
    assert [o.name for o in MISSION_OBJECTIVES] == list(norm.names)
    with pytest.raises(ValueError, match="m_load_kg"):
        Normalisation(MISSION_OBJECTIVES, norm.ideal, norm.ideal * np.array([2, 2, 2]))


def test_nsga2_finds_the_known_pareto_set():
    def model(units):
        return _objectives(units), None

    designs, values, info = nsga2_front(model, 3, 2, population=60, generations=120, seed=3)
    assert len(designs) >= 30 and info["evaluations"] == 60 * 120
    exact = _exact_front(2001)
    span = exact.max(axis=0)
    # Every point lies on the exact front to 5 % of its span (measured 3.3 %), the designs
    # near the segment A-B (median measured 0.028), and the front covers it (HV 98.8 %).
    gap = (values[:, 1] - np.interp(values[:, 0], exact[:, 0], exact[:, 1])) / span[1]
    assert np.all(gap > -1e-9) and np.max(gap) < 0.05
    assert np.median(_distance_to_segment(designs)) < 0.05
    assert hypervolume(values / span) >= 0.98 * hypervolume(exact / span)
    again, _, _ = nsga2_front(model, 3, 2, population=60, generations=120, seed=3)
    assert np.array_equal(designs, again)


def test_nsga2_respects_a_constraint_and_reports_an_empty_feasible_set():
    def cut(units):  # feasible only where x0 <= 0.5: the front stops there
        return _objectives(units), (units[:, 0] - 0.5)[:, None]

    designs, _, info = nsga2_front(cut, 3, 2, population=40, generations=60, seed=1, n_constr=1)
    assert info["reason"] is None and np.all(designs[:, 0] <= 0.5 + 1e-12)

    def nowhere(units):
        return _objectives(units), np.ones((len(units), 1))

    designs, values, info = nsga2_front(
        nowhere, 3, 2, population=10, generations=3, seed=1, n_constr=1
    )
    assert designs.shape == (0, 3) and values.shape == (0, 2) and "no feasible" in info["reason"]


def test_nsga2_matches_pymoos_own_nsga2():
    """The array NSGA-II against pymoo's NSGA2 class (the same algorithm and defaults, a
    second implementation) on the constrained problem: over five seeds each, the fronts'
    hypervolumes agree within 1 % (measured: ours 0.05 % higher, in 0.13 s against 0.55 s),
    and ours makes the same evaluations."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.optimize import minimize

    def cut(units):
        return _objectives(units), (units[:, 0] - 0.5)[:, None]

    class Cut(Problem):
        def __init__(self):
            super().__init__(n_var=3, n_obj=2, n_ieq_constr=1, xl=0.0, xu=1.0)

        def _evaluate(self, x, out, *args, **kwargs):
            out["F"], out["G"] = cut(x)

    span = _exact_front(2001).max(axis=0)
    ours, theirs = [], []
    for seed in range(5):
        _, values, info = nsga2_front(
            cut, 3, 2, population=40, generations=60, seed=seed, n_constr=1
        )
        assert info["evaluations"] == 40 * 60
        ours.append(hypervolume(values / span))
        result = minimize(Cut(), NSGA2(pop_size=40), ("n_gen", 60), seed=seed)
        theirs.append(hypervolume(np.atleast_2d(result.F) / span))
    assert np.mean(ours) == pytest.approx(np.mean(theirs), rel=0.01)


def test_surrogates_of_an_analytic_problem_give_the_known_front(scenario):
    """SMT surrogates fitted on 60 samples, then NSGA-II on them (not on the functions)."""
    from ovtraj.surrogate import fit_surrogates

    settings = scenario.mission.surrogate
    units = qmc.LatinHypercube(d=3, seed=5).random(60)
    values = _objectives(units)
    outputs = {"f1": values[:, 0], "f2": values[:, 1]}
    surrogates = fit_surrogates(
        units,
        outputs,
        np.ones(60, dtype=bool),
        np.zeros(3),
        np.ones(3),
        settings,
        input_names=("x0", "x1", "x2"),
    )
    chosen = surrogates.validation[surrogates.validation["selected"].astype(bool)]
    assert set(chosen["model"]) >= {"f1", "f2"}
    assert (chosen.set_index("model").loc[["f1", "f2"], "heldout_r2"] > 0.99).all()

    def model(u):
        predicted = surrogates.predict(u)
        return np.column_stack([predicted["f1"], predicted["f2"]]), None

    designs, _, _ = nsga2_front(model, 3, 2, population=60, generations=120, seed=3)
    exact = _exact_front(2001)
    span = exact.max(axis=0)
    real = _objectives(designs)  # the surrogate front's designs, evaluated exactly
    gap = (real[:, 1] - np.interp(real[:, 0], exact[:, 0], exact[:, 1])) / span[1]
    assert np.max(gap) < 0.05 and np.median(_distance_to_segment(designs)) < 0.05
    assert hypervolume(real / span) >= 0.97 * hypervolume(exact / span)


def test_spread_picks_cover_the_front_and_skip_evaluated_designs():
    t = np.linspace(0.0, 1.0, 21)
    normalised = np.column_stack([t, 1.0 - t])
    units = np.column_stack([t, t, t])
    picks = spread_picks(normalised, units, np.zeros((0, 3)), 3, 0.02)
    assert sorted(picks) == [0, 10, 20]
    # The first objective's best point is already evaluated: the next ones are taken.
    picks = spread_picks(normalised, units, units[:1] + 0.001, 3, 0.02)
    assert 0 not in picks and len(picks) == 3 and 20 in picks
    assert spread_picks(normalised, units, units, 3, 0.02) == []
    assert spread_picks(normalised, units, np.zeros((0, 3)), 50, 0.02) == list(
        spread_picks(normalised, units, np.zeros((0, 3)), 50, 0.02)
    )
    assert len(spread_picks(normalised, units, np.zeros((0, 3)), 50, 0.02)) == 21


def test_pick_by_index_weights_and_limits(scenario):
    norm = Normalisation.mission(scenario.mission.optimize)
    front = pd.DataFrame(
        {
            "front_index": [0, 1, 2],
            "sample_id": [7, 3, 9],
            "t_total_s": [260000.0, 340000.0, 430000.0],
            "dv_total_mps": [290.0, 230.0, 200.0],
            "m_load_kg": [409.0, 400.0, 392.0],
        }
    )
    assert pick_front_point(front, norm, Pick(index=1))["sample_id"] == 3
    assert pick_front_point(front, norm, Pick(weights=(1, 0, 0)))["sample_id"] == 7
    assert pick_front_point(front, norm, Pick(weights=(0, 1, 0)))["sample_id"] == 9
    assert (
        pick_front_point(front, norm, Pick(max_dv_total_mps=250, weights=(1, 0, 0)))["sample_id"]
        == 3
    )
    with pytest.raises(PipelineError, match=r"pick index 3 is outside the front: allowed 0\.\.2"):
        pick_front_point(front, norm, Pick(index=3))
    with pytest.raises(PipelineError, match="max_t_total_h = 10"):
        pick_front_point(front, norm, Pick(max_t_total_h=10))
    with pytest.raises(PipelineError, match="weights"):
        pick_front_point(front, norm, Pick(weights=(0, 0, 0)))
    with pytest.raises(PipelineError, match="empty"):
        pick_front_point(front.iloc[:0], norm, Pick())


def test_hypervolume_picks_take_the_largest_predicted_gain_first():
    from ovtraj.optimize import hypervolume_picks

    real = np.array([[0.5, 0.5, 0.5]])
    # b dominates the real point: gain 0.6^3 - 0.5^3 = 0.091; a adds a thin slab,
    # 0.9*0.1*0.1 - 0.5*0.1*0.1 = 0.004; c is dominated: no gain.
    normalised = np.array([[0.1, 0.9, 0.9], [0.4, 0.4, 0.4], [0.6, 0.6, 0.6]])
    units = np.array([[0.1, 0.1, 0.1], [0.5, 0.5, 0.5], [0.9, 0.9, 0.9]])
    none = np.zeros((0, 3))
    assert hypervolume_picks(normalised, units, none, real, 1, 0.02) == [1]
    assert hypervolume_picks(normalised, units, none, real, 2, 0.02) == [1, 0]
    # No gain left: the rest is spread, so the count is still met.
    assert hypervolume_picks(normalised, units, none, real, 3, 0.02) == [1, 0, 2]
    # An evaluated design is never picked again.
    assert hypervolume_picks(normalised, units, units[1:2], real, 1, 0.02) == [0]
