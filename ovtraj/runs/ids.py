"""A run's id and the checks of ids and paths that come from outside (the command line, a
flow's parameters, a stored document).

The run id is a content hash of what changes results: the resolved config (which
holds the design bounds) without the settings that only say how the run executes
or what is done with it afterwards (``mission.doe``, ``mission.surrogate``,
``mission.optimize``, ``mission.verify``, ``mission.plan``), the seed, the samples
themselves, the parent run and the code version.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.store.backends import S3Path
from ovtraj.store.files import StoreError
from ovtraj.store.layout import ID_HEX_DIGITS, is_id

__all__ = [
    "NON_RESULT_SETTINGS",
    "checked_id",
    "results_config",
    "results_hash",
    "run_id",
    "samples_hash",
    "within_store",
]


# Settings that do not change a sample's results: how the DoE executes, and what
# the pipeline does with the results afterwards.
NON_RESULT_SETTINGS = ("doe", "surrogate", "optimize", "verify", "plan")


def results_config(resolved: dict[str, Any]) -> dict[str, Any]:
    """The resolved config without :data:`NON_RESULT_SETTINGS` (a copy)."""
    content = dict(resolved)
    mission = content.get("mission")
    if isinstance(mission, dict):
        content["mission"] = {k: v for k, v in mission.items() if k not in NON_RESULT_SETTINGS}
    return content


def samples_hash(samples: pd.DataFrame) -> str:
    """Hash of the design table (ids and values, bit for bit)."""
    table = samples.reset_index(drop=True)
    digest = hashlib.sha256()
    for column in sorted(table.columns):
        digest.update(column.encode("utf-8"))
        digest.update(np.ascontiguousarray(table[column].to_numpy(dtype=float)).tobytes())
    return digest.hexdigest()[:16]


def results_hash(resolved: dict[str, Any]) -> str:
    """Hash of :func:`results_config` (the runs of one scenario share it)."""
    text = json.dumps(results_config(resolved), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def run_id(
    resolved: dict[str, Any], seed: int, samples: pd.DataFrame, code: str, parent: str | None
) -> str:
    """The id of the run of these inputs: :data:`~ovtraj.store.layout.ID_HEX_DIGITS` hex
    digits of the SHA-256 of its results config, seed, samples, code version and parent."""
    content = {
        "config": results_config(resolved),
        "seed": seed,
        "samples": len(samples),
        "samples_hash": samples_hash(samples),
        "code": code,
        "parent": parent,
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:ID_HEX_DIGITS]


def checked_id(value: Any, what: str = "run id") -> str:
    """``value`` if it is an id of the store (see :data:`ID_HEX_DIGITS`), else
    :class:`StoreError` naming it, escaped (a newline shows as ``\\n``) and cut
    (:func:`ovtraj.config.io_limits.echoed`)."""
    if not isinstance(value, str) or not is_id(value):
        from ovtraj.config.io_limits import echoed

        raise StoreError(
            f"{what} {echoed(repr(value))} is not an id of this store ({ID_HEX_DIGITS} "
            "lowercase hexadecimal digits, as `ovtraj runs` lists them)"
        )
    return value


def within_store(root: Path | S3Path, path: Path | S3Path, what: str) -> Path | S3Path:
    """``path`` if, its links followed, it lies inside the store ``root``, else
    :class:`StoreError` naming ``what`` (a file and its field): a path built from ids
    (:func:`checked_id`) cannot climb out of the store by its name, this refuses a folder
    of the store that is a link to elsewhere. An object store has no links."""
    if isinstance(root, S3Path) or isinstance(path, S3Path):
        return path
    if not path.resolve().is_relative_to(root.resolve()):
        from ovtraj.formatting import printable

        raise StoreError(f"{what}: {printable(str(path))} leads outside the store {root}")
    return path
