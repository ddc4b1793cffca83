"""Burn-angle study (seed sec. 2.5, figs. 6-7): the converged solve repeated over burn angles.

The iteration of seed eq. 27 meets the entry u and flight-path angle at any burn angle, but
not the entry speed; the study reports, for each angle, the delta-v the converged burn needs
and the entry speed error it leaves, and the angles where that error crosses zero (linear
interpolation between neighbouring angles of the study).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem
from ovtraj.studies.deorbit_burn.solve import BurnSolver

__all__ = ["burn_angle_study", "zero_speed_error_angles"]

STUDY_COLUMNS = (
    "burn_angle_deg",
    "converged",
    "iterations",
    "u_open_deg",
    "dv_mps",
    "burn_duration_s",
    "entry_u_error_deg",
    "entry_fpa_error_deg",
    "entry_speed_error_mps",
    "impulsive_dv_mps",
    "reason",
)


def burn_angle_study(
    problem: DeorbitBurnProblem,
    burn_angles_deg: Sequence[float] | None = None,
    *,
    strategy: int | None = None,
) -> pd.DataFrame:
    """One converged solve per burn angle [deg] (default: the config's ``study`` list).

    Returns a frame with the columns of ``STUDY_COLUMNS``, one row per angle, in the given
    order; a solve that fails keeps its row with ``converged`` False and its reason.
    """
    angles = problem.config.study.burn_angles_deg if burn_angles_deg is None else burn_angles_deg
    solver = BurnSolver(problem)
    rows = []
    for angle in angles:
        row = solver.solve(strategy=strategy, burn_angle_deg=float(angle)).to_row()
        rows.append({key: row[key] for key in STUDY_COLUMNS})
    return pd.DataFrame(rows, columns=list(STUDY_COLUMNS))


def zero_speed_error_angles(study: pd.DataFrame) -> list[float]:
    """Burn angles [deg] where the entry speed error changes sign (linear interpolation)."""
    rows = study[study["converged"]].sort_values("burn_angle_deg")
    angles = rows["burn_angle_deg"].to_numpy(dtype=float)
    errors = rows["entry_speed_error_mps"].to_numpy(dtype=float)
    zeros = []
    for k in range(len(angles) - 1):
        a, b = errors[k], errors[k + 1]
        if a == 0.0:
            zeros.append(float(angles[k]))
        elif a * b < 0.0:
            zeros.append(float(angles[k] + (angles[k + 1] - angles[k]) * a / (a - b)))
    if len(errors) and errors[-1] == 0.0:
        zeros.append(float(angles[-1]))
    return [float(z) for z in np.round(zeros, 6)]
