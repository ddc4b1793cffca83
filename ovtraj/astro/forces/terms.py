"""The terms of the high-fidelity force model, each declared once.

A term's name is the key of its acceleration (:func:`ovtraj.astro.forces.dynamics.
accelerations`) and of its section in ``configs/force_model.yaml``
(:class:`ovtraj.config.force_model.ForceModelSettings`, whose switchable sections carry
``enabled``). ``switch`` names the field of
:class:`~ovtraj.astro.forces.dynamics.ForceTerms` that holds the term's figures and whose
``None`` switches it off (``None`` for a term that is always on); ``needs`` names what the
term reads beyond the state: ``sun_position`` (built once for every term that needs it)
and ``space_weather`` (whose bundled table bounds the epochs a flight may reach).

The lists of terms (the accelerations' order, the switches of the settings and of
:class:`~ovtraj.astro.forces.dynamics.ForceTerms`, what the flight's span is checked
against) are all read from :data:`FORCE_TERMS`: a new term is its declaration here and its
kernel in :mod:`.dynamics` (``KERNELS``), with its figures (a field of ``ForceTerms``, a
section of the settings). This module imports nothing heavy: the settings read it
without heyoka.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

__all__ = [
    "FORCE_TERMS",
    "SWITCHABLE",
    "TERM_NAMES",
    "ForceTerm",
    "check_term_names",
    "needed",
]


@dataclass(frozen=True)
class ForceTerm:
    """One term: its name, the field that switches it off (None: always on), its needs."""

    name: str
    switch: str | None
    needs: tuple[str, ...] = ()

    @property
    def switchable(self) -> bool:
        return self.switch is not None


FORCE_TERMS = (
    ForceTerm("gravity", None),
    ForceTerm("drag", "drag_model", needs=("space_weather",)),
    ForceTerm("sun", "sun_mu", needs=("sun_position",)),
    ForceTerm("moon", "moon_mu"),
    ForceTerm("solar_radiation_pressure", "radiation", needs=("sun_position",)),
)
"""Every term, in the order their accelerations are summed."""

TERM_NAMES = tuple(term.name for term in FORCE_TERMS)
SWITCHABLE = tuple(term.name for term in FORCE_TERMS if term.switchable)


def check_term_names(names: Iterable[str]) -> None:
    """``ValueError`` naming any of ``names`` that is not a switchable term."""
    unknown = set(names) - set(SWITCHABLE)
    if unknown:
        raise ValueError(f"unknown force terms {sorted(unknown)}; known: {SWITCHABLE}")


def needed(what: str, switched_on: Iterable[str]) -> bool:
    """Whether a term that is always on, or one of the switchable ``switched_on``, needs
    ``what``."""
    on = set(switched_on)
    return any(
        what in term.needs and (not term.switchable or term.name in on) for term in FORCE_TERMS
    )
