"""The replay's trajectory as ephemeris: one :class:`EphemerisSegment` per continuous arc
in the project's ECI (TEME, docs/conventions.md), sampled by an :class:`EphemerisRecorder`
as the replay flies (:func:`ovtraj.mission.fly.replay_ephemeris`), the source of the
CCSDS export (:mod:`ovtraj.mission.ccsds`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class EphemerisSegment:
    """One continuous arc of the replayed trajectory in the project's ECI (TEME).

    ``t_s``: (N,) seconds from the plan's launch day 0 h UTC, increasing, the arc's two
    ends included; ``r_eci_m`` [m] and ``v_eci_mps`` [m/s]: (N, 3).
    """

    name: str
    t_s: NDArray[np.float64]
    r_eci_m: NDArray[np.float64]
    v_eci_mps: NDArray[np.float64]


class EphemerisRecorder:
    """Samples the replay's arcs every ``orbit_step_s`` (orbits) and ``entry_step_s``."""

    def __init__(self, orbit_step_s: float, entry_step_s: float) -> None:
        self.orbit_step_s = orbit_step_s
        self.entry_step_s = entry_step_s
        self.segments: list[EphemerisSegment] = []

    @staticmethod
    def times(t0: float, t1: float, step: float) -> NDArray[np.float64]:
        """Every ``step`` from ``t0``, and ``t1`` (the entry's arcs)."""
        return np.unique(np.r_[np.arange(t0, t1, step), t1])

    @staticmethod
    def even_times(t0: float, t1: float, step: float) -> NDArray[np.float64]:
        """``t0`` to ``t1`` in equal intervals of at most ``step`` (the orbital arcs): a last
        interval of a few seconds beside 60 s ones makes the file's degree-7 Hermite fit of
        the arc before it ill-conditioned (0.33 m mid-interval against ~2 mm elsewhere, a
        2.3 s last interval measured 2026-12-04, docs/export.md)."""
        intervals = max(1, math.ceil((t1 - t0) / step - 1e-9))
        return np.linspace(t0, t1, intervals + 1)

    def add(self, name: str, t: NDArray, r: NDArray, v: NDArray) -> None:
        if len(t) >= 2:  # a zero-length arc (e.g. no stay) is no segment
            self.segments.append(EphemerisSegment(name, t, r, v))
