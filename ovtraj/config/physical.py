"""The shipped physical models read from ``configs/``: the Earth (``earth.yaml``) and the
US76 atmosphere (``atmosphere_us76.yaml``), each a regular file within
``config_file_max_kib`` without YAML anchors (:func:`.io_limits.read_config_file`),
validated into :mod:`ovtraj.astro`'s types. Here, not in ``astro``: the numeric kernels
read no file (the layers contract in pyproject.toml)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from ovtraj.astro.atmosphere import US76Atmosphere, US76Table
from ovtraj.astro.constants import EarthModel
from ovtraj.bounded_reads import read_yaml
from ovtraj.config.io_limits import read_config_file
from ovtraj.paths import config_path

__all__ = [
    "default_atmosphere",
    "default_earth",
    "load_earth",
    "load_us76_table",
    "us76_atmosphere",
]

US76_CONFIG_FILE = "atmosphere_us76.yaml"


def load_earth(path: str | Path) -> EarthModel:
    """An Earth model read from a YAML file."""
    return EarthModel.model_validate(read_yaml(read_config_file(path)))


@lru_cache(maxsize=1)
def default_earth() -> EarthModel:
    """The project's Earth model, ``configs/earth.yaml``."""
    return load_earth(config_path("earth.yaml"))


def load_us76_table(path: str | Path) -> US76Table:
    """The US76 figures read from a YAML file."""
    return US76Table.model_validate(read_yaml(read_config_file(path)))


def us76_atmosphere(path: str | Path | None = None) -> US76Atmosphere:
    """The US76 model of a YAML file, by default ``configs/atmosphere_us76.yaml``."""
    return US76Atmosphere(load_us76_table(config_path(US76_CONFIG_FILE) if path is None else path))


@lru_cache(maxsize=1)
def default_atmosphere() -> US76Atmosphere:
    """The project's US76 model, built once from ``configs/atmosphere_us76.yaml``."""
    return us76_atmosphere()
