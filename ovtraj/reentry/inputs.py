"""The reentry stage's input (SI), from a scenario or from the deorbit stage's entry state."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.config.reentry import ReentrySettings
from ovtraj.config.scenario import Scenario


@dataclass(frozen=True)
class EntryState:
    """Earth-relative entry state: geocentric position and relative velocity (SI, rad)."""

    epoch: Epoch
    latitude_rad: float
    longitude_rad: float
    altitude_m: float
    speed_mps: float
    fpa_rad: float
    heading_rad: float  # from north, clockwise


@dataclass(frozen=True)
class ReentryInput:
    entry: EntryState
    earth: EarthModel
    settings: ReentrySettings

    @property
    def target_latitude_rad(self) -> float:
        return math.radians(self.settings.landing_site.latitude_deg)

    @property
    def target_longitude_rad(self) -> float:
        return math.radians(self.settings.landing_site.longitude_deg)


def entry_from_config(settings: ReentrySettings) -> EntryState:
    e = settings.entry
    return EntryState(
        epoch=Epoch.from_iso(e.epoch_utc),
        latitude_rad=math.radians(e.latitude_deg),
        longitude_rad=math.radians(e.longitude_deg),
        altitude_m=e.altitude_km * 1e3,
        speed_mps=e.speed_mps,
        fpa_rad=math.radians(e.fpa_deg),
        heading_rad=math.radians(e.heading_deg),
    )


def reentry_input(scenario: Scenario, *, entry: EntryState | None = None) -> ReentryInput:
    """The reentry problem of a scenario; ``entry`` (e.g. the deorbit's) overrides its entry.

    Raises ``ValueError`` when the scenario has no ``reentry`` section.
    """
    settings = scenario.reentry
    if settings is None:
        raise ValueError("the scenario has no reentry section")
    return ReentryInput(
        entry=entry if entry is not None else entry_from_config(settings),
        earth=scenario.earth,
        settings=settings,
    )
