"""h-refinement of the collocation mesh from each segment's own re-flight.

After a solve, every segment is flown by the independent model of :mod:`.flight` from its
collocated first state, over its own time span, with the interpolated optimal controls;
the distance from where it lands to its collocated last state is the segment's error.
Segments whose error exceeds their share of ``feasibility.tolerance_km`` (the tolerance
divided by the number of segments: the terminal error sums what each segment adds) are
split in two, the largest errors first, up to ``transcription.max_segments``. This is the
h-method of Betts (*Practical Methods for Optimal Control*, 2nd ed., SIAM 2010, sec. 4.7)
and of dymos and GPOPS-II, with the local error measured by integration rather than by
the collocation residual between the nodes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ovtraj.deadline import Deadline
from ovtraj.studies.optimal_entry.feasibility import position_distance_m
from ovtraj.studies.optimal_entry.flight import fly
from ovtraj.studies.optimal_entry.flight_kernel import ControlTable
from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["refined_edges", "segment_errors"]


def segment_errors(
    problem: EntryProblem,
    t_points: NDArray[np.float64],
    y_points: NDArray[np.float64],
    segment_points: Sequence[NDArray[np.intp]],
    controls: ControlTable,
    deadline: Deadline | None = None,
) -> NDArray[np.float64]:
    """Each segment's re-flight error [km]: flown from its first state point to its last.

    ``t_points`` [s] and ``y_points`` (rows of h, lon, lat, V, gamma, psi, SI) at every
    state point; ``segment_points`` the state points of each segment. A segment whose
    recovered times do not increase, or whose flight does not complete, has an infinite
    error.
    """
    settings = problem.config.feasibility
    errors = np.full(len(segment_points), math.inf)
    for k, points in enumerate(segment_points):
        first, last = int(points[0]), int(points[-1])
        t_a, t_b = float(t_points[first]), float(t_points[last])
        if not t_b > t_a or (deadline is not None and deadline.expired()):
            continue
        flown = fly(
            problem,
            controls,
            t_b,
            rtol=settings.relative_tolerance,
            atol=settings.absolute_tolerance,
            deadline=deadline,
            start=(t_a, y_points[first]),
        )
        if flown.status == "completed":
            errors[k] = position_distance_m(flown.y[-1], y_points[last], problem.radius) / 1e3
    return errors


def refined_edges(
    edges: NDArray[np.float64],
    errors: NDArray[np.float64],
    tolerance_km: float,
    max_segments: int,
    terminal_error_km: float | None = None,
) -> NDArray[np.float64] | None:
    """The segment edges with the segments over their share of the tolerance halved.

    The share is ``tolerance_km / segments``, divided by how much the terminal miss
    (``terminal_error_km``, the re-flight's) exceeds the segments' summed errors: the
    entry's dynamics grow a segment's error along the rest of the flight.

    When every segment is under its share while the terminal error is not (errors
    compound along the flight), the worst quarter of the segments is split; ``None`` when
    no segment can be added.
    """
    n = len(errors)
    room = max_segments - n
    if room <= 0:
        return None
    share = tolerance_km / n
    finite = errors[np.isfinite(errors)]
    if terminal_error_km is not None and np.isfinite(terminal_error_km) and finite.sum() > 0.0:
        # The terminal miss is the segments' errors grown along the flight: their ratio
        # (measured) scales each segment's share down.
        share /= max(1.0, terminal_error_km / float(finite.sum()))
    over = np.flatnonzero(errors > share)
    worst_first = over[np.argsort(-errors[over], kind="stable")]
    if len(worst_first) == 0:
        worst_first = np.argsort(-errors, kind="stable")[: max(1, math.ceil(n / 4))]
    chosen = set(worst_first[:room].tolist())
    new = [float(edges[0])]
    for k in range(n):
        if k in chosen:
            new.append(0.5 * float(edges[k] + edges[k + 1]))
        new.append(float(edges[k + 1]))
    return np.array(new)
