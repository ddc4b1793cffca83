"""The mission objectives (SPEC step 5) and their normalisation.

Minimise ``T_total`` and ``dV_total``, maximise ``M_load``. The optimiser and the
hypervolume work on the normalised minimisation form

    f_n = (s f - s f_ideal) / (s f_ref - s f_ideal),   s = +1 (minimise), -1 (maximise)

so the configured ideal point maps to 0 and the reference point to 1 in every
objective (``mission.optimize.ideal`` / ``reference``; docs/optimize.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ovtraj.config.mission import ObjectivePoint, OptimizeSettings
from ovtraj.units import S_PER_HOUR


@dataclass(frozen=True)
class Objective:
    name: str  # the totals column, SI unit in the name
    sense: int  # +1 minimise, -1 maximise
    label: str  # for tables and plots
    report_unit: str
    report_scale: float  # SI value x scale = reported value


MISSION_OBJECTIVES = (
    Objective("t_total_s", +1, "T_total", "h", 1.0 / S_PER_HOUR),
    Objective("dv_total_mps", +1, "dV_total", "m/s", 1.0),
    Objective("m_load_kg", -1, "M_load", "kg", 1.0),
)


def _si(point: ObjectivePoint) -> np.ndarray:
    return np.array([point.t_total_h * S_PER_HOUR, point.dv_total_mps, point.m_load_kg])


@dataclass(frozen=True)
class Normalisation:
    """Maps physical objectives (columns in ``objectives`` order) to the unit scale."""

    objectives: tuple[Objective, ...]
    ideal: np.ndarray  # physical units
    reference: np.ndarray

    def __post_init__(self) -> None:
        sense = self.senses
        span = sense * (self.reference - self.ideal)
        if not np.all(span > 0):
            bad = [o.name for o, s in zip(self.objectives, span, strict=True) if s <= 0]
            raise ValueError(
                f"the reference point must be worse than the ideal point in every objective; "
                f"not in {', '.join(bad)}"
            )

    @classmethod
    def mission(cls, settings: OptimizeSettings) -> Normalisation:
        return cls(MISSION_OBJECTIVES, _si(settings.ideal), _si(settings.reference))

    @property
    def senses(self) -> np.ndarray:
        return np.array([o.sense for o in self.objectives], dtype=float)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.objectives)

    def normalise(self, values: np.ndarray) -> np.ndarray:
        """Physical (n, m) -> normalised minimisation form (n, m)."""
        s = self.senses
        return (s * np.asarray(values, dtype=float) - s * self.ideal) / (
            s * self.reference - s * self.ideal
        )

    def physical(self, normalised: np.ndarray) -> np.ndarray:
        s = self.senses
        scaled = np.asarray(normalised, dtype=float) * (s * self.reference - s * self.ideal)
        return (scaled + s * self.ideal) / s

    def span(self) -> np.ndarray:
        """|reference - ideal| per objective (physical units): the error scale."""
        return np.abs(self.reference - self.ideal)
