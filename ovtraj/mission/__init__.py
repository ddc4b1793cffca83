"""The whole-mission chain (SPEC step 5): launch fit, rendezvous, transfer, deorbit, reentry."""

from ovtraj.mission.chain import (
    DESIGN_NAMES,
    STAGES,
    MissionContext,
    MissionDesign,
    MissionRecord,
    evaluate,
)

__all__ = [
    "DESIGN_NAMES",
    "STAGES",
    "MissionContext",
    "MissionDesign",
    "MissionRecord",
    "evaluate",
]
