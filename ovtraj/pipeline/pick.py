"""Choosing the point of the verified front that becomes the mission plan (SPEC step 6)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ovtraj.config.io_limits import echoed
from ovtraj.optimize import Normalisation
from ovtraj.units import S_PER_HOUR


@dataclass(frozen=True)
class Pick:
    """By ``index`` on the front, or by weights on the normalised objectives among the
    points that meet the limits (all of them when no limit is given)."""

    index: int | None = None
    weights: tuple[float, float, float] | None = None  # T_total, dV_total, M_load
    max_t_total_h: float | None = None
    max_dv_total_mps: float | None = None
    min_m_load_kg: float | None = None


def checked_pick(
    pick: int | None = None,
    weights: Sequence[float] | str | None = None,
    max_time_h: float | None = None,
    max_dv_mps: float | None = None,
    min_payload_kg: float | None = None,
    *,
    shown: Mapping[str, str] | None = None,
) -> Pick:
    """The :class:`Pick` of ``ovtraj pipeline``'s pick options under their own names (the
    flows' parameters), checked before any work: a ``ValueError`` naming the first that
    is wrong (an index below 0, weights that cannot weigh, a limit that is not a finite
    number >= 0). ``weights``: three numbers, or the text ``T,dV,M`` the command takes.

    ``shown``: how a message names an input, by parameter name; the command maps each to
    its option (``{"max_dv_mps": "--max-dv-mps"}``: ``--max-dv-mps inf: ...``, the text
    of ``--weights`` as typed), a name it leaves out reads ``max_dv_mps = inf: ...``."""

    def wrong(name: str, value: object, problem: str) -> ValueError:
        label = (shown or {}).get(name)
        return ValueError(
            f"{name} = {value}: {problem}" if label is None else f"{label} {value}: {problem}"
        )

    if pick is not None and pick < 0:
        raise wrong("pick", pick, "must be a front index >= 0")
    parsed = None
    if weights is not None:
        text = isinstance(weights, str)
        typed = echoed(repr(weights)) if text else list(weights)
        try:
            parsed = tuple(float(w) for w in (weights.split(",") if text else weights))
        except (TypeError, ValueError):
            wanted = "must be three numbers" + (" separated by commas" if text else "")
            raise wrong("weights", typed, wanted) from None
    problem = weights_problem(parsed)
    if problem is not None:
        raise wrong("weights", typed, problem)
    limits = {"max_time_h": max_time_h, "max_dv_mps": max_dv_mps, "min_payload_kg": min_payload_kg}
    for name, value in limits.items():
        if value is not None and not np.isfinite(value):
            raise wrong(name, value, "must be a finite number")
        if value is not None and value < 0:
            raise wrong(name, value, "must be a finite number >= 0")
    return Pick(pick, parsed, max_time_h, max_dv_mps, min_payload_kg)


def pick_front_point(front: pd.DataFrame, normalisation: Normalisation, pick: Pick) -> pd.Series:
    """The chosen row of the front; ``ValueError`` naming the pick when none fits."""
    from ovtraj.pipeline.loop import PipelineError

    if len(front) == 0:
        raise PipelineError("the front is empty: nothing to pick")
    if pick.index is not None:
        if not 0 <= pick.index < len(front):
            raise PipelineError(
                f"pick index {pick.index} is outside the front: allowed 0..{len(front) - 1}"
            )
        return front.iloc[pick.index]
    keep = np.ones(len(front), dtype=bool)
    limits = (
        ("t_total_s", pick.max_t_total_h, S_PER_HOUR, np.less_equal, "max_t_total_h"),
        ("dv_total_mps", pick.max_dv_total_mps, 1.0, np.less_equal, "max_dv_total_mps"),
        ("m_load_kg", pick.min_m_load_kg, 1.0, np.greater_equal, "min_m_load_kg"),
    )
    asked = []
    for column, limit, scale, within, label in limits:
        if limit is not None:
            keep &= within(front[column].to_numpy(dtype=float), limit * scale)
            asked.append(f"{label} = {limit:g}")
    if not keep.any():
        raise PipelineError(f"no front point meets {', '.join(asked)}")
    problem = weights_problem(pick.weights)
    if problem is not None:
        raise PipelineError(f"weights {pick.weights}: {problem}")
    score = np.where(keep, weighted_scores(front, normalisation, pick_weights(pick)), np.inf)
    return front.iloc[int(np.argmin(score))]


def weights_problem(weights: Sequence[float] | None) -> str | None:
    """Why ``weights`` cannot weigh (T_total, dV_total, M_load), None when they can: three
    finite, non-negative numbers, not all zero (a NaN weight made every score NaN, and
    the first point was picked "with score nan"). None: equal weights."""
    if weights is None:
        return None
    values = np.asarray(weights, dtype=float)
    if values.shape != (3,):
        return f"three weights are needed (T, dV, M), got {values.size}"
    if not np.all(np.isfinite(values)):
        return "every weight must be a finite number"
    if np.any(values < 0):
        return "every weight must be non-negative"
    if not np.any(values > 0):
        return "the weights must not all be zero"
    return None


def pick_weights(pick: Pick) -> np.ndarray:
    """The pick's weights on (T_total, dV_total, M_load); equal when none are given."""
    return np.array(pick.weights if pick.weights is not None else (1.0, 1.0, 1.0), float)


def weighted_scores(
    front: pd.DataFrame, normalisation: Normalisation, weights: np.ndarray
) -> np.ndarray:
    """Each front point's weighted mean of its normalised objectives (0 the ideal point,
    1 the reference point): the lowest is picked."""
    values = normalisation.normalise(front[list(normalisation.names)].to_numpy(dtype=float))
    return values @ weight_fractions(weights)


def weight_fractions(weights: np.ndarray) -> np.ndarray:
    """``weights`` as fractions of their sum, which is taken after scaling them by their
    largest: it then lies between 1 and their count whatever their size (three weights of
    1e308 would sum to inf, every score be 0 and the first point be picked);
    ``ValueError`` when they cannot weigh (:func:`weights_problem`)."""
    problem = weights_problem(weights)
    if problem is not None:
        raise ValueError(f"weights {np.asarray(weights).tolist()}: {problem}")
    scaled = np.asarray(weights, dtype=float) / np.max(weights)
    return scaled / scaled.sum()
