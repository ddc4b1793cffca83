"""Caches that last as long as the process, also on a Dask worker (where a task's module
arrives by value with every task)."""

from __future__ import annotations

import sys
import types
from typing import Any

_CACHE_MODULE = "_ovtraj_task_caches"


def process_cache(name: str) -> dict[str, Any]:
    """A dict that lasts as long as this process (fill it with :func:`remember`, which
    bounds its size). A module-level cache would not do: on a Dask
    worker a task's module arrives by value with every task (fresh globals), and
    ``functools.lru_cache`` objects pickle by reference to a module the worker lacks."""
    holder = sys.modules.get(_CACHE_MODULE)
    if holder is None:
        holder = sys.modules.setdefault(_CACHE_MODULE, types.ModuleType(_CACHE_MODULE))
    caches = holder.__dict__.setdefault("caches", {})
    return caches.setdefault(name, {})


def remember(cache: dict[str, Any], key: str, value: Any, size: int) -> Any:
    """Put ``value`` in a :func:`process_cache` dict, dropping the oldest over ``size``."""
    cache[key] = value
    while len(cache) > size:
        cache.pop(next(iter(cache)))
    return value
