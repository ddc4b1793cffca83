"""Wall-time limits of the solvers: one small deadline object per solve.

Every solver stops at its iteration limit and at its wall-time limit, both from its
config (``time_limit_s`` in the solver's section, in seconds of wall time). A
:class:`Deadline` starts with the solve; the solver asks it whether the time is up:

* a solver's own loop calls :meth:`Deadline.expired` between iterations (or
  :meth:`Deadline.check`, which raises :class:`TimeLimitReached`, where the loop sits
  deep inside a computation that has no other way out);
* scipy's methods call :meth:`Deadline.stop_if_expired` from their ``callback``: it
  raises ``StopIteration``, which scipy turns into a normal return at the current
  iterate (``status`` 99 for SLSQP, 3 for ``trust-constr``);
* IPOPT gets :meth:`Deadline.remaining_s` as its own ``max_wall_time``; pymoo gets
  :func:`pymoo_termination`, its generation limit or the deadline, whichever comes first.

On reaching a limit the stage returns its normal unconverged (or infeasible) result with
a reason that names the limit, from :meth:`Deadline.reason`:
``rendezvous.time_limit_s = 30 s reached after 12 iterations``. A result that ran into
its time limit is never reported as converged: it would depend on the machine's speed.
The limits are a safety net: the shipped configs set them far above the measured solve
times, so results stay deterministic.
"""

from __future__ import annotations

import math
import time
from typing import Any

__all__ = ["Deadline", "TimeLimitReached", "pymoo_termination"]


class TimeLimitReached(Exception):
    """Raised inside a solver when its deadline has passed; its stage catches it."""

    def __init__(self, deadline: Deadline, count: int | None = None, what: str = "") -> None:
        self.deadline = deadline
        super().__init__(deadline.reason(count, what or "iterations"))


class Deadline:
    """A wall-time limit named by its config key; starts when it is created."""

    def __init__(self, limit_s: float, name: str) -> None:
        if not limit_s > 0.0:
            raise ValueError(f"{name} must be > 0 s, got {limit_s!r}")
        self.limit_s = float(limit_s)
        self.name = name
        self._start = time.perf_counter()
        self.reached = False

    @classmethod
    def unlimited(cls, name: str = "no time limit") -> Deadline:
        """A deadline that never passes (callers that set no limit, e.g. low-level tests)."""
        return cls(math.inf, name)

    def elapsed_s(self) -> float:
        return time.perf_counter() - self._start

    def remaining_s(self) -> float:
        return max(self.limit_s - self.elapsed_s(), 0.0)

    def expired(self) -> bool:
        """Whether the limit has passed; once it has, it stays passed (``reached``)."""
        if not self.reached and self.elapsed_s() >= self.limit_s:
            self.reached = True
        return self.reached

    def check(self, count: int | None = None, what: str = "iterations") -> None:
        """Raise :class:`TimeLimitReached` once the limit has passed."""
        if self.expired():
            raise TimeLimitReached(self, count, what)

    def stop_if_expired(self) -> None:
        """For scipy callbacks: ``StopIteration`` ends the method at its current iterate."""
        if self.expired():
            raise StopIteration

    def reason(self, count: int | None = None, what: str = "iterations") -> str:
        """``<config key> = <limit> s reached[ after <count> <what>]``."""
        text = f"{self.name} = {self.limit_s:g} s reached"
        return text if count is None else f"{text} after {count} {what}"


def pymoo_termination(generations: int, deadline: Deadline) -> Any:
    """pymoo's termination: ``generations`` generations, or earlier at the deadline."""
    from pymoo.core.termination import TerminateIfAny, Termination
    from pymoo.termination.max_gen import MaximumGenerationTermination

    class _AtDeadline(Termination):
        def _update(self, algorithm: object) -> float:
            return 1.0 if deadline.expired() else 0.0

    return TerminateIfAny(MaximumGenerationTermination(generations), _AtDeadline())
