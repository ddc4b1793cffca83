"""Known limits on smooth quantities decide feasibility on those quantities' own models.

The cheapest designs of the default scenario lie where the rendezvous' phasing wait
reaches ``rendezvous.max_wait_time_s``; a classifier that does not know the limit guessed
that edge. Here: the rendezvous keeps the wait it needs when it refuses one, the limits
name the samples they explain, the classifier no longer sees those, and the surrogate
front never holds a design whose predicted wait is past the limit.
"""

from __future__ import annotations

import numpy as np
import pytest

from ovtraj.config import scenario_from_dict
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, evaluate
from ovtraj.mission.chain import launch_leg
from ovtraj.pipeline.features import DEORBIT_PASSES, PHASING_WAIT, WAIT, KnownLimits
from ovtraj.pipeline.mission_fit import fit_mission_surrogates
from ovtraj.pipeline.pass_model import PassModel
from ovtraj.rendezvous.phasing import secular_phasing

# H_P0 past the wait limit by a few hundred seconds (refined) and by far (secular only),
# and one inside it; each with the same H_dp and t_dsp.
NEAR, FAR, INSIDE = 336.7, 345.0, 330.0
H_DP, T_DSP = 378.5, 0.43


@pytest.fixture(scope="module")
def context(scenario) -> MissionContext:
    return MissionContext(scenario, find_launch_fit(scenario))


def test_a_refused_wait_is_kept_refined_near_the_limit_and_secular_beyond(context, scenario):
    limit = scenario.rendezvous.max_wait_time_s
    window = scenario.rendezvous.burn_epoch_window_s
    near = evaluate(context, MissionDesign(NEAR, H_DP, T_DSP))
    far = evaluate(context, MissionDesign(FAR, H_DP, T_DSP))
    inside = evaluate(context, MissionDesign(INSIDE, H_DP, T_DSP))
    assert inside.feasible and not near.feasible and not far.feasible
    for record in (near, far):
        row = record.stages["rendezvous"]
        assert record.failed_stage == "rendezvous" and row["phasing_wait_s"] > limit
        assert f"a wait of {row['phasing_wait_s']:.0f} s" in row["reason"]
        assert row["wait_time_s"] is None  # no burn was placed
    assert near.stages["rendezvous"]["phasing_wait_s"] <= limit + window
    # With the limit out of the way the same rendezvous flies: near the limit its phasing
    # wait is the one the refusal kept (the J2 correction then moves the burn itself by up
    # to the burn window); far beyond, the refusal kept the secular estimate, within a few
    # hundred seconds of the refined wait.
    data = scenario.resolved()
    data["rendezvous"]["max_wait_time_s"] = 2.0 * limit
    relaxed = MissionContext(scenario_from_dict(data, "relaxed wait"), context.fit)
    for record, tolerance in ((near, 1e-6), (far, 1000.0)):
        flown = evaluate(relaxed, record.design)
        assert flown.stages["rendezvous"]["feasible"]
        assert flown.stages["rendezvous"]["phasing_wait_s"] == pytest.approx(
            record.stages["rendezvous"]["phasing_wait_s"], abs=tolerance
        )
        moved = (
            flown.stages["rendezvous"]["wait_time_s"] - flown.stages["rendezvous"]["phasing_wait_s"]
        )
        assert abs(moved) <= window
    leg = launch_leg(context, MissionDesign(FAR, H_DP, T_DSP))
    secular = secular_phasing(
        leg.insertion_state, context.target_at(leg.insertion_time_s), scenario.earth
    )
    assert far.stages["rendezvous"]["phasing_wait_s"] == pytest.approx(secular.wait_s, rel=1e-12)


@pytest.fixture(scope="module")
def limited(context, scenario):
    """A 40-sample DoE's training data (as the pipeline reads it) and its surrogates."""
    from ovtraj.mission.design_space import bounds_arrays, latin_hypercube
    from ovtraj.pipeline.data import COMPONENTS, TrainingData

    table = latin_hypercube(scenario.mission.design_bounds, 40, 2031)
    designs = table[list(DESIGN_NAMES)].to_numpy(dtype=float)
    records = [evaluate(context, MissionDesign(*row)) for row in designs]

    def column(stage: str, key: str) -> np.ndarray:
        return np.array(
            [
                np.nan if r.stages.get(stage, {}).get(key) is None else r.stages[stage][key]
                for r in records
            ],
            dtype=float,
        )

    feasible = np.array([r.feasible for r in records])
    outputs = {
        name: np.array([r.totals()[name] if r.feasible else np.nan for r in records], dtype=float)
        for name in ("t_total_s", "dv_total_mps", "m_load_kg")
    }
    data = TrainingData(
        sample_ids=np.arange(len(records), dtype=np.int64),
        designs=designs,
        outputs=outputs,
        feasible=feasible,
        components={name: column(*where) for name, where in COMPONENTS.items()},
    )
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    return {
        "data": data,
        "records": records,
        "surrogates": fit_mission_surrogates(data, scenario, lower, upper),
    }


def test_the_limits_explain_the_wait_and_no_pass_refusals(limited, scenario):
    data, records = limited["data"], limited["records"]
    pass_model = limited["surrogates"].pass_model
    limits = KnownLimits.of(scenario, pass_model)
    explained = limits.explained(data, pass_model)
    reasons = [r.reason or "" for r in records]
    by_wait = np.array(["phasing needs a wait" in why for why in reasons])
    at_deorbit = np.array([r.failed_stage == "deorbit" for r in records])
    assert by_wait.any() and not np.any(explained & data.feasible)
    # Every wait refusal, and the deorbit refusals where the pass model finds no pass
    # either: here all of them (the chain's deorbit and the model agree).
    assert np.array_equal(explained & ~at_deorbit, by_wait)
    assert np.array_equal(explained & at_deorbit, at_deorbit)
    assert np.all(data.components[DEORBIT_PASSES][at_deorbit & (explained)] >= 0)
    # Without the pass model only the waits are explained.
    assert np.array_equal(limits.explained(data), by_wait)


def test_the_classifier_learns_only_the_unexplained_refusals(limited):
    surrogates = limited["surrogates"]
    # On this scenario every refusal is a known limit's: the classifier has only feasible
    # samples to learn from, and its probability is 1 everywhere.
    assert surrogates.limits is not None
    assert surrogates.main.selected["feasible"] == "all-feasible"
    assert surrogates.wait.selected[WAIT] and surrogates.phasing.selected[PHASING_WAIT]


def test_no_design_past_the_predicted_wait_limit_is_called_feasible(limited, scenario):
    surrogates = limited["surrogates"]
    limit = scenario.rendezvous.max_wait_time_s
    h_p0 = np.linspace(250.0, 350.0, 201)
    designs = np.column_stack([h_p0, np.full_like(h_p0, H_DP), np.full_like(h_p0, T_DSP)])
    waits = surrogates.phasing.predict(designs[:, :1])[PHASING_WAIT]
    p = surrogates.feasibility(designs)
    constraints = surrogates.constraints(designs, 0.5)
    assert np.all(p[waits > limit] == 0.0)
    assert np.all(constraints[waits > limit].max(axis=1) > 0.0)
    beyond = waits > limit
    assert beyond.any() and (~beyond).any()
    # The predicted edge lies within a few hundred metres of H_P0 of the chain's.
    edge = h_p0[np.flatnonzero(beyond)[0]]
    assert 334.0 < edge < 339.0


def test_the_pass_model_finds_no_pass_where_the_chain_finds_none(limited, scenario):
    data, records = limited["data"], limited["records"]
    series = find_launch_fit(scenario).series
    model = PassModel.of(scenario, series["insertion_time_s"], series["flight_time_s"])
    reached = np.isfinite(data.components[WAIT])
    has = model.has_pass(data.designs[reached], data.components[WAIT][reached])
    chain = np.array([not (r.failed_stage == "deorbit") for r in records])[reached]
    assert (chain == has).mean() >= 0.95
