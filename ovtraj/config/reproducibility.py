"""How a stored run is recomputed and compared on this machine (``configs/reproducibility.yaml``;
``ovtraj verify RUN --recompute N``, :mod:`ovtraj.runs.recompute`).

Like ``configs/orchestration.yaml`` these belong to no scenario: they never change a result
or a run id.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Annotated

from pydantic import Field

from ovtraj.config.base import StrictModel, bounded, load_model
from ovtraj.formatting import split_unit
from ovtraj.paths import config_path

FILE = "reproducibility.yaml"
# A tolerance: a finite difference, at least 0, in the column's unit.
Tolerance = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class RecomputeSettings(StrictModel):
    """``recompute``: how many samples at most, and the tolerance of every compared column."""

    max_samples: int = bounded(
        unit="samples", ge=1, le=100_000, description="`ovtraj verify --recompute N` at most"
    )
    tolerances: dict[str, Tolerance] = Field(
        description="largest |stored - recomputed| accepted, by the column's unit (its name's "
        "suffix)"
    )
    columns: dict[str, Tolerance | None] = Field(
        description="by column name, for columns whose name carries no unit; null: reported, "
        "not bounded"
    )

    def tolerance(self, column: str) -> tuple[str, float | None]:
        """The unit and the tolerance of ``column`` (None: reported, not bounded); KeyError
        when the file declares none for it."""
        if column in self.columns:
            return "", self.columns[column]
        _, unit = split_unit(column)
        if unit and unit in self.tolerances:
            return unit, self.tolerances[unit]
        raise KeyError(column)


class ReproducibilityConfig(StrictModel):
    recompute: RecomputeSettings


@lru_cache(maxsize=1)
def load_reproducibility(path: str | Path | None = None) -> ReproducibilityConfig:
    """``configs/reproducibility.yaml`` (or ``path``); errors name the file and the field."""
    return load_model(ReproducibilityConfig, path or config_path(FILE))
