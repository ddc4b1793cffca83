"""Where ovtraj reads its shipped files and where it writes the user's results.

Shipped files (read only): the configuration files (Earth model, atmosphere,
scenarios, launchers, published cases) and the small reference data (the default
scenario's launch fit). In a source checkout they are the repository's
``configs/`` and ``data/reference/``; an installed package carries the same files
as package data (``ovtraj/configs``, ``ovtraj/reference``; see ``setup.py``).
``OVTRAJ_CONFIG_DIR`` points the configuration files elsewhere.

The workspace (written): ``OVTRAJ_HOME`` if set, else ``<repository>/data`` in a
source checkout, else ``$XDG_DATA_HOME/ovtraj`` (``~/.local/share/ovtraj``). It
holds the run store (``runs/``), solved launch fits (``launch_fit/``) and other
command outputs. Nothing is ever written inside the installed package, and where
results go never depends on the current directory: a relative path in a config
file is relative to that file's folder.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path
from typing import IO, Any

import yaml

from ovtraj.storage import S3Path, location

# libyaml's parser when the wheel has it: the scenario file parses ~10x faster.
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

PACKAGE_DIR = Path(str(importlib.resources.files("ovtraj")))
REPO_ROOT = PACKAGE_DIR.parent


def source_checkout() -> bool:
    """Whether this ``ovtraj`` runs from a repository checkout (editable or not installed)."""
    return (REPO_ROOT / "pyproject.toml").is_file() and (REPO_ROOT / "configs").is_dir()


def config_dir() -> Path:
    """Directory holding the YAML configuration files."""
    if "OVTRAJ_CONFIG_DIR" in os.environ:
        return Path(os.environ["OVTRAJ_CONFIG_DIR"]).resolve()
    return REPO_ROOT / "configs" if source_checkout() else PACKAGE_DIR / "configs"


def config_path(name: str) -> Path:
    """Path of a file inside the configuration directory; raises if it is missing."""
    path = config_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"configuration file not found: {path}")
    return path


def reference_dir() -> Path:
    """Directory of the shipped reference data (read only)."""
    return REPO_ROOT / "data" / "reference" if source_checkout() else PACKAGE_DIR / "reference"


def workspace() -> Path:
    """The user's workspace (absolute): ``OVTRAJ_HOME``, see the module notes."""
    if os.environ.get("OVTRAJ_HOME"):
        return Path(os.environ["OVTRAJ_HOME"]).expanduser().resolve()
    if source_checkout():
        return REPO_ROOT / "data"
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base).expanduser().resolve() / "ovtraj"


def resolve(path: str | Path | S3Path, base_dir: Path | None) -> Path | S3Path:
    """``path`` made absolute: relative to ``base_dir`` (a config file's folder) if given.

    An object-store URL (``s3://bucket/prefix``) is absolute already.
    """
    path = location(path)
    if isinstance(path, S3Path):
        return path
    path = path.expanduser()
    if not path.is_absolute():
        path = (base_dir or Path.cwd()) / path
    return path.resolve()


def store_root(
    configured: str | None, base_dir: Path | None, override: str | Path | S3Path | None
) -> Path | S3Path:
    """The run store's root: ``override`` (``--store``), else the configured one
    (relative to the config file's folder), else the workspace's ``runs/``. Either may
    be an object store (``s3://bucket/prefix``, :mod:`ovtraj.storage`)."""
    if override is not None:
        return resolve(override, None)
    if configured:
        return resolve(configured, base_dir)
    return workspace() / "runs"


def read_yaml(source: str | IO[str]) -> Any:
    """``yaml.safe_load`` with the C parser when available (same results, same errors)."""
    return yaml.load(source, Loader=_YAML_LOADER)
