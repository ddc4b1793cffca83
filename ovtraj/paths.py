"""Where ovtraj reads its shipped files and where it writes the user's results.

Shipped files (read only): the configuration files (Earth model, atmosphere,
scenarios, launchers, published cases) and the small reference data (the default
scenario's launch fit). In a source checkout they are the repository's
``configs/`` and ``data/reference/``; an installed package carries the same files
as package data (``ovtraj/configs``, ``ovtraj/reference``; see ``setup.py``).
``OVTRAJ_CONFIG_DIR`` points the configuration files elsewhere.

The workspace (written): ``OVTRAJ_HOME`` if set, else ``<repository>/data`` in a
source checkout, else ``$XDG_DATA_HOME/ovtraj`` (``~/.local/share/ovtraj``). It
holds the run store (``runs/``, :func:`ovtraj.store.paths.store_root`), solved launch
fits (``launch_fit/``) and other command outputs. The workspace and a store's root are
resolved when they are named (a symbolic link chosen for them is followed there, once);
below them no write passes through a symbolic link
(:func:`ovtraj.store.files.make_folders`). Nothing is ever written inside the installed
package, and where results go never depends on the current directory: a relative path in
a config file is relative to that file's folder.

This module is at the bottom of the library (it imports no other part of ovtraj): the
configuration and the store both find their files here.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

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


def scenario_file(config: str | Path | None) -> Path:
    """The scenario file of a command or flow: ``config``, else the shipped
    ``scenario.yaml`` (the same default for ``ovtraj`` and every flow, wherever it runs)."""
    return Path(config) if config is not None else config_path("scenario.yaml")


def reference_dir() -> Path:
    """Directory of the shipped reference data (read only)."""
    return REPO_ROOT / "data" / "reference" if source_checkout() else PACKAGE_DIR / "reference"


def workspace() -> Path:
    """The user's workspace (absolute): ``OVTRAJ_HOME``, see the module notes."""
    if os.environ.get("OVTRAJ_HOME"):
        return Path(os.environ["OVTRAJ_HOME"]).expanduser().resolve()
    if source_checkout():
        return (REPO_ROOT / "data").resolve()
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base).expanduser().resolve() / "ovtraj"
