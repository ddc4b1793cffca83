"""Which front points to verify with the real chain (the infill).

Greedy max-min spreading in the normalised objective space (Gonzalez 1985's
farthest-point traversal): start from the point best in the first objective, then
repeatedly take the point farthest from those already taken, so a few real
evaluations cover the whole front. Points within ``min_distance`` (unit cube) of a
design already evaluated are skipped: their real values are already known.
"""

from __future__ import annotations

import math

import numpy as np


def spread_picks(
    normalised: np.ndarray,
    units: np.ndarray,
    evaluated_units: np.ndarray,
    count: int,
    min_distance: float,
) -> list[int]:
    """Indices of up to ``count`` front points, spread along the front, none evaluated."""
    normalised = np.asarray(normalised, dtype=float)
    units = np.asarray(units, dtype=float)
    if len(units) == 0 or count < 1:
        return []
    fresh = np.ones(len(units), dtype=bool)
    evaluated = np.asarray(evaluated_units, dtype=float).reshape(-1, units.shape[1])
    if len(evaluated):
        distance = np.linalg.norm(units[:, None, :] - evaluated[None, :, :], axis=2)
        fresh = distance.min(axis=1) >= min_distance
    candidates = np.flatnonzero(fresh)
    if len(candidates) == 0:
        return []
    picks = [int(candidates[np.argmin(normalised[candidates, 0])])]
    while len(picks) < min(count, len(candidates)):
        taken = normalised[picks]
        gap = np.linalg.norm(normalised[candidates, None, :] - taken[None], axis=2).min(axis=1)
        # A design next to one just picked is as good as evaluated too.
        near = np.linalg.norm(units[candidates, None, :] - units[picks][None, :, :], axis=2)
        gap[near.min(axis=1) < min_distance] = -1.0
        best = int(np.argmax(gap))
        if gap[best] <= 0.0:
            break
        picks.append(int(candidates[best]))
    return picks


def hypervolume_picks(
    normalised: np.ndarray,
    units: np.ndarray,
    evaluated_units: np.ndarray,
    real_normalised: np.ndarray,
    count: int,
    min_distance: float,
) -> list[int]:
    """Up to ``count`` front points that add the most predicted hypervolume, greedily.

    Each step takes the candidate whose predicted objectives add the most hypervolume
    to the real front plus the points already taken (the greedy hypervolume-improvement
    infill of Emmerich, Giannakoglou & Naujoks 2006, on the surrogate's prediction
    rather than its expectation). Candidates that add nothing are spread by
    :func:`spread_picks` instead, so every call still verifies the front.
    """
    from ovtraj.optimize.front import hypervolume

    normalised = np.asarray(normalised, dtype=float)
    units = np.asarray(units, dtype=float)
    if len(units) == 0 or count < 1:
        return []
    evaluated = np.asarray(evaluated_units, dtype=float).reshape(-1, units.shape[1])
    fresh = np.ones(len(units), dtype=bool)
    if len(evaluated):
        distance = np.linalg.norm(units[:, None, :] - evaluated[None, :, :], axis=2)
        fresh = distance.min(axis=1) >= min_distance
    base = np.asarray(real_normalised, dtype=float).reshape(-1, normalised.shape[1])
    picks: list[int] = []
    current = hypervolume(base)
    while len(picks) < count:
        gains = np.full(len(units), -1.0)
        for k in np.flatnonzero(fresh):
            if picks and np.min(np.linalg.norm(units[picks] - units[k], axis=1)) < min_distance:
                continue
            gains[k] = hypervolume(np.vstack([base, normalised[[*picks, k]]])) - current
        best = int(np.argmax(gains))
        if gains[best] <= 0.0:
            break
        picks.append(best)
        current += gains[best]
    if len(picks) < count:
        taken = np.vstack([evaluated, units[picks]]) if picks else evaluated
        rest = spread_picks(normalised, units, taken, count - len(picks), min_distance)
        picks += [k for k in rest if k not in picks]
    return picks


def promised_gain(
    normalised: np.ndarray,
    units: np.ndarray,
    evaluated_units: np.ndarray,
    real_normalised: np.ndarray,
    min_distance: float,
) -> float:
    """The hypervolume the surrogate front still promises over the real one, relative.

    The front's points within ``min_distance`` (unit cube) of an evaluated design are left
    out: the chain has answered for them, and the real front holds that answer. The rest
    are promises; ``HV(real + promises) / HV(real) - 1`` is what verifying all of them
    would add if the surrogates are right (infinite without a real front).
    """
    from ovtraj.optimize.front import hypervolume

    normalised = np.asarray(normalised, dtype=float)
    units = np.asarray(units, dtype=float)
    base = np.asarray(real_normalised, dtype=float).reshape(-1, normalised.shape[1])
    real = hypervolume(base)
    if real <= 0.0:
        return math.inf
    if len(units) == 0:
        return 0.0
    evaluated = np.asarray(evaluated_units, dtype=float).reshape(-1, units.shape[1])
    fresh = np.ones(len(units), dtype=bool)
    if len(evaluated):
        distance = np.linalg.norm(units[:, None, :] - evaluated[None, :, :], axis=2)
        fresh = distance.min(axis=1) >= min_distance
    return hypervolume(np.vstack([base, normalised[fresh]])) / real - 1.0
