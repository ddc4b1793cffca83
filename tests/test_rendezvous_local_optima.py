"""The rendezvous keeps the cheapest of its local optima (docs/rendezvous.md, "Local optima").

With a plane difference between the insertion orbit and the target's, the J2 correction
NLP has optima on both sides of the 180-degree transfer. The reference: the interior
point run from every one of ten start shots spread over the transfer-time bounds, each
on its own; the stage's multi-start must find the cheapest of them. The rendezvous
problems are the ones the mission chain poses for its first reference designs with the
target's plane at insertion (the chain without plane management, ``mission.insertion: null``:
0.44-0.45 deg apart at the burn); with the plane aimed at the rendezvous they are nearly
coplanar and have one optimum (docs/rendezvous.md, "Plane management").
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import ovtraj.rendezvous.stage as rendezvous_stage
from ovtraj.mission import MissionContext, evaluate, reference
from ovtraj.rendezvous.correction import CorrectionProblem, correct_transfer

# Transfer-time fractions of the independent reference: the default bounds are [0.5, 1.5].
REFERENCE_STARTS = (0.55, 0.65, 0.75, 0.85, 0.95, 1.05, 1.15, 1.25, 1.35, 1.45)
DESIGNS = 6  # the first reference designs: two of them end in a worse optimum from one start
DV_TOLERANCE_MPS = reference.load_settings().tolerances.dv_mps  # the chain reference's


def _total(result) -> float:
    return float(np.linalg.norm(result.dv1_eci) + np.linalg.norm(result.dv2_eci))


@pytest.fixture(scope="module")
def rendezvous_problems() -> list[CorrectionProblem]:
    """The chain's rendezvous correction problems (not the transfers) for the designs."""
    settings = reference.load_settings()
    aimed = reference.context(settings)
    scenario = aimed.scenario
    mission = scenario.mission.model_copy(update={"insertion": None})
    context = MissionContext(scenario.model_copy(update={"mission": mission}), aimed.fit)
    posed: list[CorrectionProblem] = []

    def recording(problem: CorrectionProblem):
        if problem.solve_every_start:
            posed.append(problem)
        return correct_transfer(problem)

    patch = pytest.MonkeyPatch()
    patch.setattr(rendezvous_stage, "correct_transfer", recording)
    try:
        for design in reference.designs(context.scenario, settings)[:DESIGNS]:
            evaluate(context, design)
    finally:
        patch.undo()
    assert len(posed) >= 4
    return posed


def test_the_chain_solves_its_rendezvous_from_every_configured_start(rendezvous_problems):
    settings = reference.context(reference.load_settings()).scenario.rendezvous
    for problem in rendezvous_problems:
        assert problem.start_fractions == settings.multi_start_fractions


def test_the_multi_start_finds_the_cheapest_of_ten_single_starts(rendezvous_problems):
    improved = 0
    for problem in rendezvous_problems:
        kept = correct_transfer(problem)
        assert kept.converged
        singles = [
            correct_transfer(
                dataclasses.replace(problem, start_fractions=(f,), solve_every_start=False)
            )
            for f in REFERENCE_STARTS
        ]
        cheapest = min(_total(s) for s in singles if s.converged)
        assert _total(kept) <= cheapest + DV_TOLERANCE_MPS
        # What the stage did before: the interior point from the cheapest shot only.
        one_start = correct_transfer(
            dataclasses.replace(problem, start_fractions=(0.85, 1.0, 1.15), solve_every_start=False)
        )
        assert _total(kept) <= _total(one_start) + DV_TOLERANCE_MPS
        improved += _total(one_start) > _total(kept) + 5.0
    # Not idle: on these designs a single start ends in a worse optimum.
    assert improved >= 2


def test_a_failed_shot_falls_back_to_the_hohmann_guess_once(rendezvous_problems):
    problem = rendezvous_problems[0]
    # Both shots cannot meet a zero miss tolerance: both start from the guess, solved once.
    hopeless = dataclasses.replace(problem, miss_tolerance_m=0.0, max_iterations=3)
    result = correct_transfer(hopeless)
    single = correct_transfer(dataclasses.replace(hopeless, solve_every_start=False))
    assert not result.converged
    assert result.limit == "rendezvous.max_iterations = 3 reached"
    assert result.evaluations == single.evaluations  # the guess's solve, not twice
    assert _total(result) == _total(single)


def test_the_stored_reference_only_lowered_the_rendezvous_cost():
    """The chain's reference before and after the multi-start (both stored and checked):
    the same designs and feasibility, no rendezvous dearer, seven cheaper by 1-21 m/s."""
    settings = reference.load_settings()
    before, before_marker = reference.load(
        reference.reference_directory().with_name("mission_chain_single_start")
    )
    # The chain after the multi-start, stored with the target's plane at insertion (the current
    # reference, mission_chain/, is a different chain: tests/test_plane_aim.py).
    after, after_marker = reference.load(
        reference.reference_directory().with_name("mission_chain_plane_at_launch")
    )
    assert before_marker["code_version"] != after_marker["code_version"]
    assert before[list(reference.DESIGN_NAMES)].equals(after[list(reference.DESIGN_NAMES)])
    assert before["feasible"].equals(after["feasible"])
    feasible = after["feasible"]
    lowered = (before["rendezvous_dv_mps"] - after["rendezvous_dv_mps"])[feasible]
    assert (lowered >= -settings.tolerances.dv_mps).all()
    assert int((lowered > 5.0).sum()) >= 5
    # dV_total mostly follows. Not always: the deorbit's cost moves with the arrival time
    # (design 3 arrives 113 s later, 11.7 m/s cheaper, and its deorbit costs 22.1 m/s more).
    total_lowered = (before["dv_total_mps"] - after["dv_total_mps"])[feasible]
    assert int((total_lowered > 5.0).sum()) >= 5
