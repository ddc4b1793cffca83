"""The mission design space: its bounds as arrays, and seeded Latin hypercubes over it
(the DoE's samples)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ovtraj.config.mission import MissionBoundsConfig
from ovtraj.mission import DESIGN_NAMES


def bounds_arrays(bounds: MissionBoundsConfig) -> tuple[np.ndarray, np.ndarray]:
    lower = np.array([getattr(bounds, n).lower for n in DESIGN_NAMES])
    upper = np.array([getattr(bounds, n).upper for n in DESIGN_NAMES])
    return lower, upper


def latin_hypercube(
    bounds: MissionBoundsConfig, n: int, seed: int, *, first_id: int = 0
) -> pd.DataFrame:
    """``n`` samples of a seeded Latin hypercube (McKay, Beckman & Conover 1979).

    ``scipy.stats.qmc.LatinHypercube`` with the seed, scaled to the bounds; one row
    per sample with ``sample_id`` counted from ``first_id``. Appending to a run
    draws a further hypercube with the seed advanced by the number of samples
    already drawn, so every sample of a run is reproducible from (seed, position).
    """
    # Imported here: scipy.stats costs ~0.6 s to import, and the processes that only
    # evaluate batches (pool and Dask workers) never draw samples.
    from scipy.stats import qmc

    if n < 1:
        raise ValueError(f"samples must be >= 1, got {n}")
    lower, upper = bounds_arrays(bounds)
    unit = qmc.LatinHypercube(d=len(DESIGN_NAMES), seed=seed + first_id).random(n)
    values = qmc.scale(unit, lower, upper)
    frame = pd.DataFrame(values, columns=list(DESIGN_NAMES))
    frame.insert(0, "sample_id", np.arange(first_id, first_id + n, dtype=np.int64))
    return frame
