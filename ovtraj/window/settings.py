"""``configs/window.yaml``: the scan's bounds (no result depends on them)."""

from __future__ import annotations

from pathlib import Path

from ovtraj.config.base import StrictModel, bounded, load_model

FILE = "window.yaml"


class WindowSettings(StrictModel):
    """``configs/window.yaml``."""

    max_days: int = bounded(ge=1, le=3660, description="longest scan, in launch days")
    flow_timeout_s: float = bounded(
        unit="s", gt=0, le=31_622_400, description="wall-time limit of a window flow run"
    )


def load_window_settings(path: str | Path | None = None) -> WindowSettings:
    """``configs/window.yaml`` (or ``path``); a ConfigError names the file and the field."""
    from ovtraj.store.paths import config_path

    return load_model(WindowSettings, path or config_path(FILE))
