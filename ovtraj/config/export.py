"""Settings of the CCSDS export of a mission plan (``configs/ccsds_export.yaml``; docs/export.md).

The export writes the planned trajectory as a CCSDS Orbit Ephemeris Message and the
plan's manoeuvres as an Orbit Parameter Message (CCSDS 502.0-B-2, *Orbit Data
Messages*, Blue Book, 2009: OEM and OPM version 2.0, KVN). These settings name the
object and choose the sampling and the interpolation the OEM declares. Every text
written into a message is printable ASCII (:func:`kvn_value_problem`).
"""

from __future__ import annotations

from enum import StrEnum
from functools import lru_cache
from typing import Literal

from pydantic import Field, field_validator

from ovtraj.config.base import StrictModel, bounded, load_model


class ExportFormat(StrEnum):
    """The messages a plan is exported as: ``oem`` the whole trajectory, ``opm`` the
    insertion state and the impulses. Here, with the export's settings, not with the
    writer (:mod:`ovtraj.mission.ccsds`): ``ovtraj export --help`` offers them without
    loading the mission's dynamics (~6 s)."""

    oem = "oem"
    opm = "opm"


FORMATS: tuple[str, ...] = tuple(member.value for member in ExportFormat)

# The characters of a KVN message: printable ASCII and the blank, 32-126 (CCSDS
# 502.0-B-3, Orbit Data Messages, 2023, the KVN chapter: lines of printable ASCII
# characters and blanks; no control character, such as a tab, except the line ends).
_KVN_CHARACTERS = range(ord(" "), ord("~") + 1)


def kvn_value_problem(text: str) -> str | None:
    """Why ``text`` cannot be written as a KVN value or comment (None when it can): a
    character outside printable ASCII, such as a newline that would start a line of its
    own in the message's header."""
    for index, character in enumerate(text):
        if ord(character) not in _KVN_CHARACTERS:
            return (
                f"character {character!r} at position {index}: a CCSDS KVN value holds "
                "printable ASCII only (codes 32-126, CCSDS 502.0-B-3)"
            )
    return None


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

    @field_validator("originator", "object_id")
    @classmethod
    def _kvn_text(cls, value: str) -> str:
        problem = kvn_value_problem(value)
        if problem is not None:
            raise ValueError(problem)
        return value


@lru_cache(maxsize=1)
def default_export_settings() -> CcsdsExportSettings:
    """The shipped ``configs/ccsds_export.yaml``."""
    from ovtraj.paths import config_path

    return load_model(CcsdsExportSettings, config_path("ccsds_export.yaml"))
