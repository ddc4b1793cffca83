"""The mission chain gives the results it gave before the speed work (issue 20).

The reference values were stored from main before any change to the chain's speed
(``tools/mission_reference.py``, ``data/reference/mission_chain/``, the code version in
its marker) and stored again once, for a deliberate change of the physics: the
rendezvous's multi-start (the values before it are kept in
``data/reference/mission_chain_single_start/``; tests/test_rendezvous_local_optima.py
compares the two). The tolerances are ``configs/mission_reference.yaml``'s.
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
    assert len(stored) == settings.designs >= 20
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
