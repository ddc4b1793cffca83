"""A flow run's state tells whether its pipeline converged, as ``ovtraj``'s exit code does.

The mission and launch-window flows return :func:`verdict_state` once everything is stored
and published: their result itself (Completed) when the verification loop converged;
otherwise a Failed state whose message is the verdict, the exit 1 of ``ovtraj pipeline`` /
``ovtraj window``; with ``require_converged=False`` a Completed state named
:data:`NOT_CONVERGED`, the verdict as its message (``--allow-unconverged``), so the UI
still shows it. Either way the flow's result rides in the state: a direct call of a Failed
flow raises :class:`NotConverged` carrying it, and ``return_state=True`` hands the state.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

NOT_CONVERGED = "Not converged"


class NotConverged(RuntimeError):
    """A flow whose pipeline did not converge (or a window that planned no day): the
    verdict as the message, what the flow returns otherwise in ``result`` (its files are
    stored, its artifacts published)."""

    def __init__(self, verdict: str, result: dict[str, Any]) -> None:
        super().__init__(verdict)
        self.result = result


def verdict_state(
    result: dict[str, Any], verdict: str, *, converged: bool, require_converged: bool
) -> Any:
    """``result`` when ``converged``; else a Failed state (``require_converged``) or a
    Completed one named :data:`NOT_CONVERGED`, both with ``verdict`` as the message."""
    from prefect.states import Completed, Failed

    if converged:
        return result
    if require_converged:
        return Failed(message=verdict, data=NotConverged(verdict, result))
    return Completed(name=NOT_CONVERGED, message=verdict, data=result)


def run_from_command_line(flow_function: Callable[[], Any]) -> None:
    """``python -m flows.<module>``: the flow with its defaults, its result printed; one
    that did not converge prints its result, the verdict on stderr, and exits 1."""
    try:
        print(flow_function())
    except NotConverged as err:
        print(err.result)
        print(err, file=sys.stderr)
        raise SystemExit(1) from None
