"""Whether a plan flies the front point it was picked from (SPEC step 6).

:func:`check_front_point` compares the totals of the plan's chain record with the front
point's stored ones, within ``mission.plan.front_tolerance``, and names the stage figures
that moved when they differ (:class:`PlanMismatch`).
"""

from __future__ import annotations

import math
from typing import Any

from ovtraj.mission.chain import MissionRecord
from ovtraj.mission.plan import PlanError
from ovtraj.units import S_PER_HOUR


class PlanMismatch(PlanError):
    """A plan that does not fly the front point it was picked from, within
    ``mission.plan.front_tolerance``: ``differences`` names each total off, by how much,
    and ``causes`` the stage figures behind it (the command exits 1)."""

    def __init__(self, message: str, differences: list[str], causes: list[str]) -> None:
        super().__init__(message)
        self.differences = differences
        self.causes = causes


# The totals a plan must reproduce: name, label, unit, scale to the label's unit, and the
# front tolerance's field.
_PROMISED = (
    ("dv_total_mps", "dV_total", "m/s", 1.0, "dv_total_mps"),
    ("t_total_s", "T_total", "h", 1.0 / S_PER_HOUR, "t_total_s"),
    ("m_load_kg", "M_load", "kg", 1.0, "m_load_kg"),
)
# The stage figures that explain a difference of the totals: stage, row column, label, unit.
_CAUSES = (
    ("launch", "payload_kg", "launch payload", "kg"),
    ("launch", "drop_time_s", "drop", "s"),
    ("rendezvous", "wait_time_s", "phasing wait", "s"),
    ("rendezvous", "dv_total_mps", "rendezvous dV", "m/s"),
    ("rendezvous", "plane_difference_deg", "plane difference at the burn", "deg"),
    ("transfer", "dv_total_mps", "transfer dV", "m/s"),
    ("deorbit", "wait_time_s", "deorbit wait", "s"),
    ("deorbit", "dv_mps", "deorbit dV", "m/s"),
    ("reentry", "flight_time_s", "entry flight", "s"),
)


def check_front_point(
    record: MissionRecord,
    front: dict[str, float],
    front_stages: dict[str, dict[str, Any]],
    tolerance: Any,
    what: str,
) -> None:
    """Raise :class:`PlanMismatch` when the plan's chain ``record`` does not reproduce the
    ``front`` totals (``t_total_s``, ``dv_total_mps``, ``m_load_kg``) within ``tolerance``
    (:class:`~ovtraj.config.mission.FrontTolerance`). ``front_stages``: the front point's
    stored stage rows, to say why (the figures of each stage that moved)."""
    differences = []
    for name, label, unit, scale, field in _PROMISED:
        planned, promised = getattr(record, name), front.get(name)
        if promised is None or planned is None:
            continue
        if abs(planned - promised) > getattr(tolerance, field):
            differences.append(
                f"{label} {promised * scale:.6g} -> {planned * scale:.6g} {unit} "
                f"({(planned - promised) * scale:+.3g}; tolerance "
                f"{getattr(tolerance, field) * scale:.3g})"
            )
    if not differences:
        return
    causes = []
    for stage, column, label, unit in _CAUSES:
        before = (front_stages.get(stage) or {}).get(column)
        after = record.stages.get(stage, {}).get(column)
        if isinstance(before, int | float) and isinstance(after, int | float):
            if not math.isclose(before, after, rel_tol=1e-9, abs_tol=1e-6):
                causes.append(f"{label} {before:.6g} -> {after:.6g} {unit}")
    why = "; ".join(causes) or "no stored stage figures to compare"
    raise PlanMismatch(
        f"the plan of {what} does not fly its front values: {'; '.join(differences)}. "
        f"Stage figures, front -> plan: {why}",
        differences,
        causes,
    )
