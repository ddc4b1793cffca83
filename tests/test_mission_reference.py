"""The mission chain gives the results it gave before the speed work.

The reference values were stored from main before any change to the chain's speed
(``tools/mission_reference.py``, ``data/reference/mission_chain/``, the code version in
its marker) and stored again for each deliberate change of the physics, the values before
it kept beside: the rendezvous's multi-start (``mission_chain_single_start/``;
tests/test_rendezvous_local_optima.py compares the two), the plane aimed at the
rendezvous (``mission_chain_plane_at_launch/``; tests/test_plane_aim.py) and the deorbit's
pass within a cost bound (``mission_chain_first_pass/``, below). The tolerances are
``configs/mission_reference.yaml``'s.
"""

from __future__ import annotations

import pytest

from ovtraj.mission import reference


@pytest.fixture(scope="module")
def compared():
    settings = reference.load_settings()
    stored, marker = reference.load()  # every file checked against the marker's digest
    context = reference.context(settings)
    now = reference.values(context, reference.designs(context.scenario, settings))
    return settings, stored, marker, now


def test_the_reference_covers_the_configured_designs(compared):
    settings, stored, marker, _ = compared
    assert len(stored) == settings.designs + len(settings.extra_designs)
    assert settings.designs >= 20
    assert marker["settings"] == settings.model_dump(mode="json")
    assert stored["feasible"].sum() == marker["feasible"] > 0
    assert stored["landing_miss_m"].notna().sum() >= stored["feasible"].sum()


def test_every_design_gives_its_stored_totals_within_the_tolerances(compared):
    settings, stored, _, now = compared
    assert reference.differences(stored, now, settings.tolerances) == []


def test_a_change_beyond_a_tolerance_is_reported_naming_the_design(compared):
    settings, stored, _, now = compared
    changed = now.copy()
    k = int(changed.index[changed["feasible"]][0])
    changed.loc[k, "dv_total_mps"] += 2 * settings.tolerances.dv_mps
    changed.loc[k, "landing_miss_m"] += 0.5 * settings.tolerances.landing_miss_m  # within
    (line,) = reference.differences(stored, changed, settings.tolerances)
    assert line.startswith(f"design {stored.loc[k, 'design']}: dv_total_mps")
    flipped = now.copy()
    flipped.loc[k, "feasible"] = False
    assert any(
        "feasible" in line for line in reference.differences(stored, flipped, settings.tolerances)
    )


def test_without_the_pass_cost_margin_the_chain_takes_the_first_pass_as_before(compared):
    """``deorbit.solver.pass_cost_margin_mps: null`` (a config stored before it) gives the
    values stored before the rule, and the rule changes only the designs where it acts."""
    from ovtraj.config import scenario_from_dict
    from ovtraj.mission import MissionContext

    settings, now_stored, _, _ = compared
    before, _ = reference.load(
        reference.reference_directory().with_name("mission_chain_first_pass")
    )
    context = reference.context(settings)
    data = context.scenario.resolved()
    data["deorbit"]["solver"]["pass_cost_margin_mps"] = None
    first_pass = MissionContext(scenario_from_dict(data, "first pass"), context.fit)
    designs = reference.designs(context.scenario, settings)
    again = reference.values(first_pass, designs[: len(before)])
    assert reference.differences(before, again, settings.tolerances) == []
    # The hypercube's designs meet no pinned burn: the same values with the rule as without.
    assert reference.differences(before, now_stored.iloc[: len(before)], settings.tolerances) == []
    # The added designs: without the rule a radially steered burn, with it the next pass.
    extra = reference.values(first_pass, designs[len(before) :])
    rule = now_stored.iloc[len(before) :].reset_index(drop=True)
    assert (extra["deorbit_dv_mps"] > rule["deorbit_dv_mps"] + 15.0).all()
    assert (rule["t_total_s"] - extra["t_total_s"] > 12 * 3600.0).all()
