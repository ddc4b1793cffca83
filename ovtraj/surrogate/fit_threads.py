"""The threads of the surrogate fits: one BLAS thread, one fit at a time in a process.

A LAPACK factorisation's last bits depend on the thread count, so the fits, their
predictions at the training inputs and the rebuilds of stored models all run with one
BLAS thread, wherever they run: the same models and figures in this process, in a pool's
processes and after a load.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from ovtraj.parallel import blas_threads

__all__ = ["one_blas_thread", "serial_blas"]

_FIT_LOCK = threading.Lock()


def one_blas_thread() -> Any:
    """A context with one BLAS thread."""
    return blas_threads(1)


@contextmanager
def serial_blas() -> Iterator[None]:
    """One BLAS thread while fitting, one fit at a time in the process.

    The Kriging likelihood works on n x n matrices with n ~ 30-80, where OpenBLAS's thread
    pool costs far more than it gains: on a busy 2-core machine a KRG fit on 30 samples
    took 0.2-4 s with 2 BLAS threads and a steady 0.12 s with one. The lock keeps two
    threads of one process (a threaded task runner) from restoring each other's limits
    out of order.
    """
    with _FIT_LOCK, one_blas_thread():
        yield
