"""Orbit propagation: the compiled Taylor propagator, events, and a reference integrator."""

from ovtraj.astro.propagation.events import (
    AltitudeCrossing,
    ArgumentOfLatitudeCrossing,
    Event,
    EventContext,
    LatitudeCrossing,
    LongitudeCrossing,
)
from ovtraj.astro.propagation.taylor import EventHit, OrbitPropagator, PropagationResult

__all__ = [
    "AltitudeCrossing",
    "ArgumentOfLatitudeCrossing",
    "Event",
    "EventContext",
    "EventHit",
    "LatitudeCrossing",
    "LongitudeCrossing",
    "OrbitPropagator",
    "PropagationResult",
]
