"""The computing environment: OpenBLAS's kernel pinned, checked and recorded.

Every ``np.dot``, ``@``, ``np.linalg.norm`` of a vector, SciPy's SLSQP, SMT's Kriging and
scikit-learn call OpenBLAS, which picks a kernel for the CPU it finds when it loads
(Haswell, Sandybridge, SkylakeX...). Kernels sum in different orders: the same run id
once stored other last bits under ``OPENBLAS_CORETYPE=Sandybridge`` than under Haswell
(iteration counts and a deorbit trajectory moved, and the pipeline's surrogates turned
that into another front and plan). Thread counts are already fixed
(:data:`ovtraj.parallel.EVALUATION_BLAS_THREADS`); the kernel is fixed here.

- :func:`pin`, called first thing by ``ovtraj/__init__.py``: on Linux x86-64 with AVX2 and
  FMA (x86-64-v3: every x86 server since ~2013) it sets ``OPENBLAS_CORETYPE`` to
  :data:`PINNED_KERNEL`, over a value the user set (recorded), so the numpy and SciPy
  imported after it, and every process this one starts (pools, a local Dask cluster),
  run that kernel. glibc picks its FMA variants of libm on all such CPUs too, so the
  same bits follow. ``OVTRAJ_BLAS_KERNEL`` overrides the pin: another kernel the CPU
  supports, or ``native`` (OpenBLAS's own choice); results then differ in the last bits
  from other machines'.
- :func:`check`: the one-line problem when an OpenBLAS loaded in this process runs
  another kernel than the pin although the pin was possible (numpy imported before
  ovtraj; a ``dask worker`` started by hand, since ``distributed`` imports numpy), else
  None. :func:`require_pinned_kernel` raises it where stored content is computed.
- :func:`environment`: what computed a result (Python, OS, CPU and its flags, glibc,
  NumPy's and SciPy's BLAS as threadpoolctl sees them, the pin, numba and heyoka, the
  package versions), recorded beside the results (run manifests, batch markers, product
  markers; ``ovtraj.store.environment_block``), never in what an id hashes.

No import of numpy here: this module runs before it.
"""

from __future__ import annotations

import functools
import os
import platform
import sys
from dataclasses import dataclass, replace
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = [
    "CORETYPE_ENV",
    "KERNEL_ENV",
    "PINNED_KERNEL",
    "BlasKernelError",
    "Pin",
    "blas_libraries",
    "check",
    "dependency_versions",
    "environment",
    "pin",
    "require_pinned_kernel",
]

PINNED_KERNEL = "Haswell"
"""OpenBLAS's kernel of every stored computation: AVX2 and FMA (x86-64-v3)."""
CORETYPE_ENV = "OPENBLAS_CORETYPE"
KERNEL_ENV = "OVTRAJ_BLAS_KERNEL"
"""Overrides the pin: an OpenBLAS kernel of :data:`KERNEL_FLAGS`, or ``native``."""
NATIVE = "native"

# The x86-64 kernels an override may name, as OpenBLAS reports them (threadpoolctl's
# "architecture"; an unknown OPENBLAS_CORETYPE silently falls back to the CPU's own), and
# the /proc/cpuinfo flags each needs: forced on a CPU without them, OpenBLAS dies of
# SIGILL (SkylakeX on an AVX2 machine), so ovtraj refuses instead.
KERNEL_FLAGS: dict[str, tuple[str, ...]] = {
    "Nehalem": ("sse4_2",),
    "Sandybridge": ("avx",),
    "Haswell": ("avx2", "fma"),
    "SkylakeX": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"),
    "CooperLake": ("avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512_bf16"),
}
# CPU flags the environment block records: those the kernels and libm's variants follow.
RECORDED_FLAGS = ("sse4_2", "avx", "avx2", "fma")
RECORDED_FLAG_PREFIX = "avx512"
# Modules that load an OpenBLAS: imported before the pin, the variable comes too late.
BLAS_MODULES = ("numpy", "scipy")
PACKAGES = ("numpy", "scipy", "pandas", "pyarrow", "heyoka", "numba", "pydantic", "prefect")
"""The dependencies whose versions every run records (:func:`dependency_versions`)."""


class BlasKernelError(RuntimeError):
    """Stored content would be computed under another OpenBLAS kernel than the pin (one
    line naming the fix)."""


@dataclass(frozen=True)
class Pin:
    """What :func:`pin` did: the kernel asked of OpenBLAS (None: none), the
    ``OPENBLAS_CORETYPE`` and ``OVTRAJ_BLAS_KERNEL`` the process was started with, whether
    an OpenBLAS was already loaded then, and why no kernel is pinned (or why the
    override is refused: ``refused``)."""

    kernel: str | None
    requested: str | None
    override: str | None
    blas_loaded_before: bool
    reason: str | None = None
    refused: bool = False


_PIN: Pin | None = None


def pin() -> Pin:
    """Pin OpenBLAS's kernel for this process and its children (module notes); once per
    process, the first call's outcome kept."""
    global _PIN
    if _PIN is None:
        _PIN = _pinned_now()
        if _PIN.kernel is not None:
            os.environ[CORETYPE_ENV] = _PIN.kernel
    return _PIN


def _pinned_now() -> Pin:
    requested = os.environ.get(CORETYPE_ENV)
    override = os.environ.get(KERNEL_ENV) or None
    loaded = any(name in sys.modules for name in BLAS_MODULES)
    found = Pin(None, requested, override, loaded)
    if override is not None and override.strip().lower() == NATIVE:
        return replace(found, reason=f"{KERNEL_ENV}={NATIVE}: OpenBLAS chooses its own kernel")
    wanted = PINNED_KERNEL if override is None else _kernel_named(override.strip())
    if wanted is None:
        known = ", ".join([NATIVE, *KERNEL_FLAGS])  # the value is not echoed: any length
        return replace(found, reason=f"{KERNEL_ENV} is not one of {known}", refused=True)
    if not _x86_64_linux():
        why = f"{platform.system()} on {platform.machine()}: no x86-64 OpenBLAS kernel to pin"
        return replace(found, reason=why, refused=override is not None)
    missing = [flag for flag in KERNEL_FLAGS[wanted] if flag not in cpu_flags()]
    if missing:
        why = f"this CPU lacks {', '.join(missing)}, which OpenBLAS's {wanted} kernel needs"
        return replace(found, reason=why, refused=override is not None)
    return replace(found, kernel=wanted)


def _kernel_named(name: str) -> str | None:
    for kernel in KERNEL_FLAGS:
        if kernel.lower() == name.lower():
            return kernel
    return None


def _x86_64_linux() -> bool:
    return sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")


@functools.cache
def _cpuinfo() -> tuple[str | None, frozenset[str]]:
    """The CPU's model name and flags (/proc/cpuinfo's first processor); (None, {})
    where there is no such file."""
    model, flags = None, frozenset()
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as handle:
            for line in handle:
                key, _, value = line.partition(":")
                key = key.strip()
                if key == "model name" and model is None:
                    model = value.strip()
                elif key == "flags":
                    flags = frozenset(value.split())
                    break  # the first processor's: every core of a machine has the same
    except OSError:
        pass
    return model, flags


def cpu_flags() -> frozenset[str]:
    """The CPU's flags as the kernel lists them (empty where there is no /proc/cpuinfo)."""
    return _cpuinfo()[1]


def blas_libraries() -> list[dict[str, Any]]:
    """The BLAS libraries loaded in this process, as threadpoolctl sees them (a look at
    /proc/self/maps, ~1 ms): each one's package (``numpy``, ``scipy`` or None), internal
    API, version, architecture (OpenBLAS's kernel), threads and library file name."""
    from threadpoolctl import threadpool_info

    found = []
    for info in threadpool_info():
        if info.get("user_api") != "blas":
            continue
        path = Path(str(info.get("filepath") or ""))
        found.append(
            {
                "package": _owner(path),
                "internal_api": info.get("internal_api"),
                "version": info.get("version"),
                "architecture": info.get("architecture"),
                "threads": info.get("num_threads"),
                "library": path.name,
            }
        )
    return sorted(found, key=lambda lib: (str(lib["package"]), lib["library"]))


def _owner(path: Path) -> str | None:
    """The package that ships a library: its folder is ``numpy.libs`` or lies in ``numpy/``
    (a wheel's), likewise SciPy's; None for a system library."""
    for part in reversed(path.parent.parts):
        name = part.removesuffix(".libs")
        if name in BLAS_MODULES:
            return name
    return None


def check() -> str | None:
    """One line when this process must not compute stored content: an OpenBLAS loaded here
    runs another kernel than the pin although the pin was possible, or the override
    names a kernel this machine cannot run; else None (also where nothing can be pinned:
    another CPU family, a CPU without AVX2/FMA, ``native``)."""
    state = pin()
    if state.refused:
        return f"{state.reason}; unset {KERNEL_ENV} to use ovtraj's pin ({PINNED_KERNEL})"
    if state.kernel is None:
        return None
    for lib in blas_libraries():
        if lib["internal_api"] != "openblas":
            continue
        running = str(lib["architecture"])
        if running.lower() != state.kernel.lower():
            return (
                f"OpenBLAS runs the {running} kernel in this process ({lib['library']}), not "
                f"{state.kernel}: start it with {CORETYPE_ENV}={state.kernel} or import "
                "ovtraj before numpy"
            )
    return None


def require_pinned_kernel() -> None:
    """Raise :class:`BlasKernelError` with :func:`check`'s problem, if any: called where
    stored content is computed (a DoE batch, a surrogate fit, a front, a plan)."""
    problem = check()
    if problem is not None:
        raise BlasKernelError(problem)


def dependency_versions() -> dict[str, str]:
    """The versions of Python and of the dependencies, as this process imported them."""
    return dict(_installed_versions())


@functools.cache
def _installed_versions() -> dict[str, str]:
    # Once per process (~5 ms: each lookup scans the installed distributions); a
    # package upgraded while the process runs does not change the code it imported.
    versions = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def environment() -> dict[str, Any]:
    """What this process computes with, JSON-able, in a fixed key order, no time in it
    (module notes); declared by :class:`ovtraj.store.environment_block.EnvironmentBlock`."""
    state = pin()
    libraries = blas_libraries()
    openblas = [lib for lib in libraries if lib["internal_api"] == "openblas"]
    held = (
        None
        if state.kernel is None or not openblas
        else all(str(lib["architecture"]).lower() == state.kernel.lower() for lib in openblas)
    )
    versions = dependency_versions()
    return {
        **_machine(),
        "blas": libraries,
        "blas_pin": {
            "kernel": state.kernel,
            "requested": state.requested,
            "override": state.override,
            "blas_loaded_before": state.blas_loaded_before,
            "held": held,
            "reason": state.reason,
        },
        "numba": _numba(versions),
        "heyoka": {"version": versions.get("heyoka")},
        "packages": versions,
    }


@functools.cache
def _machine() -> dict[str, Any]:
    """The parts of :func:`environment` that do not change while the process runs."""
    model, flags = _cpuinfo()
    libc, libc_version = platform.libc_ver()
    recorded = sorted(f for f in flags if f in RECORDED_FLAGS or f.startswith(RECORDED_FLAG_PREFIX))
    return {
        "python": {
            "implementation": platform.python_implementation(),
            "version": platform.python_version(),
        },
        "os": {"system": platform.system(), "release": platform.release()},
        "machine": platform.machine(),
        "cpu": {"model": model or platform.processor() or None, "flags": recorded},
        "libc": {"name": libc or None, "version": libc_version or None},
    }


def _numba(versions: dict[str, str]) -> dict[str, Any]:
    """numba's version and the CPU it compiles for: ``NUMBA_CPU_NAME``, else LLVM's name
    of the host; None when numba is not imported (not worth its import)."""
    target = None
    if "numba" in sys.modules:
        try:
            import llvmlite.binding

            target = sys.modules["numba"].config.CPU_NAME or llvmlite.binding.get_host_cpu_name()
        except (ImportError, AttributeError, RuntimeError):
            target = None
    return {"version": versions.get("numba"), "target_cpu": target}
