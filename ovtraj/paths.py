"""Where the project's configuration files live.

The library reads its figures (Earth model, atmosphere tables, vehicle data) from
``configs/`` at the repository root. ``OVTRAJ_CONFIG_DIR`` overrides the location.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO, Any

import yaml

# libyaml's parser when the wheel has it: the scenario file parses ~10x faster.
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

REPO_ROOT = Path(__file__).resolve().parents[1]


def config_dir() -> Path:
    """Directory holding the YAML configuration files."""
    return Path(os.environ.get("OVTRAJ_CONFIG_DIR", REPO_ROOT / "configs"))


def config_path(name: str) -> Path:
    """Path of a file inside the configuration directory; raises if it is missing."""
    path = config_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"configuration file not found: {path}")
    return path


def data_dir() -> Path:
    """Directory of stored results and tracked reference data (``OVTRAJ_DATA_DIR``)."""
    return Path(os.environ.get("OVTRAJ_DATA_DIR", REPO_ROOT / "data"))


def read_yaml(source: str | IO[str]) -> Any:
    """``yaml.safe_load`` with the C parser when available (same results, same errors)."""
    return yaml.load(source, Loader=_YAML_LOADER)
