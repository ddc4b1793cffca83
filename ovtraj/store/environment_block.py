"""The environment block of the stores' manifests and markers: declared, stamped, checked.

Every run manifest, DoE batch marker, product marker (surrogate fits, fronts, pipeline
results, launch fits...) and Monte Carlo run and batch marker carries, under
``"environment"``, what the process that wrote it computed with
(:func:`ovtraj.environment.environment`: Python, OS, CPU and flags, glibc, the BLAS
libraries and OpenBLAS's kernel pin, numba, heyoka, package versions). It is beside the
results, never in them: no id hashes it and no Parquet file holds it, so the same inputs
still store the same data files on every machine, while each marker says which machine
computed its files (a Dask worker on another machine records its own).

:class:`EnvironmentBlock` declares it. It is validated when written (:func:`stamped`) and
on every read of a manifest or marker (:func:`environment_problem`, through
:func:`ovtraj.store.seals.authenticated`): at most ``reads.environment_block_max_kib`` of
``configs/orchestration.yaml`` as JSON, then exactly the declared fields and types (a
fixed depth: a nested value where a string belongs is refused without being walked).
A document without the block (a store written before it existed) reads as before.

A marker written again with the same content keeps the first writer's block
(:meth:`ovtraj.store.products.ProductWriter.finish`): the environment that computed the
files it lists.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationError

from ovtraj.environment import environment
from ovtraj.store.backends import S3Path
from ovtraj.store.files import StoreError
from ovtraj.store.settings import given_settings
from ovtraj.units import BYTES_PER_KIB

__all__ = ["ENVIRONMENT_KEY", "EnvironmentBlock", "environment_problem", "stamped", "unstamped"]

ENVIRONMENT_KEY = "environment"
# How a declared field's name looks (the only names an error line repeats).
_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")


class _Declared(BaseModel):
    # strict: a number is not a string, a bool is not an int; nothing undeclared
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class PythonInfo(_Declared):
    implementation: str
    version: str


class OsInfo(_Declared):
    system: str
    release: str


class CpuInfo(_Declared):
    model: str | None
    flags: list[str]  # avx, avx2, fma, sse4_2 and every avx512* the CPU has


class LibcInfo(_Declared):
    name: str | None
    version: str | None


class BlasLibrary(_Declared):
    """A BLAS library loaded in the process, as threadpoolctl saw it."""

    package: str | None  # numpy, scipy, or None (a system library)
    internal_api: str | None  # openblas, mkl, blis...
    version: str | None
    architecture: str | None  # OpenBLAS's kernel (core type)
    threads: int | None
    library: str  # the file name


class BlasPin(_Declared):
    """What ``ovtraj.environment.pin`` did."""

    kernel: str | None  # the kernel asked of OpenBLAS (None: none pinned)
    requested: str | None  # OPENBLAS_CORETYPE as the process was started with it
    override: str | None  # OVTRAJ_BLAS_KERNEL as the process was started with it
    blas_loaded_before: bool  # an OpenBLAS was loaded before the pin
    held: bool | None  # every loaded OpenBLAS runs the pinned kernel (None: nothing to hold)
    reason: str | None  # why no kernel is pinned


class NumbaInfo(_Declared):
    version: str | None
    target_cpu: str | None  # the CPU numba compiles for (None: numba not imported)


class HeyokaInfo(_Declared):
    version: str | None


class EnvironmentBlock(_Declared):
    """The declared ``"environment"`` of a manifest or marker."""

    python: PythonInfo
    os: OsInfo
    machine: str
    cpu: CpuInfo
    libc: LibcInfo
    blas: list[BlasLibrary]
    blas_pin: BlasPin
    numba: NumbaInfo
    heyoka: HeyokaInfo
    packages: dict[str, str]  # ovtraj.environment.dependency_versions


def _problem(block: Any) -> str | None:
    """Why ``block`` is not a declared environment block, in a few words; None if it is."""
    largest = int(given_settings().environment_block_max_kib * BYTES_PER_KIB)
    try:
        size = len(json.dumps(block, separators=(",", ":"), allow_nan=False))
    except (TypeError, ValueError, RecursionError):
        return "not JSON data"
    if size > largest:
        return (
            f"{size} bytes, more than {largest} (reads.environment_block_max_kib of "
            "configs/orchestration.yaml)"
        )
    try:
        EnvironmentBlock.model_validate(block)
    except ValidationError as err:
        first = err.errors()[0]
        where = ".".join(_shown(part) for part in first["loc"]) or "the block"
        return f"{where}: {first['msg']}"
    return None


def _shown(part: str | int) -> str:
    """A part of an error's location as it may be printed: a declared name or an index;
    a key from the document (hostile: any length, any character) is not echoed."""
    if isinstance(part, int) or _NAME.fullmatch(part):
        return str(part)
    return "<a key>"


def environment_problem(path: Path | S3Path, document: Any) -> str | None:
    """Why the ``"environment"`` of ``document`` (a manifest or marker read from ``path``)
    is refused, in one line naming the file and the field; None when it is declared or
    absent (a document written before the block existed)."""
    if not isinstance(document, Mapping) or ENVIRONMENT_KEY not in document:
        return None
    problem = _problem(document[ENVIRONMENT_KEY])
    if problem is None:
        return None
    return f"{path}: {ENVIRONMENT_KEY} block refused ({problem})"


def stamped(document: Mapping[str, Any]) -> dict[str, Any]:
    """``document`` with this process's environment block (checked against the
    declaration: a block this code cannot read back is never written)."""
    block = environment()
    problem = _problem(block)
    if problem is not None:
        raise StoreError(f"this process's {ENVIRONMENT_KEY} block: {problem}")
    return {**document, ENVIRONMENT_KEY: block}


def unstamped(document: Mapping[str, Any]) -> dict[str, Any]:
    """``document`` without its environment block (what two writers of it must agree on)."""
    return {k: v for k, v in document.items() if k != ENVIRONMENT_KEY}
