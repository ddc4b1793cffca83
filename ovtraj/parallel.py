"""Side-by-side work on a pool the caller already started, with this process as fallback.

The pipeline's pool (``concurrent.futures`` processes or a Dask client's executor) scores
the surrogate candidates and draws the plots as well as evaluating batches. That work is
deterministic, so when the pool breaks under it (a worker killed, e.g. out of memory)
this process does it instead: the same result, later, rather than none.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from concurrent.futures import BrokenExecutor, Executor
from typing import Any

__all__ = ["mapped"]

logger = logging.getLogger(__name__)


def mapped(
    function: Callable[..., Any], arguments: Sequence[tuple], executor: Executor | None
) -> list[Any]:
    """``function(*a)`` for each ``a`` of ``arguments``, in order: on ``executor`` when
    given (and there is more than one), else in this process; in this process too when
    the executor breaks (``BrokenExecutor``: a worker process died), with a warning."""
    if executor is None or len(arguments) <= 1:
        return [function(*a) for a in arguments]
    try:
        return list(executor.map(function, *zip(*arguments, strict=True)))
    except BrokenExecutor as err:
        logger.warning("the pool broke (%s): %s runs in this process", err, function.__name__)
        return [function(*a) for a in arguments]
