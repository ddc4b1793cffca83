"""The force terms are declared once (``ovtraj.astro.forces.terms``): the kernels, the
settings' sections and switches, the switches of ``ForceTerms`` and the span check all
follow the declaration. No integrator is compiled here."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

from ovtraj.astro.epoch import Epoch
from ovtraj.astro.forces.dynamics import KERNELS, ForceTerms
from ovtraj.astro.forces.terms import FORCE_TERMS, SWITCHABLE, TERM_NAMES, needed
from ovtraj.config.base import load_model
from ovtraj.config.force_model import ForceModelSettings, default_force_model
from ovtraj.errors import ConfigError
from ovtraj.mission.high_fidelity import check_span, force_terms
from ovtraj.target_sources import load_scenario

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(REPO / "configs" / "scenario.yaml")


def test_every_declared_term_has_one_kernel_and_every_kernel_a_term():
    assert list(KERNELS) == list(TERM_NAMES)
    assert len(set(TERM_NAMES)) == len(TERM_NAMES)


def test_each_term_has_its_settings_section_and_its_switch_field():
    fields = {f.name for f in dataclasses.fields(ForceTerms)}
    sections = ForceModelSettings.model_fields
    for term in FORCE_TERMS:
        assert term.name in sections, term.name
        section = sections[term.name].annotation
        assert ("enabled" in section.model_fields) == term.switchable, term.name
        if term.switchable:
            assert term.switch in fields, term.switch
    assert SWITCHABLE == ("drag", "sun", "moon", "solar_radiation_pressure")


@pytest.mark.parametrize("on", [(), ("drag",), ("moon", "solar_radiation_pressure"), SWITCHABLE])
def test_the_settings_switches_reach_the_terms(scenario, on):
    settings = default_force_model().only(*on)
    assert settings.switched_on() == on
    terms = force_terms(settings, scenario)
    assert terms.switched_on() == ("gravity", *on)
    for term in FORCE_TERMS:
        if term.switchable:
            assert (getattr(terms, term.switch) is None) == (term.name not in on), term.name
    everything = force_terms(default_force_model().only(*SWITCHABLE), scenario)
    assert everything.only(*on) == terms


def test_an_unknown_term_is_refused_naming_it(scenario):
    with pytest.raises(ValueError, match="'drug'"):
        default_force_model().only("drag", "drug")
    with pytest.raises(ValueError, match="'drug'"):
        force_terms(default_force_model(), scenario).only("drug")


def test_the_needs_follow_the_terms_switched_on():
    assert needed("space_weather", ("drag",)) and not needed("space_weather", ("sun", "moon"))
    assert needed("sun_position", ("solar_radiation_pressure",))
    assert not needed("sun_position", ("drag", "moon"))


def test_the_bundled_space_weather_bounds_a_flight_only_with_a_term_that_reads_it(tmp_path):
    data = yaml.safe_load((REPO / "configs" / "force_model.yaml").read_text(encoding="utf-8"))
    data["space_weather"]["source"] = "bundled"
    path = tmp_path / "force_model.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    settings = load_model(ForceModelSettings, path)
    start, beyond = Epoch.from_iso("2026-10-01T00:00:00"), Epoch.from_iso("2026-11-07T00:00:00")
    check_span(settings.only("sun", "moon"), start, beyond)  # no drag: no space weather read
    with pytest.raises(ConfigError, match=r"space_weather\.source"):
        check_span(settings.only("drag"), start, beyond)
