"""``configs/window.yaml``: the scan's bounds (no result depends on them) and the
porkchop's sweep (part of a window's id: its grid is stored with the days)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from ovtraj.config.base import StrictModel, bounded, load_model

FILE = "window.yaml"
MAX_SWEEP_POINTS = 201  # the most sweep points a day's record may hold (checked on read)


class PorkchopSettings(StrictModel):
    """``porkchop``: the design variable each planned day's plan is swept over, and how
    many points span its ``mission.design_bounds``."""

    variable: Literal["parking_altitude_km", "preparation_altitude_km", "separation_delay_h"]
    points: int = bounded(
        ge=2, le=MAX_SWEEP_POINTS, description="sweep points over the variable's bounds"
    )


class WindowSettings(StrictModel):
    """``configs/window.yaml``."""

    max_days: int = bounded(ge=1, le=3660, description="longest scan, in launch days")
    flow_timeout_s: float = bounded(
        unit="s", gt=0, le=31_622_400, description="wall-time limit of a window flow run"
    )
    porkchop: PorkchopSettings


def load_window_settings(path: str | Path | None = None) -> WindowSettings:
    """``configs/window.yaml`` (or ``path``); a ConfigError names the file and the field."""
    from ovtraj.paths import config_path

    return load_model(WindowSettings, path or config_path(FILE))
