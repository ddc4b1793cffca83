"""Pareto filtering and the hypervolume indicator (pymoo)."""

from __future__ import annotations

import numpy as np
from pymoo.indicators.hv import HV
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting


def non_dominated(values: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated rows of a minimisation table (n, m), sorted.

    Duplicated rows are all kept (none dominates the other).
    """
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return np.zeros(0, dtype=int)
    return np.sort(NonDominatedSorting().do(values, only_non_dominated_front=True))


def hypervolume(normalised: np.ndarray) -> float:
    """Hypervolume dominated by the points, up to the reference point (1, ..., 1).

    ``normalised`` is the minimisation form of :class:`~.objectives.Normalisation`
    (ideal 0, reference 1), so the value is the dominated fraction of the unit box
    (While, Hingston, Barone & Huband 2006; pymoo's ``HV``). Points that do not
    dominate the reference point add nothing.
    """
    values = np.asarray(normalised, dtype=float)
    if values.ndim != 2 or len(values) == 0:
        return 0.0
    inside = values[np.all(values < 1.0, axis=1)]
    if len(inside) == 0:
        return 0.0
    return float(HV(ref_point=np.ones(values.shape[1]))(inside))
