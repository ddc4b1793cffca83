"""The benchmarks' goals, read from ``configs/benchmark_goals.yaml``.

Each script names its section by its own file name (``goal("scale", "pipeline_s")``,
``goals("convergence")``). The file is read as the library reads a config file
(:func:`ovtraj.config.base.yaml_data`: a regular file within ``config_file_max_kib`` of
``configs/io_limits.yaml``, YAML without anchors or aliases) and every value is checked to
be a finite positive number; anything else is one :class:`~ovtraj.errors.ConfigError` line
naming the file and the key. A value keeps its YAML type (``19`` an int, ``0.99`` a
float), so a script prints its goals as the file writes them.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

from ovtraj.config.base import yaml_data
from ovtraj.config.io_limits import echoed
from ovtraj.errors import ConfigError

FILE = Path(__file__).resolve().parents[1] / "configs" / "benchmark_goals.yaml"


@lru_cache(maxsize=1)
def _all_goals() -> dict[str, dict[str, float]]:
    data = yaml_data(FILE)
    if not isinstance(data, dict):
        raise ConfigError(["not a mapping of scripts to their goals"], str(FILE))
    for script, section in data.items():
        if not isinstance(section, dict) or not section:
            raise ConfigError([f"{script}: not a mapping of goals to values"], str(FILE))
        for name, value in section.items():
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if not (number and math.isfinite(value) and value > 0):
                hint = _number_as_text(value) * " (YAML read it as text; write 4.0e+9, not 4.0e9)"
                problem = f"{script}.{name} = {echoed(repr(value))}: not a finite positive number"
                raise ConfigError([problem + hint], str(FILE))
    return data


def _number_as_text(value: object) -> bool:
    """Whether ``value`` is a text that reads as a number (YAML took ``4.0e9`` for text)."""
    if not isinstance(value, str):
        return False
    try:
        float(value)
    except ValueError:
        return False
    return True


def goals(script: str) -> dict[str, float]:
    """The goals of ``script`` (its file name without ``.py``), in the file's order."""
    data = _all_goals()
    if script not in data:
        raise ConfigError([f"{script}: no such section"], str(FILE))
    return dict(data[script])


def goal(script: str, name: str) -> float:
    """The goal ``name`` of ``script``."""
    section = goals(script)
    if name not in section:
        raise ConfigError([f"{script}.{name}: no such goal"], str(FILE))
    return section[name]
