"""What a dispersed flight changes in the replay of a plan: the ascent's inputs, each
impulse as executed and the entry's truth model. :data:`NOMINAL` changes nothing (the
plan's own replay, :func:`ovtraj.mission.fly.fly_plan`); the Monte Carlo's draws
subclass :class:`Perturbation` (:mod:`ovtraj.mission.montecarlo`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ovtraj.reentry.model import EntryModel


class Perturbation:
    """What a dispersed flight changes in the replay (``ovtraj.mission.montecarlo``); this
    base class changes nothing (the nominal replay)."""

    def ascent(self, inp: Any) -> Any:
        """The launch input the ascent is flown with (its launcher and drop)."""
        return inp

    def burn(self, index: int, dv_eci_mps: np.ndarray) -> np.ndarray:
        """The impulse executed for the ``index``-th planned one (time order)."""
        return dv_eci_mps

    def entry(self, model: EntryModel) -> EntryModel:
        """The entry model the truth is flown with (atmosphere and aerodynamics)."""
        return model


NOMINAL = Perturbation()
