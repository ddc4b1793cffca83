"""Settings of the CCSDS export of a mission plan (``configs/ccsds_export.yaml``; issue 23).

The export writes the planned trajectory as a CCSDS Orbit Ephemeris Message and the
plan's manoeuvres as an Orbit Parameter Message (CCSDS 502.0-B-2, *Orbit Data
Messages*, Blue Book, 2009: OEM and OPM version 2.0, KVN). These settings name the
object and choose the sampling and the interpolation the OEM declares.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

from pydantic import Field

from ovtraj.config.base import StrictModel, bounded, load_model


class CcsdsExportSettings(StrictModel):
    """What the exported messages declare and how finely the trajectory is sampled."""

    originator: str = Field(min_length=1, max_length=64, description="ORIGINATOR keyword")
    object_id: str = Field(
        min_length=1,
        max_length=64,
        description="OBJECT_ID keyword (the international designator once one exists)",
    )
    ref_frame: Literal["EME2000"] = Field(
        description="REF_FRAME: the J2000 mean equator and equinox (IAU-76/80 realisation)"
    )
    time_system: Literal["UTC"] = Field(description="TIME_SYSTEM of every epoch")
    orbit_step_s: float = bounded(
        unit="s", gt=0, le=3600, description="OEM sampling on the orbital arcs"
    )
    entry_step_s: float = bounded(
        unit="s", gt=0, le=600, description="OEM sampling in the atmosphere"
    )
    interpolation: Literal["HERMITE", "LAGRANGE"] = Field(
        description="INTERPOLATION declared for a reader between the OEM's samples"
    )
    interpolation_degree: int = bounded(ge=1, le=15, description="INTERPOLATION_DEGREE")


@lru_cache(maxsize=1)
def default_export_settings() -> CcsdsExportSettings:
    """The shipped ``configs/ccsds_export.yaml``."""
    from ovtraj.paths import config_path

    return load_model(CcsdsExportSettings, config_path("ccsds_export.yaml"))
