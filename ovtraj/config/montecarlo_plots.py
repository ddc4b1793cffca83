"""What the pictures of a plan's Monte Carlo draw (``configs/montecarlo_plots.yaml``).

The landing footprint's zoom at the site and the runway of each landing site, by the name
of the scenario's ``reentry.landing_site``. Like ``configs/io_limits.yaml`` these belong
to no scenario: they change the pictures only, never a result or a run id.
"""

from __future__ import annotations

from functools import lru_cache

from pydantic import Field

from ovtraj.config.base import StrictModel, bounded, load_model

__all__ = ["FootprintSettings", "MonteCarloPlotSettings", "Runway", "default_montecarlo_plots"]


class Runway(StrictModel):
    """A landing site's runway, drawn centred on the site."""

    designation: str = Field(min_length=1, max_length=16, description="e.g. 15/33")
    heading_deg: float = bounded(unit="deg", ge=0, lt=360, description="axis, from north")
    length_m: float = bounded(unit="m", gt=0, le=20000)
    width_m: float = bounded(unit="m", gt=0, le=1000)


class FootprintSettings(StrictModel):
    """The landing footprint."""

    zoom_half_width_stated_miss: float = bounded(
        gt=0, le=100, description="the site panel's half width in stated misses"
    )


class MonteCarloPlotSettings(StrictModel):
    """``configs/montecarlo_plots.yaml``."""

    footprint: FootprintSettings
    runways: dict[str, Runway] = Field(max_length=1000)


@lru_cache(maxsize=1)
def default_montecarlo_plots() -> MonteCarloPlotSettings:
    """The shipped ``configs/montecarlo_plots.yaml``."""
    from ovtraj.paths import config_path

    return load_model(MonteCarloPlotSettings, config_path("montecarlo_plots.yaml"))
