"""An interrupt seen through compiled code.

The ``ovtraj`` command turns SIGINT and SIGTERM into ``KeyboardInterrupt``, raised by its
signal handler in the main thread at the next Python statement. When that statement runs
inside numba's dispatcher (the Python code it runs to type a tuple argument of a
compiled call), the call still returns its result, and CPython reports
``SystemError: ... returned a result with an exception set`` with the interrupt as its
cause. :func:`interrupt_of` finds the interrupt behind such an exception, so that a run
is marked and reported interrupted either way.
"""

from __future__ import annotations

__all__ = ["interrupt_of"]


def interrupt_of(error: BaseException | None) -> KeyboardInterrupt | None:
    """``error`` itself if it is a ``KeyboardInterrupt``, else the first one among its
    causes and contexts (None if there is none)."""
    seen: set[int] = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return error
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return None
