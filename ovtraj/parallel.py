"""Side-by-side work on a pool the caller already started, with this process as fallback.

The pipeline's pool (``concurrent.futures`` processes or a Dask client's executor) scores
the surrogate candidates and draws the plots as well as evaluating batches. That work is
deterministic, so when the pool breaks under it (a worker killed, e.g. out of memory) or
leaves it waiting past a bound (a Dask cluster that lost every worker keeps tasks
pending), this process does it instead: the same result, later, rather than none or a
hang.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import BrokenExecutor, Executor, Future, wait
from typing import Any

from threadpoolctl import ThreadpoolController

__all__ = [
    "EVALUATION_BLAS_THREADS",
    "Bounded",
    "blas_threads",
    "mapped",
    "openmp_threads",
    "started",
]

logger = logging.getLogger(__name__)

# BLAS threads of every stored evaluation. Not a setting: a multi-threaded BLAS splits its
# sums differently, so the same sample evaluated in a Dask worker (limited to one thread)
# and in this process differed in the 12th digit; with one thread everywhere, every
# runner stores byte-identical files (tests/test_runners.py).
EVALUATION_BLAS_THREADS = 1


@functools.cache
def _thread_pools() -> ThreadpoolController:
    return ThreadpoolController()


def blas_threads(limit: int) -> Any:
    """Context manager: this process's BLAS thread pools limited to ``limit`` threads.

    The pools are looked up once per process, after the first import of numpy and scipy:
    threadpoolctl's search of the loaded libraries (reading /proc/self/maps) cost ~4 ms
    a call, ~10 % of a pipeline's surrogate fitting when each candidate fit searched.
    """
    return _thread_pools().limit(limits=limit, user_api="blas")


def openmp_threads(limit: int) -> Any:
    """Context manager: this process's OpenMP thread pools limited to ``limit`` threads
    (scikit-learn's histogram gradient boosting), looked up once as :func:`blas_threads`."""
    return _thread_pools().limit(limits=limit, user_api="openmp")


def mapped(
    function: Callable[..., Any], arguments: Sequence[tuple], executor: Executor | None
) -> list[Any]:
    """``function(*a)`` for each ``a`` of ``arguments``, in order: on ``executor`` when
    given (and there is more than one), else in this process; in this process too when
    the executor breaks (``BrokenExecutor``: a worker process died) or its results do not
    come within its bound (:class:`Bounded`), with a warning."""
    if executor is None or len(arguments) <= 1:
        return [function(*a) for a in arguments]
    try:
        return list(executor.map(function, *zip(*arguments, strict=True)))
    except (BrokenExecutor, TimeoutError) as err:
        return _here(function, arguments, err)()


def started(
    function: Callable[..., Any], arguments: Sequence[tuple], executor: Executor | None
) -> Callable[[], list[Any]]:
    """:func:`mapped` begun now, collected later: ``function(*a)`` for each ``a`` is
    submitted to ``executor`` at once, and the call returned waits for the results, in
    order. With no executor the call computes them when it is made. A broken pool, or
    results not all in within a :class:`Bounded` executor's bound (counted from the
    collection), have them computed in this process, with a warning, as :func:`mapped`
    does. Meant for work that can run while this process does something else (drawing
    plots while it runs NSGA-II)."""
    if executor is None:
        return lambda: [function(*a) for a in arguments]
    try:
        futures = [executor.submit(function, *a) for a in arguments]
    except BrokenExecutor as err:
        return _here(function, arguments, err)

    def results() -> list[Any]:
        _, pending = wait(futures, timeout=getattr(executor, "timeout_s", None))
        try:
            if pending:
                raise TimeoutError(f"{len(pending)} of {len(futures)} results not in time")
            return [future.result() for future in futures]
        except (BrokenExecutor, TimeoutError) as err:
            for future in futures:
                future.cancel()
            return _here(function, arguments, err)()

    return results


def _here(
    function: Callable[..., Any], arguments: Sequence[tuple], err: Exception
) -> Callable[[], list[Any]]:
    reason = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
    logger.warning("the pool failed (%s): %s runs in this process", reason, function.__name__)
    return lambda: [function(*a) for a in arguments]


class Bounded(Executor):
    """``executor`` whose ``map`` raises ``TimeoutError`` when its results are not all in
    ``timeout_s`` after the call (``concurrent.futures.Executor.map``'s own timeout)."""

    def __init__(self, executor: Executor, timeout_s: float) -> None:
        self.executor = executor
        self.timeout_s = timeout_s

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return self.executor.submit(fn, *args, **kwargs)

    def map(
        self,
        fn: Callable[..., Any],
        *iterables: Iterable[Any],
        timeout: float | None = None,
        chunksize: int = 1,
    ) -> Iterator[Any]:
        bound = self.timeout_s if timeout is None else timeout
        return self.executor.map(fn, *iterables, timeout=bound)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        pass  # the pool is its owner's to shut down
